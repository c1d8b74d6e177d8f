"""``python cli.py ...``: the ``brdffit`` program from a checkout (the console script's twin)."""

import brdffit._program  # noqa: F401  (first: a batch worker ignores Ctrl-C from here on)

# Guarded: worker processes started by `brdffit batch` (multiprocessing "spawn") import the
# main module again, and must not run the command line themselves.
if __name__ == "__main__":
    brdffit._program.run()
else:
    from brdffit.cli import main, run

    __all__ = ["main", "run"]
