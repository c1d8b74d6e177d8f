"""JAX's persistent compilation cache in a per-user folder, so a new process skips compiling.

Every fresh process used to compile its programs from scratch (for ``ggx`` on a full MERL
table, longer than the fit itself). The cache keeps the compiled programs on disk, so the
next process loads them instead; ``benchmarks/bench_cold_start.py`` measures the effect.

* **On by default**: :func:`brdffit.fit`, :func:`brdffit.sample_posterior`, the workers of
  :func:`brdffit.fit_many` and the command line call :func:`ensure` before their first
  compilation. It turns the cache on once per process unless the user opted out or already
  chose a cache folder of their own (``jax_compilation_cache_dir`` set: left as it is).
* **Where**: :func:`cache_folder`, ``<user cache folder>/brdffit/jax`` (the platform's cache
  folder from ``platformdirs.user_cache_dir``: ``$XDG_CACHE_HOME/brdffit/jax`` or
  ``~/.cache/brdffit/jax`` on Linux, ``~/Library/Caches/brdffit/jax`` on macOS,
  ``%LOCALAPPDATA%\\brdffit\\Cache\\jax`` on Windows), or the folder named by the environment
  variable ``BRDFFIT_COMPILATION_CACHE_DIR``. :func:`location` says which folder the cache
  uses now (``None``: off). It can be deleted at any time.
* **Opt out**: the environment variable ``BRDFFIT_NO_COMPILATION_CACHE=1`` (any value but
  ``""`` and ``"0"``) keeps it off in every process; :func:`disable` turns it off in this one
  (and keeps :func:`ensure` from turning it on again).
* **Never breaks a fit**: a folder that cannot be created or written (a read-only home, no
  home at all) leaves the cache off and the run compiles as before: quietly for the default
  folder, with one :class:`CompilationCacheWarning` for a folder the user named. A folder
  of another user's, or one every user may write, is refused the same way (JAX runs what the
  cache holds: a cache that others can write lets them run code in this process); a folder
  made here is private (mode 0700). JAX itself only warns when a single
  entry cannot be read or written.

It changes ``jax.config`` (``jax_compilation_cache_dir`` and
``jax_persistent_cache_min_compile_time_secs``) when a fit first runs, never at import.
"""

from __future__ import annotations

import os
import stat
import tempfile
import threading
import warnings
from pathlib import Path

#: Set to a non-empty value other than ``"0"`` to keep the cache off.
OPT_OUT = "BRDFFIT_NO_COMPILATION_CACHE"
#: A folder to keep the cache in instead of :func:`default_folder`.
FOLDER_VARIABLE = "BRDFFIT_COMPILATION_CACHE_DIR"
#: Programs that compile faster than this (seconds) are not written (JAX's option).
MIN_COMPILE_SECONDS = 0.2

_LOCK = threading.Lock()
#: Whether this process has decided (:func:`enable`, :func:`disable`, :func:`ensure`).
_decided = False


class CompilationCacheWarning(UserWarning):
    """A cache folder the user named cannot be used; the run goes on without the cache."""


def default_folder() -> Path:
    """``<user cache folder>/brdffit/jax`` (``platformdirs.user_cache_dir``)."""
    import platformdirs

    return Path(platformdirs.user_cache_dir("brdffit", appauthor=False)) / "jax"


def cache_folder() -> Path:
    """The folder :func:`enable` uses: ``$BRDFFIT_COMPILATION_CACHE_DIR`` if set, else
    :func:`default_folder` (created by :func:`enable`, not here)."""
    named = os.environ.get(FOLDER_VARIABLE, "")
    return Path(named).expanduser() if named else default_folder()


def opted_out() -> bool:
    """Whether the environment variable :data:`OPT_OUT` keeps the cache off."""
    return os.environ.get(OPT_OUT, "") not in ("", "0")


def _unusable(folder: Path) -> str | None:
    """Why ``folder`` cannot hold the cache (``None``: it can), after creating it (0700)."""
    try:
        folder.mkdir(mode=0o700, parents=True, exist_ok=True)
        info = folder.stat()
        if hasattr(os, "getuid") and (info.st_uid != os.getuid()
                                      or info.st_mode & stat.S_IWOTH):
            return "it belongs to another user" if info.st_uid != os.getuid() else (
                "every user may write to it")
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".probe-"):
            pass
    except OSError as exc:
        return f"{type(exc).__name__}: {exc.strerror or exc}"
    return None


def enable(folder=None) -> str | None:
    """Turn on JAX's persistent compilation cache in ``folder`` (default :func:`cache_folder`).

    Returns the folder used, or ``None`` when the cache stays off: the opt-out variable is
    set, or the folder cannot be created or written (a :class:`CompilationCacheWarning` when
    the folder was named, by ``folder`` or ``BRDFFIT_COMPILATION_CACHE_DIR``). Never raises
    for those reasons. A cache already in use elsewhere in this process moves to ``folder``.
    """
    global _decided
    with _LOCK:
        _decided = True
        if opted_out():
            return None
        named = folder is not None or bool(os.environ.get(FOLDER_VARIABLE))
        try:
            path = Path(folder).expanduser() if folder is not None else cache_folder()
        except Exception:  # noqa: BLE001 (no home folder to derive a cache folder from)
            return None
        why = _unusable(path)
        if why is not None:
            if named:
                warnings.warn(f"compilation cache folder {str(path)!r} cannot be used ({why}); "
                              f"compiling without the cache (set {FOLDER_VARIABLE} to another "
                              f"folder, or {OPT_OUT}=1)", CompilationCacheWarning, stacklevel=2)
            return None
        _point_jax_at(str(path))
        return str(path)


def _point_jax_at(path: str | None) -> None:
    import jax
    from jax.experimental.compilation_cache import compilation_cache as jax_cache

    if jax.config.jax_compilation_cache_dir != path:
        jax_cache.reset_cache()  # a cache opened at another folder would go on being used
        jax.config.update("jax_compilation_cache_dir", path)
    if path is not None:
        jax.config.update("jax_persistent_cache_min_compile_time_secs", MIN_COMPILE_SECONDS)


def disable() -> None:
    """Turn the persistent compilation cache off in this process, whoever turned it on; the
    library will not turn it on again (:func:`enable` will)."""
    global _decided
    with _LOCK:
        _decided = True
        _point_jax_at(None)


def ensure() -> str | None:
    """The library's default, once per process: :func:`enable`, unless this process already
    decided (:func:`enable` or :func:`disable` called) or the user set
    ``jax_compilation_cache_dir`` themselves. Returns :func:`location`."""
    global _decided
    if not _decided:
        import jax

        if jax.config.jax_compilation_cache_dir is None:
            enable()
        _decided = True
    return location()


def location() -> str | None:
    """The folder JAX's persistent compilation cache uses in this process now, or ``None``
    when it is off (not yet turned on, opted out, or the folder was unusable)."""
    import jax

    if not jax.config.jax_enable_compilation_cache:
        return None
    return jax.config.jax_compilation_cache_dir
