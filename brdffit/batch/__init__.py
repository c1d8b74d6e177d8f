"""Fitting many tables with many models on Dask (``dask.distributed``): ``fit_many``.

* :mod:`.inputs`: globs, paths and lists of paths → named materials; input checksums.
* :mod:`.jobs`: one (material, model) fit on a worker, its files, the resume key.
* :mod:`.table`: the results table (columns, parquet/CSV, summary).
* :mod:`.runner`: the cluster, the jobs' outcomes (a dead worker included), ``fit_many``.
"""

from .inputs import BatchInputError
from .runner import SchedulerError, fit_many, open_client, run_batch
from .table import BASE_COLUMNS, OUTCOMES

__all__ = ["BASE_COLUMNS", "OUTCOMES", "BatchInputError", "SchedulerError", "fit_many",
           "open_client", "run_batch"]
