"""Local Dask nodes that open no HTTP listener.

A Dask scheduler and every worker open an HTTP server (dashboard, metrics, health) as they
start, whatever the settings: the scheduler on 8787 by default, a worker on a free port. A local
cluster of brdffit serves nothing over HTTP unless a dashboard is asked for, so its nodes are
these subclasses, whose :meth:`start_http_server` builds the (unused) routing application and
listens nowhere. :class:`QuietCluster` is a ``LocalCluster`` whose scheduler is a
:class:`QuietScheduler` (or Dask's own when ``dashboard=True``); :func:`quiet_workers` makes the
nannies of a worker spec start :class:`QuietWorker` processes.

The subclasses rely on what ``distributed.node.ServerNode.start_http_server`` sets
(``http_application``, ``http_server``) and leave ``services["dashboard"]`` unset, which is how
Dask itself reports a node without a dashboard.
"""

from __future__ import annotations

from distributed import LocalCluster, Scheduler, Worker
from distributed.http.routing import RoutingApplication


def _no_listener(node, routes) -> None:
    node.http_application = RoutingApplication(routes)
    node.http_server = None


class QuietScheduler(Scheduler):
    """A Dask scheduler with no HTTP listener (module docstring)."""

    def start_http_server(self, routes, dashboard_address, default_port=0, ssl_options=None):
        _no_listener(self, routes)


class QuietWorker(Worker):
    """A Dask worker with no HTTP listener (module docstring)."""

    def start_http_server(self, routes, dashboard_address, default_port=0, ssl_options=None):
        _no_listener(self, routes)


class QuietCluster(LocalCluster):
    """A ``LocalCluster`` whose scheduler is a :class:`QuietScheduler`, unless ``dashboard`` is
    true (then Dask's own scheduler serves the dashboard at ``dashboard_address``)."""

    def __init__(self, *args, dashboard: bool = False, **kwargs):
        self._quiet = not dashboard
        super().__init__(*args, **kwargs)

    async def _start(self):
        if self._quiet and self.scheduler is None and self.scheduler_spec is not None:
            self.scheduler_spec = {**self.scheduler_spec, "cls": QuietScheduler}
        await super()._start()


def quiet_workers(spec: dict) -> dict:
    """``spec`` (``LocalCluster.new_worker_spec()``: name → ``{"cls", "options"}``) with each
    nanny starting a :class:`QuietWorker`."""
    return {name: {**s, "options": {**s.get("options", {}), "worker_class": QuietWorker}}
            for name, s in spec.items()}
