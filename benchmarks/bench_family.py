"""Benchmark of families (issue 6): the 48 shapes of figure 1 from one solve.

    python benchmarks/bench_family.py                  # family, 48 x flow(), Blender (sampled)
    python benchmarks/bench_family.py --blender-all    # time all 48 Blender evaluations (~4 s each)
    python benchmarks/bench_family.py --quick          # family only

Mesh: spot_quad (shared/meshes) Catmull-Clark subdivided twice with
``shapeflow.subdivide``: 46,850 vertices, all quads (the paper's ~40K model;
once gives only 11,714).  Members: λ = 0, -5, ..., -235 (48, as figure 1),
one iteration, paper mode.  Times are medians over ``--repeat`` runs and
exclude file I/O; "fresh" builds the Mesh from arrays inside the timed region
(topology, operator structure), "warm" reuses one Mesh object.

Beside the family, in the same run: 48 independent ``flow()`` calls (sum of
the per-λ medians over ``--flow-repeat`` runs) and 48 evaluations of Blender's
Laplacian Smooth modifier (``benchmarks/blender_ref.py``, when ``bpy`` imports;
by default ``--blender-samples`` evenly spaced members are timed and the total
is extrapolated from their mean -- the output says so).  The load average is
printed before and after: the reference machine has 2 cores shared with other
jobs.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import shapeflow as sf  # noqa: E402

TARGET = 1.5  # seconds, issue 6


def load_mesh(levels: int):
    src = HERE.parent.parent / "shared" / "meshes" / "spot_quad.obj"
    if not src.exists():
        src = Path(sf.example_path("spot"))
    m = sf.load(src)
    return sf.subdivide(m, levels) if levels else m, f"{src.stem} subdivided {levels}x"


def median_time(fn, repeat: int):
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), times, out


def load() -> str:
    return "load average " + " ".join(f"{x:.2f}" for x in os.getloadavg()) + f" on {os.cpu_count()} cores"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=7, help="runs of the family (median)")
    ap.add_argument("--flow-repeat", type=int, default=3, help="runs of each of the 48 flow() calls (median)")
    ap.add_argument("--levels", type=int, default=2,
                    help="subdivision levels of spot_quad (default 2: 46,850 vertices)")
    ap.add_argument("--blender-samples", type=int, default=4, help="Blender evaluations timed (evenly spaced members)")
    ap.add_argument("--blender-all", action="store_true", help="time all 48 Blender evaluations")
    ap.add_argument("--no-blender", action="store_true")
    ap.add_argument("--quick", action="store_true", help="family only (no flow() or Blender comparison)")
    args = ap.parse_args(argv)

    mesh, origin = load_mesh(args.levels)
    V, S, I = mesh.vertices, mesh.face_sizes, mesh.face_indices
    lams = np.arange(0.0, -240.0, -5.0)
    k = lams.size
    print(f"{origin}: {mesh.n_vertices:,} vertices, {mesh.n_faces:,} faces; {k} members "
          f"λ = {lams[0]:g}, {lams[1]:g}, ..., {lams[-1]:g}; 1 iteration, paper mode")
    print(f"  before: {load()}")

    def row(label, seconds, extra=""):
        print(f"  {label:<46s} {seconds * 1e3:10.1f} ms  {extra}")

    # --- the family
    sf.family(mesh, lams[:3])  # imports, caches of this process (not of the mesh below)
    t_fresh, s_fresh, (shapes, rep) = median_time(
        lambda: sf.family(sf.Mesh.from_csr(V, S, I), lams, return_report=True), args.repeat)
    ok = "OK" if t_fresh <= TARGET else "OVER"
    row("family, fresh mesh (all included)", t_fresh,
        f"[{rep.path}, {rep.krylov_iterations} shared iterations; target <= {TARGET:.1f} s: {ok}]")
    warm = sf.Mesh.from_csr(V, S, I)
    sf.family(warm, lams[:2])
    t_warm, s_warm, (shapes, rep) = median_time(lambda: sf.family(warm, lams, return_report=True), args.repeat)
    row("family, warm topology", t_warm, f"(min {min(s_warm) * 1e3:.0f} ms, max {max(s_warm) * 1e3:.0f} ms)")
    t_bl, _, (shapes_bl, rep_bl) = median_time(
        lambda: sf.family(warm, lams, compat="blender", return_report=True), args.repeat)
    row("family, compat='blender', warm", t_bl, f"[{rep_bl.path}]")
    t_sep, _, _ = median_time(lambda: sf.family(warm, lams, strategy="separate"), 1)
    row("family, strategy='separate' (one FlowSolver)", t_sep, "(1 run)")
    if args.quick:
        print(f"  after: {load()}")
        return 0

    # --- 48 independent flow() calls
    per = np.zeros(k)
    worst = 0.0
    for m, lam in enumerate(lams):
        t, _, out = median_time(lambda: sf.flow(warm, float(lam)), args.flow_repeat)
        per[m] = t
        worst = max(worst, float(np.abs(out.vertices - shapes[m]).max()) / mesh.diagonal)
    t_flows = float(per.sum())
    row(f"{k} x flow(), warm (sum of per-λ medians)", t_flows,
        f"= {t_flows / t_warm:.1f}x the family (warm); slowest λ {per.max() * 1e3:.0f} ms")
    print(f"  {'':46s} agreement family vs flow(): max {worst:.1e} x diagonal")

    # --- Blender
    if args.no_blender:
        print(f"  after: {load()}")
        return 0
    import blender_ref

    if not blender_ref.available():
        print("  Blender: bpy not importable, skipped")
        print(f"  after: {load()}")
        return 0
    idx = np.arange(k) if args.blender_all else np.unique(
        np.round(np.linspace(1, k - 1, max(1, args.blender_samples))).astype(int))
    secs, dev = [], 0.0
    for m in idx:
        pos, sec = blender_ref.laplacian_smooth(V, S, I, lambda_factor=float(lams[m]), lambda_border=0.0,
                                                iterations=1, use_normalized=True, use_volume_preserve=False)
        secs.append(sec)
        dev = max(dev, float(np.abs(pos - shapes_bl[m]).max()) / mesh.diagonal)
    if args.blender_all:
        t_blender = float(np.sum(secs))
        how = "all 48 timed"
    else:
        t_blender = float(np.mean(secs)) * k
        how = (f"EXTRAPOLATED: mean of {len(idx)} timed members (λ = "
               f"{', '.join(f'{lams[m]:g}' for m in idx)}) x {k}")
    row(f"{k} x Blender Laplacian Smooth", t_blender, f"= {t_blender / t_warm:.0f}x the family (warm); {how}")
    print(f"  {'':46s} per evaluation: median {statistics.median(secs) * 1e3:.0f} ms; "
          f"family(compat='blender') vs Blender: max {dev:.1e} x diagonal (Blender is float32)")
    print(f"  after: {load()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
