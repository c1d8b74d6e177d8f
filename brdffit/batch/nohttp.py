"""Local Dask workers without an HTTP server.

A Dask worker opens an HTTP listener (metrics, health) even when no dashboard is asked for.
:class:`NoHttp` closes it before the worker's first job; the routes are empty anyway on a local
cluster of brdffit (:data:`brdffit.batch.runner.NO_HTTP`), so nothing is served in between.
"""

from __future__ import annotations

from distributed.diagnostics.plugin import WorkerPlugin


def stop_http(node) -> None:
    """Close the HTTP listener of a Dask scheduler or worker, if it has one."""
    server = getattr(node, "http_server", None)
    if server is not None:
        server.stop()


class NoHttp(WorkerPlugin):
    """Dask worker plugin: close the worker's HTTP listener (:func:`stop_http`)."""

    name = "brdffit-no-http"

    def setup(self, worker):
        stop_http(worker)
