"""Running a batch on Dask: the cluster, the jobs, their outcomes, the table, the summary.

``fit_many`` is the whole batch for Python; ``brdffit batch`` (:mod:`brdffit.cli.batch`) calls
the same :func:`run_batch`. Where jobs run:

* ``client``: an existing ``distributed.Client`` (its cluster is used as it is);
* else ``scheduler`` or ``DASK_SCHEDULER_ADDRESS``: a running scheduler (``tcp://HOST:8786``,
  or ``tls://`` with Dask's TLS configuration; checked by :func:`check_scheduler_address` before
  anything runs); input paths and the outdir must then be readable (and the outdir writable) by
  the workers;
* else a ``LocalCluster`` of ``workers`` processes (default: one per CPU core, at most one per
  2 GiB of memory: :func:`default_workers`), one thread each
  (a fit already uses every core it is given; two fits in one process would only queue):
  ``brdffit batch`` starts one for the batch and closes it after; ``fit_many`` keeps the one
  it started for the session (:func:`session_client`), so a later call with the same
  ``workers`` and ``dashboard`` runs at once on workers that have compiled their programs
  already, and closes it at exit (:func:`close_session`; a signal's
  :func:`close_local_clusters` closes it too). Each local worker is pinned to its own share of
  the cores (:class:`brdffit.batch.pinning.PinCores`): XLA sizes its thread pool to the cores a process may use, so
  unpinned workers would each start a thread per core and oversubscribe the machine.
  The local cluster is closed to other users of the machine: it listens on loopback only and
  speaks TLS with credentials made for this batch alone (``Security.temporary()``: a key and
  certificate that exist only in this process and its workers), so a connection without them
  (any other process, another user) is refused before it can submit anything. No HTTP server
  runs: its scheduler and workers open no HTTP listener at all (:mod:`brdffit.batch.nohttp`),
  unless ``dashboard`` names an address for the scheduler's dashboard; its link is then printed
  on stderr (when that port is in use, Dask serves it on a free one: the line says so).

Worker processes live for the whole batch, so each compiles a model's programs once per table
layout and reuses them for every later job; the persistent compilation cache
(:mod:`brdffit.compilation_cache`) lets a fresh worker load them instead of compiling.

A job that takes its worker down (``os._exit``, the out-of-memory killer) is resubmitted by
Dask up to ``distributed.scheduler.allowed-failures`` times (once on a local cluster started
here, :data:`LOCAL_SCHEDULER`) and then recorded as ``worker died``; the other jobs go on.
"""

from __future__ import annotations

import atexit
import contextlib
import dataclasses
import logging
import os
import shutil
import tempfile
import threading
import time
import uuid
import warnings

from data_formats.files import writing

from ..errors import BrdffitError
from . import inputs, jobs, outdir as outdirs, table

#: Scheduler settings of a local cluster started here. ``allowed-failures``: resubmissions of a
#: job whose worker died, one retry for a transient cause (memory taken by a concurrent job),
#: then the job is recorded as failed. (Jobs are submitted one per worker thread, see
#: :func:`_collect`, so a worker that dies takes no waiting job down with it.)
LOCAL_SCHEDULER = {"distributed.scheduler.allowed-failures": 1}


#: Memory a local worker is given at least (a full MERL table's fit peaks near 1.3 GiB).
WORKER_MEMORY = 2 * 2**30
#: How long to try to reach a scheduler given by address before giving up.
CONNECT_TIMEOUT = "20s"


#: The schemes a scheduler address may have (``tls`` takes its credentials from Dask's
#: configuration, ``distributed.comm.tls``).
SCHEDULER_SCHEMES = ("tcp", "tls")
#: The scheduler's dashboard address when ``--dashboard`` names none: loopback only.
DEFAULT_DASHBOARD = "127.0.0.1:8787"


#: The local clusters open now (for :func:`close_local_clusters`).
_LIVE_CLUSTERS: set = set()
#: Their scratch folders, registered before the cluster is made (a signal may come meanwhile).
_SCRATCH: set = set()


class SchedulerError(BrdffitError):
    """The scheduler named by ``--scheduler`` / ``DASK_SCHEDULER_ADDRESS`` is not a valid
    address or cannot be reached."""


