from brdffit.cli import main, run

__all__ = ["main", "run"]

# Guarded: worker processes started by `brdffit batch` (multiprocessing "spawn") import the
# main module again, and must not run the command line themselves.
if __name__ == "__main__":
    run()
