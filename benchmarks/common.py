"""Pieces the benchmarks share: the path set-up, a median timer and the 126K Suzanne test mesh."""

from __future__ import annotations

import os
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
SHARED = Path(os.environ.get("SHAPEFLOW_SHARED", ROOT.parent / "shared")) / "meshes"   # or $SHAPEFLOW_SHARED/meshes


def median_time(fn, reps: int) -> float:
    """Median wall time of ``reps`` calls of ``fn``."""
    ts = []
    for _ in range(reps):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts)


def suzanne_126k():
    """Suzanne (the shared hybrid mesh) subdivided until it has 100K+ vertices: 126,290."""
    import shapeflow as sf

    suz = sf.load(SHARED / "suzanne_hybrid_open.obj")
    while suz.n_vertices < 100_000:
        suz = sf.subdivide(suz, 1)
    return suz