def check_scheduler_address(address, source: str = "--scheduler") -> str:
    """``address`` (``tcp://HOST:PORT``, ``tls://HOST:PORT``, or ``HOST:PORT`` for tcp) if it is
    one a scheduler can have; else :class:`SchedulerError` naming ``source`` (the option or
    variable it came from)."""
    text = str(address).strip()
    hint = "give tcp://HOST:PORT (or tls://HOST:PORT with Dask's TLS configuration)"
    scheme, sep, rest = text.partition("://")
    if not sep:
        scheme, rest = "tcp", text
    if scheme.lower() not in SCHEDULER_SCHEMES:
        why = (" (it reaches only a scheduler inside this process)" if scheme == "inproc"
               else "")
        raise SchedulerError(f"{source} {text!r}: scheme {scheme + '://'!r} is not "
                             f"supported{why}; {hint}")
    from distributed.comm.addressing import parse_host_port

    try:
        host, port = parse_host_port(rest)
    except (ValueError, TypeError) as exc:
        reason = str(exc) if "port" in str(exc) or "ipv6" in str(exc) else "port is not a number"
        raise SchedulerError(f"{source} {text!r}: not a scheduler address ({reason}); "
                             f"{hint}") from None
    if not host or any(c.isspace() or c in "/?#@" for c in host):
        raise SchedulerError(f"{source} {text!r}: not a scheduler address (host {host!r}); "
                             f"{hint}")
    if not 0 < port < 65536:
        raise SchedulerError(f"{source} {text!r}: port {port} is not 1 to 65535; {hint}")
    return f"{scheme.lower()}://{rest}"


#: The most local worker processes a batch starts: each is a Python process of its own with a
#: share of the cores (:mod:`.pinning`) and :data:`WORKER_MEMORY` of memory.
MAX_LOCAL_WORKERS = 256


def check_workers(workers, source: str = "workers") -> int | None:
    """``workers`` as an int in 1 to :data:`MAX_LOCAL_WORKERS` (``None`` stays ``None``: one
    per core); :class:`~brdffit.errors.ConfigError` in one line otherwise."""
    from ..errors import ConfigError

    if workers is None:
        return None
    if isinstance(workers, bool) or not isinstance(workers, int) or \
            not 1 <= workers <= MAX_LOCAL_WORKERS:
        raise ConfigError(f"{source} {workers!r}: give a whole number of local worker "
                          f"processes from 1 to {MAX_LOCAL_WORKERS} (default: one per core)")
    return int(workers)


