"""Benchmark: what sharp features cost — the feature-aware flow step and creased subdivision.

    python benchmarks/bench_features.py [--rounds N] [--angle DEG]

* **flow**: one step ``flow(mesh, 1.0)`` against ``flow(mesh, 1.0, feature_angle=DEG)`` (sharp
  edges found from the dihedral angle inside the call) on the 126,290-vertex Suzanne (the fixture
  Suzanne subdivided 4 times, as ``bench_flow.py``), "fresh" (the Mesh built from arrays in the
  timed call: validation, topology, operator pattern) and "warm" (one Mesh reused, its topology
  cached); also ``feature_angle=5`` (many sharp edges: creases all over the model);
* **subdivision**: ``subdivide(mesh, 2)`` against the same with creases — every 8th ring of a
  200 × 200 quad torus (40,000 vertices → 640,000), values 0.2 (fading within the first level),
  0.5, 0.8 and 1 — built from arrays in each call.

Every comparison runs its variants alternately, round after round (the machine is shared), and
prints the medians and their ratio.  Needs ``shared/`` beside the repository (or
``SHAPEFLOW_SHARED``) for the Suzanne fixture mesh.
"""

from __future__ import annotations

import argparse
import gc
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

import shapeflow as sf  # noqa: E402


def shared_dir() -> Path:
    env = os.environ.get("SHAPEFLOW_SHARED")
    for c in ([Path(env)] if env else []) + [ROOT.parent / "shared", ROOT / "shared"]:
        if (c / "fixtures" / "blender" / "meshes").is_dir():
            return c
    raise SystemExit("shared/ not found beside the repository (set SHAPEFLOW_SHARED)")


def suzanne_126k():
    d = np.load(shared_dir() / "fixtures" / "blender" / "meshes" / "suzanne.npz")
    m = sf.subdivide(sf.Mesh.from_csr(d["vertices"], d["face_sizes"], d["face_indices"]), 4)
    return m.vertices, m.face_sizes, m.face_indices


def torus(n: int, m: int, R: float = 2.0, r: float = 0.7):
    i, j = np.meshgrid(np.arange(n), np.arange(m), indexing="ij")
    th, ph = 2 * np.pi * i / n, 2 * np.pi * j / m
    V = np.stack([(R + r * np.cos(ph)) * np.cos(th), (R + r * np.cos(ph)) * np.sin(th), r * np.sin(ph)], -1)
    idx = lambda a, b: (a % n) * m + (b % m)  # noqa: E731
    F = np.stack([idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)], -1).reshape(-1, 4)
    ring = np.stack([idx(i, j), idx(i, j + 1)], -1)[::8].reshape(-1, 2)      # every 8th ring of edges
    values = np.resize([0.2, 0.5, 0.8, 1.0], ring.shape[0] // m).repeat(m)
    return V.reshape(-1, 3), np.full(n * m, 4), F.reshape(-1), (ring, values)


def interleaved(variants: dict, rounds: int) -> dict:
    """Median seconds of each variant, run alternately ``rounds`` times (after one untimed round)."""
    times = {k: [] for k in variants}
    for r in range(rounds + 1):
        for k, fn in variants.items():
            gc.collect()
            t0 = time.perf_counter()
            fn()
            if r:
                times[k].append(time.perf_counter() - t0)
    return {k: statistics.median(v) for k, v in times.items()}


def report(title: str, med: dict, base: str) -> None:
    print(title)
    for k, t in med.items():
        ratio = "" if k == base else f"   {t / med[base]:.3f}x {base}"
        print(f"  {k:34s} {t * 1e3:8.1f} ms{ratio}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=15)
    ap.add_argument("--angle", type=float, default=30.0, help="feature angle of the flow comparison")
    args = ap.parse_args(argv)
    print(f"shapeflow {sf.__version__}, {time.strftime('%Y-%m-%d')}, threads {sf.accel.current().threads}, "
          f"compiled kernels {sf.accel.available()}")

    V, S, I = suzanne_126k()
    warm = sf.Mesh.from_csr(V, S, I)
    sharp = sf.flow(warm, 1.0, feature_angle=args.angle).report
    many = sf.flow(warm, 1.0, feature_angle=5.0).report
    print(f"\nSuzanne {warm.n_vertices:,} vertices: feature_angle={args.angle:g} finds {sharp.sharp_edges} sharp "
          f"edges ({sharp.curve_vertices} curve vertices); feature_angle=5 finds {many.sharp_edges} "
          f"({many.curve_vertices} curve vertices, {many.feature_fixed} ends and corners)")
    med = interleaved({
        "fresh plain": lambda: sf.flow(sf.Mesh.from_csr(V, S, I), 1.0),
        f"fresh feature_angle={args.angle:g}": lambda: sf.flow(sf.Mesh.from_csr(V, S, I), 1.0,
                                                               feature_angle=args.angle),
        "fresh feature_angle=5": lambda: sf.flow(sf.Mesh.from_csr(V, S, I), 1.0, feature_angle=5.0),
        "warm plain": lambda: sf.flow(warm, 1.0),
        f"warm feature_angle={args.angle:g}": lambda: sf.flow(warm, 1.0, feature_angle=args.angle),
    }, args.rounds)
    report(f"flow, one step, λ = 1 (medians of {args.rounds} interleaved rounds)",
           {k: v for k, v in med.items() if k.startswith("fresh")}, "fresh plain")
    report("", {k: v for k, v in med.items() if k.startswith("warm")}, "warm plain")

    TV, TS, TI, creases = torus(200, 200)
    n_semi = int(((creases[1] > 0) & (creases[1] < 1)).sum())
    print(f"\ntorus {TV.shape[0]:,} vertices, {TS.size:,} quads: {creases[0].shape[0]} creased edges "
          f"({n_semi} semi-sharp)")
    med = interleaved({
        "subdivide(levels=2)": lambda: sf.subdivide(sf.Mesh.from_csr(TV, TS, TI), 2),
        "subdivide(levels=2, creases)": lambda: sf.subdivide(sf.Mesh.from_csr(TV, TS, TI), 2, creases=creases),
    }, args.rounds)
    report(f"subdivision (medians of {args.rounds} interleaved rounds)", med, "subdivide(levels=2)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
