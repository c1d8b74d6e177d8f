"""The JAX persistent compilation cache in a per-user folder, so a new process starts warm.

:func:`enable` points ``jax_compilation_cache_dir`` at ``<user cache>/brdffit/jax`` (the
platform's cache folder, from :mod:`platformdirs`: ``~/.cache/brdffit/jax`` on Linux, honouring
``XDG_CACHE_HOME``) and caches every compiled program, however quick its compilation. A process
that runs a fit JAX has compiled before (same program, same shapes, same jaxlib) then loads the
executable instead of compiling it; tracing still happens. It is called by the command line and by
batch workers, never at import (the library does not change ``jax.config`` on its own).

Opt out with ``BRDFFIT_NO_COMPILATION_CACHE=1``.
"""

from __future__ import annotations

import os
from pathlib import Path

#: Set to anything but ``""`` or ``"0"`` to leave JAX's compilation cache off.
OPT_OUT = "BRDFFIT_NO_COMPILATION_CACHE"


def folder() -> Path:
    """The per-user cache folder for compiled programs (not created here)."""
    import platformdirs

    return Path(platformdirs.user_cache_dir("brdffit", appauthor=False)) / "jax"


def enable() -> str | None:
    """Turn the persistent cache on; return the folder used, or ``None`` when it stays off.

    Off when ``BRDFFIT_NO_COMPILATION_CACHE`` is set (not ``"0"``) or when the folder cannot be
    created or written; JAX then compiles in every process, as without a cache. Idempotent.
    """
    if os.environ.get(OPT_OUT, "") not in ("", "0"):
        return None
    path = folder()
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    if not os.access(path, os.W_OK | os.X_OK):
        return None
    import jax

    jax.config.update("jax_compilation_cache_dir", str(path))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    return str(path)
