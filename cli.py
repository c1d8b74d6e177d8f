from brdffit.cli import main

# Guarded: worker processes started by `brdffit batch` (multiprocessing "spawn") import the
# main module again, and must not run the command line themselves.
if __name__ == "__main__":
    raise SystemExit(main())
