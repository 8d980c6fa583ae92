"""``shapeflow batch INPUTS OUTDIR OPERATION [options]``: one command on every file, on Dask.

Exit status: 0 when every file is done (or was done before), 1 when any failed
(each failure is in the manifest with its message), 2 for a usage error, 130 when
interrupted (the files finished so far are recorded; the same command resumes).
"""

from __future__ import annotations

import argparse
import re

from ..errors import ParameterError
from .common import eprint

_SIZE = re.compile(r"^\s*([0-9]*\.?[0-9]+)\s*([kmgt]?)(i?b)?\s*$", re.IGNORECASE)


def parse_size(text: str) -> int:
    """Bytes from ``4G``, ``512M``, ``1.5GiB``, ``2000000000`` (K/M/G/T are powers of 1024)."""
    m = _SIZE.match(text)
    if not m:
        raise ParameterError(f"--max-memory must be a size such as 4G, 512M or a number of bytes; got {text!r}")
    value = float(m.group(1)) * 1024 ** " kmgt".index((m.group(2) or " ").lower())
    if value < 1:
        raise ParameterError(f"--max-memory must be positive; got {text!r}")
    return int(value)


def register(sub) -> None:
    p = sub.add_parser(
        "batch", help="run a command on every file of a folder, glob or manifest (Dask; local or a cluster)",
        usage="shapeflow batch [options] INPUTS OUTDIR OPERATION [operation options] [--then OPERATION ...]",
        description="Run one single-file command (enhance, smooth, flow, subdivide, family, render, curvature, "
                    "brush) with its options on every file of INPUTS, writing the results under OUTDIR with "
                    "the input tree's layout.  A manifest OUTDIR/shapeflow-batch.jsonl records every file; "
                    "running the same command again skips the files already done.  Needs shapeflow[batch].",
        epilog="Examples:  shapeflow batch 'scans/**/*.ply' smoothed smooth --strength 2    "
               "shapeflow batch --scheduler tcp://10.0.0.5:8786 list.txt out enhance -s 50 --then subdivide -l 1")
    p.add_argument("inputs", metavar="INPUTS",
                   help="a glob (quote it; ** is recursive), a folder, or a manifest (.txt/.csv of paths or URLs); "
                        "fsspec URLs accepted")
    p.add_argument("outdir", metavar="OUTDIR", help="where the outputs and the manifest go")
    p.add_argument("operation", nargs=argparse.REMAINDER, metavar="OPERATION",
                   help="a command and its options, without input and output; several joined by --then")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="a running Dask scheduler (tcp://host:8786); default: a local cluster of worker processes")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="worker processes of the local cluster (default: the cores this process may use)")
    p.add_argument("--format", default=None, metavar="EXT", help="output format, e.g. ply (default: the input's)")
    p.add_argument("--force", action="store_true", help="redo files already done with the same parameters")
    p.add_argument("--timeout", type=float, default=None, metavar="SECONDS",
                   help="a file still running after this fails (its worker process is restarted)")
    p.add_argument("--max-memory", default=None, metavar="SIZE",
                   help="memory a worker may use for one file, e.g. 4G: a file estimated or found over it fails")
    p.add_argument("--retries", type=int, default=1, metavar="N",
                   help="attempts after a file's worker died (default 1; local cluster)")
    p.add_argument("--progress-interval", type=float, default=10.0, metavar="SECONDS",
                   help="seconds between two progress lines when stderr is not a terminal (default 10)")
    p.add_argument("--quiet", "-q", action="store_true", help="no progress or summary (the manifest has it all)")
    p.set_defaults(func=run)


def run(args) -> int:
    import logging

    from ..batch import run as run_batch

    max_memory = parse_size(args.max_memory) if args.max_memory is not None else None
    if not args.operation:
        raise ParameterError("no OPERATION given, e.g. 'enhance --strength 50' (see shapeflow batch --help)")
    # the command is its own application: Dask's reports of workers it restarts go to the manifest,
    # not the terminal
    for name in ("distributed", "tornado"):
        logging.getLogger(name).setLevel(logging.CRITICAL)

    def notice(text):
        if not args.quiet:
            eprint(f"shapeflow batch: {text}")

    def started(info):
        if args.quiet:
            return
        where = f"; dashboard {info['dashboard']}" if info["dashboard"] else ""
        eprint(f"shapeflow batch: {info['files']} files, {info['skipped']} done before, {info['todo']} to do "
               f"on {info['workers'] or 'no'} workers{where}")

    report = run_batch(args.inputs, args.outdir, args.operation, scheduler=args.scheduler, workers=args.workers,
                       format=args.format, force=args.force, timeout=args.timeout, max_memory=max_memory,
                       retries=args.retries, progress=False if args.quiet else None,
                       progress_interval=args.progress_interval, on_start=started, on_notice=notice)
    if not args.quiet:
        for line in report.summary().splitlines():
            eprint(f"shapeflow batch: {line}")
    if report.interrupted:
        return 130
    return 0 if report.ok else 1
