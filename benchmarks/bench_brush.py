"""Benchmark of the sculpt brush (issue 8), reproducing figure 10 of the paper.

    python benchmarks/bench_brush.py             # all meshes, dabs of ~800 / 1,800 / 2,600 vertices
    python benchmarks/bench_brush.py --quick     # fewer dabs, skip the largest mesh
    python benchmarks/bench_brush.py --solvers   # also compare the linear solvers per dab size (auto = split)
    python benchmarks/bench_brush.py --profile   # also split each dab into its phases
    python benchmarks/bench_brush.py --sizes     # Suzanne 8K against 126K, dabs interleaved (size independence)

Figure 10 plots sculpted vertices per second for dabs of ~800, ~1,800 and
~2,600 vertices on models of 12K, 40K and 164K vertices (paper: 800 vertices
in 0.1 s, 2,600 in 0.5 s on a 2012 quad-core).  Here: camelhead (11K, open,
triangles), Spot subdivided twice (47K quads), Spot subdivided three times
(187K quads, the closest to 164K among the shared meshes) and AMO (90K
triangles, a scanned mesh in file order).  For every dab the radius is chosen
so that exactly the target number of vertices lies inside the sphere; centres
are random vertices (fixed seed).  Timed: ``Brush.dab`` (query,
classification, assembly, solve, commit and cache update), wall clock and
process CPU time, median over the dabs; each dab is then undone (not timed)
so the next one sees the input surface and the targeted vertex count
(``--keep`` keeps them: repeated λ = -50 dabs inflate small meshes enough to
empty the spheres).  A last case times a stroke of overlapping dabs
(spacing 0.25 r) that are all kept.
``--sizes`` times 2,600-vertex dabs on Suzanne subdivided twice (7,958 vertices) and four times
(126,290) in one loop, one dab on each mesh in turn, so a change of the machine's load touches
both alike; it prints each mesh's median and phases, and their ratio.
"vertices/s" counts the solved (moved) vertices.  The machine has 2 cores
that other jobs share; the load average is printed with the results.
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
sys.path.insert(0, str(HERE.parent / "src"))

import shapeflow as sf  # noqa: E402

SHARED = Path(os.environ.get("SHAPEFLOW_SHARED", HERE.parent.parent / "shared")) / "meshes"
TARGETS = (800, 1800, 2600)


def load_meshes(quick: bool):
    def spot(levels):
        return sf.subdivide(sf.load(SHARED / "spot_quad.obj"), levels)

    cases = [("camelhead 11K (tri, open)", lambda: sf.load(SHARED / "camelhead_tri_open.obj")),
             ("spot x2 47K (quad)", lambda: spot(2)),
             ("amo 90K (tri)", lambda: sf.load(SHARED / "amo_large_tri.obj"))]
    if not quick:
        cases.append(("spot x3 187K (quad)", lambda: spot(3)))
    for name, make in cases:
        t0 = time.perf_counter()
        mesh = make()
        yield name, mesh, time.perf_counter() - t0


def centres_and_radii(mesh, target: int, count: int, seed: int):
    """Random vertex centres and, for each, the radius holding ``target`` vertices."""
    rng = np.random.default_rng(seed)
    V = mesh.vertices
    idx = rng.choice(mesh.n_vertices, count, replace=False)
    radii = []
    for i in idx:
        d = np.linalg.norm(V - V[i], axis=1)
        kth = np.partition(d, target)[target - 1:target + 1]
        radii.append(0.5 * (kth[0] + kth[1]))       # exactly `target` vertices inside
    return V[idx], np.array(radii)


def run_dabs(brush, centres, radii, warmup: int = 3, keep: bool = False):
    """Time ``brush.dab`` (commit and cache update included).  Unless ``keep``,
    each dab is undone afterwards (untimed), so every dab sees the input surface
    and holds the targeted number of vertices."""
    times, cpu, moved, inside, bws, solvers = [], [], [], [], [], []
    for j, (c, r) in enumerate(zip(centres, radii)):
        brush.radius = r
        t0 = time.perf_counter()
        c0 = time.process_time()
        m = brush.dab(c)
        dc = time.process_time() - c0
        dt = time.perf_counter() - t0
        if not keep:
            brush.undo()
        if j < warmup:
            continue
        times.append(dt)
        cpu.append(dc)
        moved.append(m.size)
        inside.append(brush.last.n_inside)
        bws.append(brush.last.bandwidth)
        solvers.append(brush.last.solver)
    return np.array(times), np.array(cpu), np.array(moved), np.array(inside), np.array(bws), solvers


def stroke_path(mesh, start, r, steps: int = 4):
    """A polyline of surface vertices about 2 r apart, walking away from ``start``."""
    V = mesh.vertices
    pts = [start]
    for _ in range(steps):
        d_prev = np.linalg.norm(V - pts[-1], axis=1)
        d_start = np.linalg.norm(V - start, axis=1)
        score = np.abs(d_prev - 2 * r) - 0.5 * d_start
        pts.append(V[np.argmin(score)])
    return np.array(pts)


def fmt_ms(t: np.ndarray) -> str:
    p10, p90 = 1e3 * np.percentile(t, 10), 1e3 * np.percentile(t, 90)
    return f"{1e3 * np.median(t):6.2f} ms (p10 {p10:5.2f}, p90 {p90:6.2f})"


def profile_phases(brush, centres, radii):
    """Median time of each phase of a dab (monkeypatched timers)."""
    acc: dict = {}
    _phase_timers(brush, acc)
    for c, r in zip(centres, radii):
        brush.radius = r
        brush.dab(c)
    for k in list(acc):
        print(f"      {k:32s} {1e3 * statistics.median(acc[k]):6.2f} ms")
    for name in ("_query", "_classify", "_solve_region", "_apply", "_moved"):
        brush.__dict__.pop(name, None)
    brush._local_solver.__dict__.pop("solve", None)


def compare_solvers(mesh, lam, centres, radii):
    """Time the linear solve alone for each back end, on the systems of real dabs."""
    import scipy.linalg as sl

    from shapeflow.linalg import cholesky_available

    captured = []
    from shapeflow.linalg.local import LocalSolver, csr

    probe = sf.Brush(mesh, lam=lam, radius=float(radii[0]))
    solver = probe._local_solver
    orig = solver.solve

    def grab(k, ri, ci, vi, diag, rhs, grouped=True, notes=None):
        captured.append((k, ri, ci, vi, diag, rhs))
        return orig(k, ri, ci, vi, diag, rhs, grouped=grouped, notes=notes)

    solver.solve = grab
    for c, r in zip(centres, radii):
        probe.radius = r
        probe.preview(c)
    # "auto": the two-thread split solver where it applies (1,000+ unknowns, numba), else one band
    methods = ["auto", "banded", "lu"] + (["cholesky"] if cholesky_available() else [])
    out = {m: [] for m in methods + ["dense"]}
    for j, (k, ri, ci, vi, diag, rhs) in enumerate(captured):
        for m in methods[j % len(methods):] + methods[:j % len(methods)]:   # rotated: no method always first
            timed = LocalSolver(m)
            t0 = time.perf_counter()
            timed.solve(k, ri, ci, vi, diag, rhs)
            out[m].append(time.perf_counter() - t0)
    # dense last: its multi-threaded BLAS leaves OpenBLAS threads spinning on the other core
    for (k, ri, ci, vi, diag, rhs) in captured[:3]:
        A = csr(k, ri, ci, vi, diag).toarray()
        t0 = time.perf_counter()
        sl.cho_solve(sl.cho_factor(A), rhs)
        out["dense"].append(time.perf_counter() - t0)
    ks = [c[0] for c in captured]
    return int(np.median(ks)), {m: 1e3 * statistics.median(v) for m, v in out.items() if v}


def suzanne_sizes():
    """Suzanne subdivided twice (7,958 vertices) and four times (126,290)."""
    m = sf.load(SHARED / "suzanne_hybrid_open.obj")
    return [(f"suzanne x{k} ({n:,})", sf.subdivide(m, k)) for k, n in ((2, 7958), (4, 126290))]


def interleaved_sizes(dabs: int, lam: float) -> None:
    """2,600-vertex dabs on a small and a large mesh, alternating, with each dab's phases."""
    cases = []
    for name, mesh in suzanne_sizes():
        brush = sf.Brush(mesh, lam=lam, radius=1.0)
        centres, radii = centres_and_radii(mesh, 2600, dabs, seed=2600)
        cases.append((name, brush, centres, radii, {}))
    for name, brush, _, _, acc in cases:
        _phase_timers(brush, acc)
    total = {c[0]: [] for c in cases}
    cpu = {c[0]: [] for c in cases}
    for j in range(dabs):
        for name, brush, centres, radii, acc in cases:
            brush.radius = radii[j]
            t0, c0 = time.perf_counter(), time.process_time()
            brush.dab(centres[j])
            dt, dc = time.perf_counter() - t0, time.process_time() - c0
            counts = {k: len(v) for k, v in acc.items()}
            brush.undo()
            for k, m in counts.items():          # the undo's cache update is not the dab's
                del acc[k][m:]
            if j >= 3:
                total[name].append(dt)
                cpu[name].append(dc)
            else:
                acc.clear()
    for name, brush, _, _, acc in cases:
        t = np.array(total[name])
        print(f"  {name}: {fmt_ms(t)}, CPU {1e3 * np.median(cpu[name]):.2f} ms; "
              + ", ".join(f"{k} {1e3 * statistics.median(v):.2f}" for k, v in acc.items()))
    a, b = (statistics.median(total[c[0]]) for c in cases)
    ca, cb = (statistics.median(cpu[c[0]]) for c in cases)
    print(f"  large / small: {b / a:.2f} (wall), {cb / ca:.2f} (CPU)")


