"""Files per second of ``shapeflow batch`` against a plain loop and a multiprocessing.Pool, one run.

    python benchmarks/bench_batch.py [--files 48] [--reps 3] [--workers 2]

The dataset: ``--files`` meshes in OBJ, PLY, OFF and STL made from the bundled Spot (2,930
vertices) and Spot subdivided once (11,720), each rotated; the operation ``enhance --strength 20``.
Each way runs the same per-file function (:func:`shapeflow.batch.process_file`, one thread per
file) into a fresh folder: in this process one file after another, in a ``multiprocessing.Pool``
of ``--workers`` processes, and through :func:`shapeflow.batch.run` on a Dask LocalCluster of as
many one-thread workers (started once, outside the timing, as a user reusing a cluster would; its
start-up is printed apart).  Medians of ``--reps`` runs.  The overhead per file is the wall time
times the workers, less the files' own time (their records' ``seconds``), per file: what the way
of running adds to each file (scheduling, transfer, the manifest, idle workers at the end).
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from multiprocessing import get_context
from pathlib import Path

import numpy as np
from common import median_time  # noqa: F401,E402  (first: it puts src/ on the path)

import shapeflow as sf  # noqa: E402
import shapeflow.batch as sb  # noqa: E402

OP = "enhance --strength 20"
FORMATS = (".obj", ".ply", ".off", ".stl")


def make_dataset(root: Path, n: int) -> list[str]:
    spot = sf.load_example("spot")
    bigger = sf.subdivide(spot, 1)
    rng = np.random.default_rng(0)
    out = []
    for i in range(n):
        base = bigger if i % 4 == 3 else spot
        q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
        mesh = base.with_vertices(base.vertices @ q.T)
        path = root / f"d{i % 3}" / f"m{i:03d}{FORMATS[i % len(FORMATS)]}"
        path.parent.mkdir(parents=True, exist_ok=True)
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")     # STL/OFF keep positions only: expected here
            sf.save(path, mesh)
        out.append(str(path))
    return out


def jobs_for(files: list[str], root: Path, outdir: Path) -> list[tuple[str, str, str]]:
    return [(f, str(outdir / os.path.relpath(f, root)), OP) for f in files]


def sequential(jobs):
    return [sb.process_file(*j) for j in jobs]


def pooled(pool, jobs):
    return pool.starmap(sb.process_file, jobs, chunksize=1)


def timed(fn, *args):
    t0 = time.perf_counter()
    recs = fn(*args)
    return time.perf_counter() - t0, recs


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--files", type=int, default=48)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        root = tmp / "in"
        files = make_dataset(root, a.files)
        rows = {"sequential loop (1 process)": [], f"multiprocessing.Pool({a.workers})": [],
                f"shapeflow.batch.run, Dask LocalCluster({a.workers})": []}
        busy = {k: [] for k in rows}
        t0 = time.perf_counter()
        cluster, client = sb.local_cluster(a.workers)
        start = time.perf_counter() - t0
        with get_context("fork").Pool(a.workers) as pool:
            pooled(pool, jobs_for(files[:a.workers], root, tmp / "warm"))     # import and load kernels
            sb.run(files[:a.workers], str(tmp / "warmd"), OP, client=client, progress=False)
            sequential(jobs_for(files[:1], root, tmp / "warms"))
            for r in range(a.reps):   # interleaved, so a change of machine load touches every way alike
                names = list(rows)
                t, recs = timed(sequential, jobs_for(files, root, tmp / f"s{r}"))
                rows[names[0]].append(t)
                busy[names[0]].append(sum(x["seconds"] for x in recs))
                t, recs = timed(pooled, pool, jobs_for(files, root, tmp / f"p{r}"))
                rows[names[1]].append(t)
                busy[names[1]].append(sum(x["seconds"] for x in recs))
                t, rep = timed(lambda: sb.run(str(root), str(tmp / f"d{r}"), OP, client=client, progress=False))
                assert rep.ok and len(rep.done) == a.files, rep.summary()
                rows[names[2]].append(t)
                busy[names[2]].append(sum(x["seconds"] for x in rep.records))
        client.close()
        cluster.close()
    print(f"{a.files} files ({', '.join(FORMATS)}; 2,930 and 11,720 vertices), '{OP}', "
          f"{os.cpu_count()} cores, medians of {a.reps} runs, {time.strftime('%Y-%m-%d')}")
    print(f"Dask LocalCluster({a.workers}) start-up, once: {start:.2f} s")
    base = statistics.median(rows[next(iter(rows))])
    print(f"{'way':52s} {'wall s':>8s} {'files/s':>8s} {'vs loop':>8s} {'overhead/file':>14s}")
    for name, ts in rows.items():
        t = statistics.median(ts)
        workers = 1 if name.startswith("sequential") else a.workers
        over = (t * workers - statistics.median(busy[name])) / a.files
        print(f"{name:52s} {t:8.2f} {a.files / t:8.1f} {base / t:7.2f}x {over * 1e3:11.1f} ms")


if __name__ == "__main__":
    main()
