"""Benchmark of families (issue 6): the 48 shapes of figure 1 from one solve.

    python benchmarks/bench_family.py                  # family, 48 x flow(), Blender (sampled)
    python benchmarks/bench_family.py --blender-all    # time all 48 Blender evaluations (~4 s each)
    python benchmarks/bench_family.py --quick          # family only
    python benchmarks/bench_family.py --blender-only   # the Blender evaluations alone (a Python with bpy)
    python benchmarks/bench_family.py --ratio          # family / flow() at its largest λ, Suzanne x3 (issue 35)
    python benchmarks/bench_family.py --check-cost     # the members' true-residual check: family with / without

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

``--ratio`` (issue 35): the same 48 members on Suzanne (shared/meshes/suzanne_hybrid_open.obj beside
the checkout or under ``SHAPEFLOW_SHARED``,
Catmull-Clark ``--suzanne-levels`` times: 31,658 vertices at 3) against one ``flow()`` at the
family's largest |λ| (λ = -235), warm mesh, in interleaved rounds (family and flow alternate,
their order swapped every round) under four settings in turn each round: kernels as by default
(``auto``: at 31K vertices NumPy/SciPy, where flow() factorises) and forced (``force``: the
compiled seed CG against flow()'s Gauss-Seidel CG), each with the default threads and with one.
Printed per setting: the medians of the family, of flow() and of the per-round ratios, and the
largest deviation of the family's member from that flow() (x diagonal).

``--check-cost``: the same family on Suzanne with its true-residual check
(``flow.family_paths.check_members``) and with the check replaced by one that passes every member,
in interleaved rounds (order swapped every round), kernels as by default and forced: medians and the
median of the per-round ratios.
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
    src = Path(os.environ.get("SHAPEFLOW_SHARED", HERE.parent.parent / "shared")) / "meshes" / "spot_quad.obj"
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
    ap.add_argument("--blender-only", action="store_true",
                    help="only the Blender evaluations (for a Python with bpy but without the fast extra; "
                         "benchmarks/measure_all.py runs it so)")
    ap.add_argument("--quick", action="store_true", help="family only (no flow() or Blender comparison)")
    ap.add_argument("--ratio", action="store_true", help="family / flow() at its largest λ on Suzanne (issue 35)")
    ap.add_argument("--check-cost", action="store_true", help="family with / without its true-residual check")
    ap.add_argument("--rounds", type=int, default=15, help="interleaved rounds of --ratio")
    ap.add_argument("--suzanne-levels", type=int, default=3, help="subdivisions of Suzanne for --ratio")
    args = ap.parse_args(argv)
    if args.ratio:
        return ratio(args.rounds, args.suzanne_levels)
    if args.check_cost:
        return check_cost(args.rounds, args.suzanne_levels)

    mesh, origin = load_mesh(args.levels)
    V, S, I = mesh.vertices, mesh.face_sizes, mesh.face_indices
    lams = np.arange(0.0, -240.0, -5.0)
    k = lams.size
    print(f"{origin}: {mesh.n_vertices:,} vertices, {mesh.n_faces:,} faces; {k} members "
          f"λ = {lams[0]:g}, {lams[1]:g}, ..., {lams[-1]:g}; 1 iteration, paper mode")
    print(f"  before: {load()}")
    if args.blender_only:
        ok = blender_rows(mesh, lams, sf.family(mesh, lams, compat="blender"), None, args)
        print(f"  after: {load()}")
        return 0 if ok else 2

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

    if not args.no_blender:
        blender_rows(mesh, lams, shapes_bl, t_warm, args)
    print(f"  after: {load()}")
    return 0


def blender_rows(mesh, lams, shapes_bl, t_warm, args) -> bool:
    """48 evaluations of Blender's Laplacian Smooth (sampled unless --blender-all), against the family's
    compat='blender' members; against the warm family's time when given.  False when bpy does not import."""
    import blender_ref

    if not blender_ref.available():
        print("  Blender: bpy not importable, skipped")
        return False
    V, S, I = mesh.vertices, mesh.face_sizes, mesh.face_indices
    k = lams.size
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
    vs = f"= {t_blender / t_warm:.0f}x the family (warm); " if t_warm else ""
    print(f"  {f'{k} x Blender Laplacian Smooth':<46s} {t_blender * 1e3:10.1f} ms  {vs}{how}")
    print(f"  {'':46s} per evaluation: median {statistics.median(secs) * 1e3:.0f} ms; "
          f"family(compat='blender') vs Blender: max {dev:.1e} x diagonal (Blender is float32)")
    return True


