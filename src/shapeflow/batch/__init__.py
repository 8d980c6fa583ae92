"""Whole datasets: one operation on every file of a folder, glob or manifest, on Dask.

``shapeflow batch INPUTS OUTDIR OPERATION`` on the command line, :func:`run` in
Python, :func:`process_file` for any other runner (joblib, Ray, a plain
``multiprocessing.Pool``).  Needs ``pip install 'shapeflow[batch]'`` (Dask's
distributed scheduler; fsspec for URLs).  Guide: docs/batch.md.

>>> import shapeflow.batch as sb                                      # doctest: +SKIP
>>> report = sb.run("scans/**/*.ply", "smoothed", "smooth --strength 2")  # doctest: +SKIP
>>> print(report.summary())                                           # doctest: +SKIP
"""

from .engine import local_cluster, run
from .inputs import Job, expand_inputs, plan_jobs
from .manifest import MANIFEST_NAME, Manifest
from .operation import Operation, parse_operation
from .report import BatchReport
from .task import process_file

__all__ = ["run", "local_cluster", "process_file", "BatchReport", "Operation", "parse_operation", "Job",
           "expand_inputs", "plan_jobs", "Manifest", "MANIFEST_NAME"]
