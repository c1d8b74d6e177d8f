"""Test configuration: float64 everywhere (the library never flips jax.config itself)."""

import jax

jax.config.update("jax_enable_x64", True)