def suzanne(levels: int):
    shared = Path(os.environ.get("SHAPEFLOW_SHARED", HERE.parent.parent / "shared"))
    src = shared / "meshes" / "suzanne_hybrid_open.obj"
    mesh = sf.load(src)
    for _ in range(levels):
        mesh = sf.subdivide(mesh, 1)
    return mesh, src


def check_cost(rounds: int, levels: int) -> int:
    """Family of 48 with and without its true-residual check, interleaved rounds, kernels auto / forced."""
    import importlib
    import inspect

    from shapeflow import accel

    paths = importlib.import_module("shapeflow.flow.family_paths")
    real = paths.check_members

    def none_wrong(*args, **kwargs):          # whatever check_members takes: no member is wrong
        members = inspect.signature(real).bind(*args, **kwargs).arguments["members"]
        return members[:0]

    mesh, src = suzanne(levels)
    lams = np.arange(0.0, -240.0, -5.0)
    print(f"{src.stem} subdivided {levels}x: {mesh.n_vertices:,} vertices; {lams.size} members; "
          f"{rounds} interleaved rounds, family with / without the true-residual check")
    print(f"  before: {load()}")
    for kernels in ("auto", "force"):
        with accel.use(kernels=kernels):
            sf.family(mesh, lams)                     # warm-up
            on, off = [], []
            for r in range(rounds):
                for check in ((True, False) if r % 2 == 0 else (False, True)):
                    paths.check_members = real if check else none_wrong
                    t0 = time.perf_counter()
                    sf.family(mesh, lams)
                    (on if check else off).append(time.perf_counter() - t0)
            paths.check_members = real
        ratios = [a / b for a, b in zip(on, off)]
        print(f"  kernels {kernels:<6s} with {statistics.median(on) * 1e3:7.1f} ms  without "
              f"{statistics.median(off) * 1e3:7.1f} ms  ratio median {statistics.median(ratios):.3f} "
              f"(rounds {min(ratios):.3f}-{max(ratios):.3f})")
    print(f"  after: {load()}")
    return 0


def ratio(rounds: int, levels: int) -> int:
    """Family of 48 against flow() at λ = -235, interleaved rounds under four backend settings."""
    from shapeflow import accel

    mesh, src = suzanne(levels)
    lams = np.arange(0.0, -240.0, -5.0)
    lam_max = float(lams[np.argmax(np.abs(lams))])
    settings = {"kernels auto, threads auto": dict(kernels="auto"),
                "kernels auto, 1 thread": dict(kernels="auto", threads=1),
                "kernels force, threads auto": dict(kernels="force"),
                "kernels force, 1 thread": dict(kernels="force", threads=1)}
    print(f"{src.stem} subdivided {levels}x: {mesh.n_vertices:,} vertices; {lams.size} members λ = 0 ... "
          f"{lams[-1]:g} against flow(λ = {lam_max:g}); {rounds} interleaved rounds")
    print(f"  before: {load()}")
    times = {name: ([], []) for name in settings}
    info = {}
    for name, kw in settings.items():      # warm-up: compiled code, caches of the mesh
        with accel.use(**kw):
            shapes, rep = sf.family(mesh, lams, return_report=True)
            out = sf.flow(mesh, lam_max)
        dev = float(np.abs(shapes[-1] - out.vertices).max()) / mesh.diagonal
        info[name] = (rep, out.report, dev)
    for r in range(rounds):
        for name, kw in settings.items():
            tf, tl = times[name]
            with accel.use(**kw):
                for which in ((0, 1) if r % 2 == 0 else (1, 0)):
                    t0 = time.perf_counter()
                    if which == 0:
                        sf.family(mesh, lams)
                        tf.append(time.perf_counter() - t0)
                    else:
                        sf.flow(mesh, lam_max)
                        tl.append(time.perf_counter() - t0)
    for name in settings:
        tf, tl = times[name]
        rep, frep, dev = info[name]
        ratios = [a / b for a, b in zip(tf, tl)]
        print(f"  {name:<28s} family {statistics.median(tf) * 1e3:7.1f} ms  flow {statistics.median(tl) * 1e3:7.1f} ms"
              f"  ratio median {statistics.median(ratios):.2f} (rounds {min(ratios):.2f}-{max(ratios):.2f})")
        pre = getattr(frep, "preconditioner", "") or ""
        print(f"  {'':28s} [{rep.solver}, {rep.krylov_iterations} shared iterations; flow: {frep.solver} "
              f"{pre} {list(frep.cg_iterations)}; member vs flow() {dev:.1e} x diagonal]")
    print(f"  after: {load()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
