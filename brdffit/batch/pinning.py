"""Pinning local Dask workers to their own cores.

XLA sizes a process's thread pool to the cores the process may use (its affinity). A local
cluster of ``n`` worker processes on ``n`` cores would otherwise start ``n`` threads in each and
run ``n²`` busy threads on ``n`` cores. :class:`PinCores` gives worker ``k`` its own contiguous
group of cores before its first job. Only clusters started by brdffit are pinned; a cluster the
user brings (``client``, ``--scheduler``) is left as it is.
"""

from __future__ import annotations

import contextlib
import os

from distributed.diagnostics.plugin import WorkerPlugin


def core_groups(n: int) -> list[list[int]]:
    """The cores available to this process split into ``n`` contiguous, near-equal groups
    (``[]`` when there are fewer cores than workers, or no affinity on this platform)."""
    try:
        cores = sorted(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not on Linux
        return []
    if n < 1 or n > len(cores):
        return []
    size, extra = divmod(len(cores), n)
    groups, start = [], 0
    for k in range(n):
        stop = start + size + (k < extra)
        groups.append(cores[start:stop])
        start = stop
    return groups


def pin_process(cores) -> None:
    """Restrict every thread of this process to ``cores`` (threads made later inherit it)."""
    try:
        tids = [int(t) for t in os.listdir("/proc/self/task")]
    except OSError:  # pragma: no cover - no procfs
        tids = [0]
    for tid in tids:
        with contextlib.suppress(OSError):
            os.sched_setaffinity(tid, cores)


class PinCores(WorkerPlugin):
    """Dask worker plugin: local worker ``k`` (its name) runs on core group ``k`` of
    :func:`core_groups`. Registered before any job, so each worker's XLA backend starts with
    the cores it will use; a restarted worker keeps its name and is pinned again. (A fit of a
    full table uses every core it is given, so pinned workers fit as many tables per second as
    one worker on all cores, and small fits, which do not, run side by side; the figures are in
    ``benchmarks/bench_batch.py``'s output.)
    """

    name = "brdffit-pin-cores"

    def __init__(self, groups):
        self.groups = groups  # non-empty: see open_client

    def setup(self, worker):
        try:
            k = int(worker.name)
        except (TypeError, ValueError):
            return
        pin_process(self.groups[k % len(self.groups)])