def default_workers() -> int:
    """One worker per CPU core available to this process, at most one per
    :data:`WORKER_MEMORY` of the machine's memory."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not on Linux
        cores = os.cpu_count() or 1
    import psutil  # a dependency of distributed

    by_memory = psutil.virtual_memory().total // WORKER_MEMORY
    return max(1, min(cores, int(by_memory)))


@contextlib.contextmanager
def open_client(client=None, *, workers: int | None = None, scheduler: str | None = None,
                dashboard: str | None = None, keep: bool = False):
    """Yield ``(client, description)``: the given client, one connected to ``scheduler`` (or
    ``DASK_SCHEDULER_ADDRESS``), or one of a new local cluster of ``workers`` processes (with
    the scheduler's dashboard at ``dashboard``, an address like ``127.0.0.1:8787``, if given).
    With ``keep``, the local cluster is the session's (:func:`session_client`): started by the
    first call, reused by the next ones and closed at exit, or when a batch on it is
    interrupted (its jobs would go on running)."""
    if client is not None:
        yield client, "the given client"
        return
    from distributed import Client

    source = "--scheduler" if scheduler else "DASK_SCHEDULER_ADDRESS"
    address = scheduler or os.environ.get("DASK_SCHEDULER_ADDRESS")
    if address:
        address = check_scheduler_address(address, source)
        try:
            c = Client(address, timeout=CONNECT_TIMEOUT)
        except (OSError, TimeoutError, TypeError, ValueError) as exc:
            raise SchedulerError(f"cannot reach the Dask scheduler at {address!r} "
                                 f"({type(exc).__name__}: {exc}); check the address "
                                 "(tcp://HOST:8786) or unset DASK_SCHEDULER_ADDRESS to run on "
                                 "local workers") from None
        with c:
            yield c, f"scheduler {address}"
        return
    n = check_workers(workers) or default_workers()
    if keep:
        kept = _session(n, dashboard)
        try:
            yield kept
        except BaseException:  # an interrupted batch leaves its jobs running on the workers:
            close_session()  # the next call would wait for them
            raise
        return
    with _local_cluster(n, dashboard) as c:
        yield c


@dataclasses.dataclass
class _Kept:
    """The session's local cluster: its settings, client and the stack that closes it."""

    key: tuple
    client: object
    description: str
    stack: contextlib.ExitStack


#: The local cluster :func:`fit_many` keeps for the session (``None``: none yet, or closed).
_KEPT: _Kept | None = None
_KEPT_LOCK = threading.Lock()
_AT_EXIT = False


def _session(n: int, dashboard: str | None) -> tuple:
    """``(client, description)`` of the session's local cluster of ``n`` workers (and
    ``dashboard``): the one kept from an earlier call while it still runs with the same
    settings, else a new one (the old one closed first). Its workers stay alive between
    calls, and with them every program they compiled."""
    global _KEPT, _AT_EXIT
    with _KEPT_LOCK:
        if _KEPT is not None and _KEPT.key == (n, dashboard) and _running(_KEPT.client):
            return _KEPT.client, _KEPT.description
        _close_kept()
        if not _AT_EXIT:  # registered after distributed's exit handlers, so it runs first
            _AT_EXIT = bool(atexit.register(close_session))
        stack = contextlib.ExitStack()
        try:
            c, where = stack.enter_context(_local_cluster(n, dashboard))
        except BaseException:
            stack.close()
            raise
        _KEPT = _Kept((n, dashboard), c, where, stack)
        return c, where


def _running(client) -> bool:
    """Whether ``client`` and its cluster still run (a signal may have closed them)."""
    from distributed.core import Status

    cluster = getattr(client, "cluster", None)
    return client.status == "running" and getattr(cluster, "status", None) == Status.running


def _close_kept() -> None:
    """Close the kept cluster, if any (caller holds :data:`_KEPT_LOCK`)."""
    global _KEPT
    kept, _KEPT = _KEPT, None
    if kept is not None:
        with contextlib.suppress(Exception):
            kept.stack.close()


def session_client():
    """The ``distributed.Client`` of the local cluster :func:`fit_many` keeps for this
    session, or ``None`` (none started yet, or closed)."""
    with _KEPT_LOCK:
        return _KEPT.client if _KEPT is not None and _running(_KEPT.client) else None


def close_session() -> None:
    """Close the local cluster :func:`fit_many` keeps for this session (its workers stop, its
    scratch folder goes); the next call starts a new one. Runs at interpreter exit too."""
    with _KEPT_LOCK:
        _close_kept()


@contextlib.contextmanager
def _local_cluster(n: int, dashboard: str | None):
    """A client of a new local cluster of ``n`` pinned worker processes (module docstring)."""
    from distributed.security import Security

    security = Security.temporary()
    # The scheduler's and workers' scratch space (Dask's "temporary-directory", its lock files
    # included) lives in a folder of this batch's own, removed with the cluster: a worker
    # killed by a signal can leave no lock file in the shared temporary folder.
    with writing():  # a signal removes the folder only once it is registered
        scratch = tempfile.mkdtemp(prefix="brdffit-dask-")
        _SCRATCH.add(scratch)
    try:
        with _cluster_in(scratch, n, dashboard, security) as c:
            yield c
    finally:
        _SCRATCH.discard(scratch)
        shutil.rmtree(scratch, ignore_errors=True)


@contextlib.contextmanager
def _cluster_in(scratch: str, n: int, dashboard: str | None, security):
    """:func:`_local_cluster`'s cluster, with its scratch space in ``scratch``."""
    import dask
    from distributed import Client

    from . import nohttp, pinning

    settings = {**LOCAL_SCHEDULER, "temporary-directory": scratch}
    # The start makes files in ``scratch`` (lock files, the nodes' folders): it counts as a
    # write in flight (data_formats.files.writing), so a signal's clean-up waits for it
    # instead of racing it (files made just after the removal stayed behind).
    with writing(), dask.config.set(settings), warnings.catch_warnings():
        # A dashboard port in use: Dask serves on another and warns; the link printed below
        # says where (with the port asked for), in one line of ours.
        warnings.filterwarnings("ignore", message=r"Port \d+ is already in use")
        # Started without workers, so that a signal during their start finds the cluster
        # (close_local_clusters); the workers are added below.
        cluster = nohttp.QuietCluster(n_workers=0, threads_per_worker=1, processes=True,
                                      host="127.0.0.1", protocol="tls://", security=security,
                                      dashboard=bool(dashboard), dashboard_address=dashboard,
                                      silence_logs=logging.ERROR, env={"MPLBACKEND": "Agg"})
        _LIVE_CLUSTERS.add(cluster)
    try:
        with cluster, Client(cluster, security=security) as c:
            with writing(), dask.config.set(settings):  # the nannies take the settings
                groups = pinning.core_groups(n)
                if n > 1 and groups:
                    c.register_plugin(pinning.PinCores(groups))
                for _ in range(n):  # what scale(n) does, but waiting and raising as
                    cluster.worker_spec.update(nohttp.quiet_workers(  # LocalCluster(n)
                        cluster.new_worker_spec()))
                cluster.sync(cluster._correct_state)
            if dashboard:
                _report_dashboard(cluster, dashboard)
            yield c, f"{n} local worker{'s' * (n != 1)}"
    finally:
        _LIVE_CLUSTERS.discard(cluster)


def _report_dashboard(cluster, asked: str) -> None:
    """One line on stderr with the dashboard's link, and the port asked for when Dask had to
    serve it on another (that one was in use)."""
    import sys

    from distributed.comm.addressing import parse_host_port

    link = cluster.dashboard_link
    port = cluster.scheduler_info.get("services", {}).get("dashboard")
    with contextlib.suppress(ValueError, TypeError):
        wanted = parse_host_port(asked)[1]
        if wanted and port and wanted != port:
            link += f" (port {wanted} is in use)"
    print(f"Dask dashboard: {link}", file=sys.stderr, flush=True)


def close_local_clusters(timeout: float = 5) -> None:
    """Close the local clusters started here that still run: for a signal handler that is
    about to end the process, so that the workers stop and their semaphores are released
    (no "leaked semaphore" warning from ``multiprocessing``) and their scratch folders go."""
    import signal

    logging.disable(logging.CRITICAL)  # the process ends: lost jobs and workers are expected
    for cluster in list(_LIVE_CLUSTERS):
        for nanny in list(getattr(cluster, "_created", ())):  # a fit does not stop soon
            with contextlib.suppress(Exception):
                os.kill(nanny.process.process.pid, signal.SIGKILL)
        with contextlib.suppress(Exception):
            cluster.close(timeout=timeout)
    if _SCRATCH:  # a worker still starting (not yet the cluster's) would write after the
        _kill_children()  # removal: no child of this process but multiprocessing's tracker
        for scratch in list(_SCRATCH):  # is left to write; the main thread may still be
            for _ in range(10):  # closing the cluster it was starting: remove what it makes
                shutil.rmtree(scratch, ignore_errors=True)
                if not os.path.lexists(scratch):
                    break
                time.sleep(0.05)


def _kill_children(timeout: float = 2) -> None:
    """SIGKILL every child process of this one but multiprocessing's resource tracker (which
    releases the semaphores of the dead), and wait for them at most ``timeout`` seconds."""
    import psutil  # a dependency of distributed
    from multiprocessing import resource_tracker

    tracker = getattr(resource_tracker._resource_tracker, "_pid", None)
    with contextlib.suppress(psutil.Error):
        children = [c for c in psutil.Process().children(recursive=True) if c.pid != tracker]
        for child in children:
            with contextlib.suppress(psutil.Error):
                child.kill()
        psutil.wait_procs(children, timeout=timeout)


@dataclasses.dataclass
class BatchOutcome:
    """``frame``: the results table; ``results``: a FitResult (or None) per row, when asked;
    ``wall_time``: seconds; ``where``: what ran the jobs; ``files``: the table's files;
    ``merged``: rows of the outdir's earlier table ``kept`` and ``replaced`` in its files
    (:func:`brdffit.batch.table.merge`)."""

    frame: object
    results: list | None
    wall_time: float
    where: str
    files: list
    merged: dict | None = None


def make_jobs(mats, models_and_kwargs) -> list[jobs.Job]:
    """One job per (material, model), material-major; ``models_and_kwargs``: ``[(name, kw)]``.

    Paths are made absolute (workers of a remote cluster do not share the client's folder);
    the ``input`` column keeps them as given.
    """
    return [jobs.Job(m.name, name, m.table if m.path is None else os.path.abspath(m.path),
                     m.label, kwargs, jobs.options_key(name, kwargs))
            for m in mats for name, kwargs in models_and_kwargs]


def run_batch(job_list, *, outdir=None, force=False, plot=False, want_results=False,
              client=None, workers=None, scheduler=None, dashboard=None,
              progress=None, keep: bool = False) -> BatchOutcome:
    """Run every job, collect one row per job (in job order), write the table if ``outdir``.
    ``keep``: run on the session's local cluster (:func:`open_client`).

    ``outdir`` is created and checked (writable, no link or special file where an output
    belongs: :func:`brdffit.batch.outdir.prepare`) before the cluster starts, and removed again
    if it was created and the cluster cannot start. The rows are merged into the outdir's
    table (:func:`brdffit.batch.table.merge`), which is read, and refused if it is not a batch
    table, before the cluster starts; ``frame`` holds this batch's rows only."""
    t0 = time.perf_counter()
    previous = merged = None
    if outdir is not None:
        outdir, created = outdirs.prepare(outdir, _files_by_folder(job_list, plot))
        previous = table.read(outdir)
    outputs: dict[int, dict] = {}
    with contextlib.ExitStack() as stack:
        try:
            c, where = stack.enter_context(open_client(client, workers=workers,
                                                       scheduler=scheduler, dashboard=dashboard,
                                                       keep=keep))
        except BaseException:
            if outdir is not None:  # nothing ran: no output folder left behind
                outdirs.remove_empty(created)
            raise
        try:
            _collect(c, job_list, outputs, {"outdir": outdir, "force": force, "plot": plot,
                                                "want_result": want_results}, progress)
        finally:
            df = table.frame([outputs[i]["row"] for i in sorted(outputs)])
            files = []
            if outdir is not None and len(df):
                whole, merged = table.merge(previous, df)
                files = table.write(whole, outdir)
    results = None
    if want_results:
        from ..api import FitResult

        results = [None if outputs[i]["result"] is None else
                   FitResult.from_dict(outputs[i]["result"]) for i in sorted(outputs)]
    return BatchOutcome(df, results, time.perf_counter() - t0, where, files, merged)


def _files_by_folder(job_list, plot: bool) -> dict:
    """Material → the file names its jobs write in ``OUTDIR/<material>/``."""
    folders: dict = {}
    for job in job_list:
        names = job.names(plot)
        folders.setdefault(job.material, []).extend(
            [names["json"], names["meta"], *names.get("plots", [])])
    return folders


def _collect(client, job_list, outputs, kwargs, progress) -> None:
    """Submit the jobs, at most one per worker thread in flight, and store each outcome.

    The window (the cluster's thread count, read again as jobs finish, so it follows workers
    that join or leave) keeps a worker from holding jobs it is not running: Dask counts every
    job assigned to a worker that dies as suspect, so a backlog would fail with its worker.
    """
    from distributed import as_completed

    token = uuid.uuid4().hex[:8]  # keys unique to this batch: never an earlier batch's result
    todo = list(enumerate(job_list))[::-1]
    running = as_completed()
    futures = {}

    def submit() -> None:
        i, job = todo.pop()
        # A table in memory travels inside its task, not scattered: scattered data dies with
        # the worker holding it, and would take the table's other jobs down with it.
        data = None
        if not isinstance(job.source, str):
            job, data = dataclasses.replace(job, source=None), job.source
        fut = client.submit(jobs.run, job, data, key=f"fit-{job.material}-{job.model}-{token}-{i}",
                            pure=False, **kwargs)
        futures[fut] = i
        running.add(fut)

    def fill() -> None:
        window = max(1, sum(client.nthreads().values()))
        while todo and running.count() < window:
            submit()

    bar = _Bar(len(job_list), progress)
    try:
        fill()
        for fut in running:
            i = futures.pop(fut)
            outputs[i] = _output(fut, job_list[i])
            bar.update(outputs[i]["row"])
            fill()
    except BaseException:
        client.cancel(list(futures))
        raise
    finally:
        bar.close()


def _output(fut, job) -> dict:
    """A finished future's output, or the row of a job whose worker was lost."""
    if fut.status == "finished":
        try:
            return fut.result()
        except Exception as exc:  # noqa: BLE001 (a result that cannot come back)
            return _lost(job, "error", f"{type(exc).__name__}: {exc}")
    try:
        exc = fut.exception()
    except Exception as err:  # noqa: BLE001 (cancelled)
        exc = err
    from distributed import KilledWorker

    if isinstance(exc, KilledWorker):
        worker = getattr(exc, "last_worker", None) or "a worker"
        return _lost(job, "worker died", f"the worker process running it ({worker}) died: out "
                     "of memory, killed or crashed; see that worker's log")
    return _lost(job, "error", f"{type(exc).__name__}: {exc}")


def _lost(job, outcome: str, message: str) -> dict:
    from .. import __version__

    row = {"material": job.material, "model": job.model, "skipped": False, "input": job.input,
           "options": job.key, "brdffit_version": __version__,
           **table.failure_row(outcome, message)}
    return {"row": row, "result": None}


class _Bar:
    """A tqdm bar with done/failed/skipped counts and time left; off when ``progress`` is False
    (``None``: on when stderr is a terminal)."""

    def __init__(self, total: int, progress):
        self.counts = {"done": 0, "failed": 0, "skipped": 0}
        self.bar = None
        if progress is False:
            return
        from tqdm import tqdm

        self.bar = tqdm(total=total, unit="fit", disable=None if progress is None else False,
                        dynamic_ncols=True, desc="fits")

    def update(self, row: dict) -> None:
        key = "skipped" if row.get("skipped") else "done" if row.get("success") else "failed"
        self.counts[key] += 1
        if self.bar is not None:
            self.bar.set_postfix(self.counts, refresh=False)
            self.bar.update(1)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def fit_many(paths_or_tables, models, *, client=None, outdir=None, force: bool = False,
             plot: bool = False, return_results: bool = False, workers: int | None = None,
             scheduler: str | None = None, dashboard: str | None = None,
             progress: bool | None = False, keep_cluster: bool = True, **fit_options):
    """Fit every model in ``models`` to every input, on Dask; return a pandas DataFrame.

    Args:
        paths_or_tables: paths, globs, text files listing paths (see
            :func:`brdffit.batch.inputs.expand`), or tables in memory (anything with
            ``.to_samples()``, named by their ``name``); one of them or a list.
        models: a registered model name, a comma-separated string (``"ggx,beckmann"``) or a
            list of names.
        client: a ``distributed.Client`` to run on; by default a scheduler at ``scheduler`` or
            ``DASK_SCHEDULER_ADDRESS``, else a local cluster of ``workers`` processes (one per
            core; :func:`open_client`), closed to other users (TLS with credentials of its
            own) and without an HTTP server unless ``dashboard`` gives the scheduler's
            dashboard an address (``"127.0.0.1:8787"``).
        keep_cluster: keep that local cluster for the session (default): the next call with
            the same ``workers`` and ``dashboard`` runs on it, on workers that have already
            compiled their programs; it closes at exit or with :func:`close_session`
            (:func:`session_client` gives its client). ``False``: a cluster for this call
            alone, closed when it returns.
        outdir: if given, each result is written to ``outdir/<material>/<model>.json`` (and
            figures with ``plot``), the table to ``outdir/results.parquet`` and ``.csv``, and
            results already there for the same input checksum and options are read back
            instead of refitted (``skipped``), unless ``force``. The table holds every result
            of the folder: this call's rows are merged into the one already there (a row of
            the same material and model replaced; :func:`brdffit.batch.table.merge`), and a
            table that is not a batch table raises ``BatchOutputError`` before any work.
        return_results: also return the :class:`~brdffit.FitResult` of each row (None where a
            job failed): ``(frame, results)``.
        progress: a progress bar on stderr (``None``: when stderr is a terminal).
        **fit_options: keywords of :func:`brdffit.fit`, applied to every job: ``options``
            (a :class:`~brdffit.config.FitOptions`, a preset say) and the options by name,
            checked here before any work as :func:`brdffit.fit` checks them (``throw`` is
            always False: a fit that does not converge is a row with ``success=False``).

    Rows follow the inputs, then the models; columns are those of :mod:`brdffit.batch.table`.
    An option that is no option or out of its range raises (``TypeError``,
    :class:`~brdffit.errors.ConfigError`, :class:`~brdffit.errors.UnknownNameError`) before any
    work. Past that, failures never raise: a malformed input, a fit that cannot run, or a worker
    that dies is a row with ``success=False`` and the reason in ``message``.
    """
    from ..fitting import fit_options as checked

    fit_options.pop("throw", None)
    fit_options = checked(fit_options.pop("options", None), **fit_options)
    names = [m.strip() for m in models.split(",")] if isinstance(models, str) else list(models)
    from ..models.registry import get_model

    names = list(dict.fromkeys(get_model(m).name for m in names))  # errors list valid models
    job_list = make_jobs(inputs.materials(paths_or_tables),
                         [(m, dict(fit_options)) for m in names])
    out = run_batch(job_list, outdir=outdir, force=force, plot=plot,
                    want_results=return_results, client=client, workers=workers,
                    scheduler=scheduler, dashboard=dashboard, progress=progress,
                    keep=keep_cluster)
    return (out.frame, out.results) if return_results else out.frame
