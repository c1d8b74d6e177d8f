"""Fitting many tables with many models on Dask (``dask.distributed``): ``fit_many``.

* :mod:`.inputs`: globs, paths and lists of paths → named materials; input checksums.
* :mod:`.jobs`: one (material, model) fit on a worker, its files, the resume key.
* :mod:`.outdir`: the output folder, checked before any work and written without following
  links.
* :mod:`.table`: the results table (columns, parquet/CSV, summary; a rerun merges into it).
* :mod:`.runner`: the cluster (closed to other users, no HTTP server; ``fit_many`` keeps its
  own for the session: ``session_client``, ``close_session``), the jobs' outcomes (a dead
  worker included), ``fit_many``.
"""

from .inputs import BatchInputError
from .outdir import BatchOutputError
from .runner import (SchedulerError, check_scheduler_address, close_session, fit_many,
                     open_client, run_batch, session_client)
from .table import BASE_COLUMNS, OUTCOMES

__all__ = ["BASE_COLUMNS", "OUTCOMES", "BatchInputError", "BatchOutputError", "SchedulerError",
           "check_scheduler_address", "close_session", "fit_many", "open_client", "run_batch",
           "session_client"]
