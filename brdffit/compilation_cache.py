"""JAX's persistent compilation cache in a per-user folder, so a new process skips compiling.

Every ``brdffit fit`` process used to compile its programs from scratch (about 5 s for ``ggx``
on a full MERL table, more than the fit itself). :func:`enable` points JAX's persistent
compilation cache (``jax_compilation_cache_dir``) at ``<user cache>/brdffit/jax`` (the
platform's cache folder from ``platformdirs``: ``$XDG_CACHE_HOME`` or ``~/.cache`` on Linux),
so the second process loads the compiled programs instead. ``benchmarks/bench_cold_start.py``
measures the effect.

* Opt out with the environment variable ``BRDFFIT_NO_COMPILATION_CACHE=1`` (any value but
  ``""`` and ``"0"``).
* A folder that cannot be created or written (a read-only home, no home at all) disables the
  cache quietly: the run goes on and compiles as before.
* It changes ``jax.config`` and must run before the first compilation; the command line calls
  it, the library never does at import. Library users may call it themselves.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

#: Set to a non-empty value other than ``"0"`` to keep the cache off.
OPT_OUT = "BRDFFIT_NO_COMPILATION_CACHE"
#: Programs that compile faster than this (seconds) are not written (JAX's option).
MIN_COMPILE_SECONDS = 0.2


def cache_folder() -> Path:
    """``<user cache folder>/brdffit/jax`` (created by :func:`enable`, not here)."""
    import platformdirs

    return Path(platformdirs.user_cache_dir("brdffit", appauthor=False)) / "jax"


def _writable(folder: Path) -> bool:
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".probe-"):
            pass
    except OSError:
        return False
    return True


def enable() -> str | None:
    """Turn on JAX's persistent compilation cache in :func:`cache_folder`.

    Returns the folder used, or ``None`` when the cache stays off: the opt-out variable is
    set, or the folder cannot be created or written. Never raises for those reasons.
    """
    if os.environ.get(OPT_OUT, "") not in ("", "0"):
        return None
    try:
        folder = cache_folder()
    except Exception:  # noqa: BLE001 (no home folder to derive a cache folder from)
        return None
    if not _writable(folder):
        return None
    import jax

    jax.config.update("jax_compilation_cache_dir", str(folder))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", MIN_COMPILE_SECONDS)
    return str(folder)
