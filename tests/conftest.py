"""Test configuration: float64 everywhere (the library never flips jax.config itself)."""

import os

import jax

# Tests call the CLI in-process (`main(argv)`), which would point this process's jax.config at
# the per-user compilation cache; keep the suite hermetic (tests/test_compilation_cache.py
# removes the variable in its own subprocesses).
os.environ.setdefault("BRDFFIT_NO_COMPILATION_CACHE", "1")

jax.config.update("jax_enable_x64", True)
