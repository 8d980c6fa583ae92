"""Speed when the machine is busy: the default thread choice against one thread, idle and with one
and two other busy processes (started and stopped here).

    python benchmarks/bench_contention.py [--reps 9]

Cases: a fresh flow (λ = 1) on Suzanne subdivided to ~126K vertices, and dabs of 2,600
vertices (the radius set per centre) of the enhancement brush on Spot subdivided three times,
the same dabs for both settings.  For every machine state the
runs alternate between ``threads="auto"`` (the default: the cores free at the moment of the
call) and ``threads=1``, so both see the same conditions; printed are the medians and the ratio
default / one thread (target: <= 1.10 in every row).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time

import numpy as np  # noqa: E402
from common import SHARED, suzanne_126k  # noqa: E402  (first: it puts src/ on the path)

import shapeflow as sf  # noqa: E402
from shapeflow import accel  # noqa: E402

BUSY = "import time\nend = time.time() + 600\nwhile time.time() < end:\n    pass\n"


def busy(n: int) -> list:
    return [subprocess.Popen([sys.executable, "-c", BUSY]) for _ in range(n)]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=9)
    args = ap.parse_args(argv)
    import warnings

    warnings.simplefilter("ignore")
    suz = suzanne_126k()
    spot = sf.subdivide(sf.load(SHARED / "spot_quad.obj"), 3)
    brush = {t: sf.Brush(spot, lam=-50.0, radius=0.05 * spot.diagonal) for t in ("auto", 1)}
    rng = np.random.default_rng(1)
    centres = spot.vertices[rng.integers(0, spot.n_vertices, 4 * args.reps)]
    from scipy.spatial import cKDTree

    radii = cKDTree(spot.vertices).query(centres, k=2600)[0][:, -1]   # ~2,600 vertices in every sphere
    for t in ("auto", 1):   # compile and warm
        with accel.use(threads=t):
            sf.flow(suz, 1.0)
            brush[t].dab(centres[0])
            brush[t].undo()

    def flow_case(t):
        with accel.use(threads=t):
            t0 = time.perf_counter()
            sf.flow(suz.with_vertices(suz.vertices), 1.0)      # fresh topology: a fresh flow
            return time.perf_counter() - t0

    it = iter(range(10**9))
    pick = {}

    def dab_case(t):
        if t == "auto":            # the same dab for both settings (auto runs first in each pair)
            pick["i"] = next(it) % centres.shape[0]
        i = pick["i"]
        c = centres[i]
        brush[t].radius = float(radii[i])
        with accel.use(threads=t):
            t0 = time.perf_counter()
            brush[t].dab(c)
            dt = time.perf_counter() - t0
        brush[t].undo()
        return dt

    print(f"shapeflow {sf.__version__}; {os.cpu_count()} cores; flow on {suz.n_vertices:,} vertices, dabs on "
          f"{spot.n_vertices:,}; medians of {args.reps} interleaved runs\n")
    print("| case | machine | default (auto) | one thread | default / one |")
    print("|---|---|---|---|---|")
    for others in (0, 1, 2):
        procs = busy(others)
        try:
            time.sleep(0.5)
            for name, case in (("fresh flow, λ=1", flow_case), ("brush dab", dab_case)):
                times = {"auto": [], 1: []}
                for _ in range(args.reps):
                    for t in ("auto", 1):
                        times[t].append(case(t))
                a, o = statistics.median(times["auto"]), statistics.median(times[1])
                state = "idle" if others == 0 else f"{others} busy process{'es' if others > 1 else ''}"
                print(f"| {name} | {state} | {1e3 * a:.1f} ms | {1e3 * o:.1f} ms | {a / o:.2f} |", flush=True)
        finally:
            for p in procs:
                p.kill()
    return 0


if __name__ == "__main__":
    sys.exit(main())