def _phase_timers(brush, acc: dict) -> None:
    """Time a brush's phases into ``acc`` (label -> list of seconds) from now on."""
    def wrap(obj, name, label):
        f = getattr(obj, name)

        def g(*a, **k):
            t0 = time.perf_counter()
            out = f(*a, **k)
            acc.setdefault(label, []).append(time.perf_counter() - t0)
            return out
        setattr(obj, name, g)

    wrap(brush, "_query", "query")
    wrap(brush, "_classify", "classify")
    wrap(brush, "_solve_region", "assembly+solve")
    wrap(brush._local_solver, "solve", "linear solve")
    wrap(brush, "_apply", "commit")
    wrap(brush, "_moved", "cache update (in commit)")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="12 dabs per case, skip the 187K mesh")
    ap.add_argument("--dabs", type=int, default=103,
                    help="dabs per case (3 of them warm-up); a case then lasts ~0.5 s, "
                         "longer than most of the machine's noise bursts")
    ap.add_argument("--lam", type=float, default=-50.0, help="λ of every dab (default -50)")
    ap.add_argument("--solvers", action="store_true", help="compare auto (split) / banded / SuperLU / cholespy / dense")
    ap.add_argument("--profile", action="store_true", help="median time of each phase of a dab")
    ap.add_argument("--keep", action="store_true", help="keep every dab (no undo between timed dabs)")
    ap.add_argument("--sizes", action="store_true",
                    help="only Suzanne 8K against 126K, 2,600-vertex dabs interleaved")
    ap.add_argument("--json", metavar="PATH", help="also write the table (for docs/gallery.py fig10)")
    args = ap.parse_args(argv)
    dabs = 12 if args.quick else args.dabs
    print(f"shapeflow {sf.__version__}, numpy {np.__version__}, {os.cpu_count()} cores; "
          f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    how = "each kept" if args.keep else "each committed, then undone untimed"
    print(f"λ = {args.lam:g}, {dabs - 3} timed dabs per case (random centres, {how})\n")
    if args.sizes:
        interleaved_sizes(dabs, args.lam)
        print(f"\nload average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
        return 0
    table = []
    for name, mesh, t_load in load_meshes(args.quick):
        t0 = time.perf_counter()
        brush = sf.Brush(mesh, lam=args.lam, radius=1.0)
        t_build = time.perf_counter() - t0
        print(f"{name}: {mesh.n_vertices} vertices; mesh {t_load:.2f} s, Brush set-up {t_build:.2f} s")
        for target in TARGETS:
            centres, radii = centres_and_radii(mesh, target, dabs, seed=target)
            t, cpu, moved, inside, bws, solvers = run_dabs(brush, centres, radii, keep=args.keep)
            vps = np.median(moved / t)
            used = {s: solvers.count(s) for s in set(solvers)}
            print(f"  {target:4d} inside ({np.median(moved):5.0f} solved, band {np.median(bws):4.0f}): "
                  f"{fmt_ms(t)}, CPU {1e3 * np.median(cpu):5.2f} ms; {vps / 1e3:5.0f}K vertices/s; {used}")
            table.append((name, mesh.n_vertices, target, float(np.median(t)), vps, float(np.median(cpu))))
            if args.profile:
                c2, r2 = centres_and_radii(mesh, target, 12, seed=target + 1)
                profile_phases(brush, c2, r2)
            if args.solvers:
                k, res = compare_solvers(mesh, args.lam, *centres_and_radii(mesh, target, 8, seed=target + 2))
                print("      solve only, median over 8 systems of ~%d unknowns: %s" % (
                    k, ", ".join(f"{m} {v:.2f} ms" for m, v in res.items())))
        # a stroke: overlapping dabs of ~2,600 vertices, all kept
        c0, r0 = centres_and_radii(mesh, 2600, 1, seed=99)
        path = stroke_path(mesh, c0[0], r0[0])
        brush.radius = r0[0]
        centres = brush.dab_centers(path, 0.25)
        t, cpu, moved, inside, bws, solvers = run_dabs(brush, centres, np.full(len(centres), r0[0]),
                                                       warmup=0, keep=True)
        print(f"  stroke of {len(centres)} dabs, r for 2600 at the start ({np.median(moved):5.0f} solved): "
              f"{fmt_ms(t)}, CPU {1e3 * np.median(cpu):5.2f} ms")
        print(f"  spatial-index rebuilds: {brush.tree_rebuilds}")
    load_after = os.getloadavg()
    print(f"\nload average after: {' '.join(f'{x:.2f}' for x in load_after)}")
    if args.json:
        import datetime
        import json

        rows = [dict(mesh=r[0], vertices=r[1], inside=r[2], seconds=r[3], vertices_per_second=r[4], cpu_seconds=r[5])
                for r in table]
        meta = dict(date=datetime.date.today().isoformat(), shapeflow=sf.__version__, numpy=np.__version__,
                    cores=os.cpu_count(), load_after=list(load_after), lam=args.lam, timed_dabs=dabs - 3,
                    compiled=sf.accel.available())
        Path(args.json).write_text(json.dumps(dict(meta=meta, rows=rows), indent=1) + "\n")
    print("\nmedian wall ms per dab [CPU ms] (rows: mesh; columns: vertices inside the sphere)")
    print(f"{'':28s}" + "".join(f"{t:>16d}" for t in TARGETS))
    for name in dict.fromkeys(r[0] for r in table):
        rows = [r for r in table if r[0] == name]
        print(f"{name:28s}" + "".join(f"{1e3 * r[3]:9.2f} [{1e3 * r[5]:4.2f}]" for r in rows))
    print("\nsculpted vertices per second (median)")
    for name in dict.fromkeys(r[0] for r in table):
        rows = [r for r in table if r[0] == name]
        print(f"{name:28s}" + "".join(f"{r[4] / 1e3:15.0f}K" for r in rows))
    print("paper (2012):                  ~100 ms at 800, ~500 ms at 2,600")
    worst = max(r[3] for r in table if r[2] == 2600)
    print(f"target: 2,600-vertex dab <= 5 ms median; slowest mesh here: {1e3 * worst:.2f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
