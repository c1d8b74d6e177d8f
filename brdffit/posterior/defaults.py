"""Default sampler settings, in a module free of heavy imports (the CLI's ``--help`` reads them).

32 walkers × 2500 steps, 500 of them burn-in, on 2000 cells stratified in θh: a ``ggx`` run
takes well under a minute on 2 CPU cores and keeps a chain of more than 50 autocorrelation
times (see ``benchmarks/bench_posterior.py``).
"""

DEFAULT_WALKERS = 32
DEFAULT_STEPS = 2500
DEFAULT_BURN = 500
DEFAULT_SUBSAMPLE_CELLS = 2000
