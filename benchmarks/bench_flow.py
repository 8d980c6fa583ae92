"""Benchmark of the flow (issue 4): shapeflow against Blender's own modifier, same run.

    python benchmarks/bench_flow.py            # everything (Blender too when bpy imports)
    python benchmarks/bench_flow.py --quick    # skip the 1M-vertex case and Blender
    python benchmarks/bench_flow.py --scan 10M # a generated triangle scan: load, smooth, save, peak memory
    python benchmarks/bench_flow.py --blender-only   # Blender's modifier alone (a Python with bpy)

Prints medians over ``--repeat`` runs and ratios.  Times exclude file I/O;
"fresh" includes building the Mesh from arrays (validation, topology, operator
pattern), "warm" reuses a Mesh whose topology is cached (as in an interactive
session or a λ family).  The 1M-vertex case runs in a child process so its peak
memory (VmHWM) can be reported.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
CACHE = HERE / ".cache"
SHARED = Path(os.environ.get("SHAPEFLOW_SHARED", HERE.parent.parent / "shared"))
sys.path.insert(0, str(HERE))

import shapeflow as sf  # noqa: E402

LAST_TIMES: list = []   # the runs behind the last median_time (for the spread)


def median_time(fn, repeat: int) -> tuple[float, object]:
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    LAST_TIMES[:] = times
    return statistics.median(times), out


def spread() -> str:
    """Fastest and slowest of the last median_time's runs (the machine is shared and noisy)."""
    return f"(runs {min(LAST_TIMES) * 1e3:.0f}-{max(LAST_TIMES) * 1e3:.0f} ms)"


def suzanne_sub4():
    """Suzanne subdivided 4 times (126,290 vertices, all quads).

    Blender's own (cached by blender_ref when bpy is installed), else our
    Catmull-Clark of the fixture Suzanne (same connectivity).
    """
    cached = CACHE / "suzanne_sub4.npz"
    if cached.exists():
        d = np.load(cached)
        return d["vertices"], d["face_sizes"], d["face_indices"], "Blender subsurf (cached)"
    import blender_ref

    if blender_ref.available():
        v, s, i = blender_ref.suzanne_sub4()
        return v, s, i, "Blender subsurf"
    shared = SHARED / "fixtures" / "blender" / "meshes" / "suzanne.npz"
    d = np.load(shared)
    m = sf.subdivide(sf.Mesh.from_csr(d["vertices"], d["face_sizes"], d["face_indices"]), 4)
    return m.vertices, m.face_sizes, m.face_indices, "shapeflow Catmull-Clark of the fixture Suzanne"


def million_mesh():
    """~0.94M vertices: the camel triangle mesh after three Catmull-Clark steps (all quads)."""
    cached = CACHE / "million.npz"
    if cached.exists():
        d = np.load(cached)
        return sf.Mesh.from_csr(d["vertices"], d["face_sizes"], d["face_indices"])
    src = SHARED / "meshes" / "camel_tri.obj"
    m = sf.subdivide(sf.load(src), 3)
    CACHE.mkdir(exist_ok=True)
    np.savez(cached, vertices=m.vertices, face_sizes=m.face_sizes, face_indices=m.face_indices)
    return m


def peak_rss_mb() -> float:
    """Peak resident memory of this process in MB.

    VmHWM of /proc/self/status where available: ``ru_maxrss`` survives exec on
    Linux, so a child started from a large parent (bpy loaded) would report
    the parent's peak.
    """
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def child_million(repeat: int) -> dict:
    """Runs in a child process: 1M-vertex flow, fresh, and peak memory."""
    m = million_mesh()
    V, S, I = m.vertices, m.face_sizes, m.face_indices
    del m
    base = peak_rss_mb()
    # the first call of a new process also loads the compiled kernels (numba), once
    t_first, _ = median_time(lambda: sf.flow(sf.Mesh.from_csr(V, S, I), 1.0), 1)
    t, out = median_time(lambda: sf.flow(sf.Mesh.from_csr(V, S, I), 1.0), repeat)
    peak = peak_rss_mb()
    return {"n": int(V.shape[0]), "seconds": t, "first": t_first, "peak_mb": peak, "before_mb": base,
            "solver": out.report.solver, "cg": out.report.cg_iterations, "kernels": sf.accel.available()}


def parse_count(text: str) -> int:
    """``50M``, ``2.5M``, ``800K`` or a plain number."""
    t = text.strip().upper()
    scale = {"K": 10**3, "M": 10**6, "G": 10**9}.get(t[-1:], 1)
    return int(float(t[:-1] if scale > 1 else t) * scale)


def write_scan(path: Path, n_target: int, chunk: int = 4_000_000) -> tuple[int, int]:
    """A closed triangle torus of about ``n_target`` vertices (a 2:1 grid, radii jittered by 2%),
    written as binary PLY in chunks (float32 positions, uchar/int faces, as scanners write)."""
    b = max(3, int(np.sqrt(n_target / 2)))
    a = 2 * b
    n, m = a * b, 2 * a * b
    rng = np.random.default_rng(0)
    with open(path, "wb") as f:
        f.write((f"ply\nformat binary_little_endian 1.0\nelement vertex {n}\nproperty float x\n"
                 f"property float y\nproperty float z\nelement face {m}\n"
                 "property list uchar int vertex_indices\nend_header\n").encode())
        for r0 in range(0, a, max(1, chunk // b)):       # rows of the grid, a few million vertices at a time
            i = np.arange(r0, min(a, r0 + max(1, chunk // b)))[:, None]
            j = np.arange(b)[None, :]
            u, v = 2 * np.pi * i / a, 2 * np.pi * j / b
            r = 0.35 * (1 + 0.02 * rng.standard_normal((i.size, b)))
            xyz = np.stack([(1 + r * np.cos(v)) * np.cos(u), (1 + r * np.cos(v)) * np.sin(u),
                            r * np.sin(v)], -1)
            f.write(xyz.astype("<f4").tobytes())
        rec = np.dtype([("n", "u1"), ("i", "<i4", 3)])
        for r0 in range(0, a, max(1, chunk // (2 * b))):
            i = np.arange(r0, min(a, r0 + max(1, chunk // (2 * b))))[:, None]
            j = np.arange(b)[None, :]
            p00, p10 = i * b + j, ((i + 1) % a) * b + j
            p01, p11 = i * b + (j + 1) % b, ((i + 1) % a) * b + (j + 1) % b
            out = np.empty((i.size, b, 2), rec)
            out["n"] = 3
            out["i"][:, :, 0] = np.stack([p00, p10, p11], -1)
            out["i"][:, :, 1] = np.stack([p00, p11, p01], -1)
            f.write(out.tobytes())
    return n, m


def child_scan(src: str, dst: str) -> dict:
    """Runs in a child process: load, one flow step, save; times and the peak resident memory."""
    base = peak_rss_mb()
    t0 = time.perf_counter()
    mesh = sf.load(src)
    t_load = time.perf_counter() - t0
    inputs_mb = (mesh.vertices.nbytes + mesh.face_indices.nbytes + mesh.face_offsets.nbytes) / 2**20
    after_load = peak_rss_mb()
    print(f"  loaded {mesh.n_vertices:,} vertices, {mesh.n_faces:,} faces in {t_load:.1f} s "
          f"(peak {after_load:.0f} MB)", file=sys.stderr, flush=True)
    t0 = time.perf_counter()
    out = sf.flow(mesh, 1.0)
    t_flow = time.perf_counter() - t0
    after_flow = peak_rss_mb()
    print(f"  smoothed in {t_flow:.1f} s (peak {after_flow:.0f} MB)", file=sys.stderr, flush=True)
    t0 = time.perf_counter()
    sf.save(dst, out)
    t_save = time.perf_counter() - t0
    return {"n": mesh.n_vertices, "faces": mesh.n_faces, "load": t_load, "flow": t_flow, "save": t_save,
            "base_mb": base, "load_peak_mb": after_load, "flow_peak_mb": after_flow, "peak_mb": peak_rss_mb(),
            "inputs_mb": inputs_mb, "solver": out.report.solver, "cg": out.report.cg_iterations,
            "threads": str(sf.accel.current().threads)}


def scan(count: str, folder: str | None) -> int:
    import tempfile

    n_target = parse_count(count)
    with tempfile.TemporaryDirectory(dir=folder) as tmp:
        src, dst = Path(tmp) / "scan.ply", Path(tmp) / "smoothed.ply"
        t0 = time.perf_counter()
        n, m = write_scan(src, n_target)
        print(f"generated a {n:,}-vertex, {m:,}-triangle torus as binary PLY "
              f"({src.stat().st_size / 2**30:.2f} GiB) in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
        res = subprocess.run([sys.executable, __file__, "--child-scan", str(src), str(dst)],
                             stdout=subprocess.PIPE, text=True)
        if res.returncode != 0:
            print(f"scan of {n:,} vertices failed (exit {res.returncode})")
            return 1
        d = json.loads(res.stdout.strip().splitlines()[-1])
    beyond = (d["peak_mb"] - d["base_mb"] - d["inputs_mb"]) * 2**20 / d["n"]
    print(f"scan {d['n']:,} vertices, {d['faces']:,} triangles ({time.strftime('%Y-%m-%d')}, threads "
          f"{d['threads']}): load {d['load']:.1f} s, flow λ=1 {d['flow']:.1f} s "
          f"({d['flow'] / d['n'] * 1e6:.2f} µs per vertex) [{d['solver']}, CG {d['cg']}], save {d['save']:.1f} s")
    print(f"  peak resident memory {d['peak_mb']:,.0f} MB (interpreter {d['base_mb']:.0f} MB, the mesh's arrays "
          f"{d['inputs_mb']:,.0f} MB): {beyond:.0f} bytes per vertex beyond the input arrays, "
          f"{(d['peak_mb'] - d['base_mb']) * 2**20 / d['n']:.0f} in all; after loading {d['load_peak_mb']:,.0f} MB, "
          f"after the flow {d['flow_peak_mb']:,.0f} MB")
    return 0


def blender_rows(V, S, I, t_fresh=None, t_warm=None) -> bool:
    """Blender's Laplacian Smooth (λ=1, 1 iteration, median of 3) and compat='blender' against it;
    the ratios when shapeflow's times are given.  False when bpy does not import."""
    import blender_ref

    if not blender_ref.available():
        return False
    pos, t_blender = blender_ref.laplacian_smooth(V, S, I, lambda_factor=1.0, iterations=1,
                                                  use_normalized=True, repeat=3)
    ours = sf.flow(sf.Mesh.from_csr(V, S, I), 1.0, compat="blender").vertices
    err = np.abs(ours - pos).max() / np.linalg.norm(np.ptp(V, axis=0))
    import bpy

    print(f"  {f'Blender {bpy.app.version_string} Laplacian Smooth, λ=1, 1 iteration':<52s} "
          f"{t_blender * 1e3:9.1f} ms  (median of 3)")
    ratios = (f"ratio Blender / shapeflow fresh: {t_blender / t_fresh:.1f}x, warm: {t_blender / t_warm:.1f}x; "
              if t_fresh else "")
    print(f"  {ratios}compat='blender' agrees to {err:.1e} x diagonal")
    return True


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=11)
    ap.add_argument("--quick", action="store_true", help="skip the 1M-vertex case and Blender")
    ap.add_argument("--no-blender", action="store_true")
    ap.add_argument("--blender-only", action="store_true",
                    help="only Blender's modifier and compat='blender' against it (for a Python with bpy "
                         "but without the fast extra; benchmarks/measure_all.py runs it so)")
    ap.add_argument("--child-million", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--scan", metavar="N", help="only the scan case: a generated triangle torus of N vertices "
                                                 "(e.g. 10M) through load, one flow step and save")
    ap.add_argument("--scan-dir", help="folder for the scan's files (default: the system's temporary folder)")
    ap.add_argument("--child-scan", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child_scan:
        print(json.dumps(child_scan(*args.child_scan)))
        return 0
    if args.scan:
        return scan(args.scan, args.scan_dir)
    if args.child_million:
        print(json.dumps(child_million(args.repeat)))
        return 0

    R = args.repeat
    V, S, I, origin = suzanne_sub4()
    print(f"Suzanne subdivided 4x: {V.shape[0]:,} vertices, {S.size:,} faces ({origin}); medians of {R} runs")
    if args.blender_only:
        return 0 if blender_rows(V, S, I) else 2
    rows = []

    def row(label, seconds, extra=""):
        rows.append((label, seconds))
        print(f"  {label:<52s} {seconds * 1e3:9.1f} ms  {extra}")

    t_fresh, out = median_time(lambda: sf.flow(sf.Mesh.from_csr(V, S, I), 1.0), R)
    row("flow λ=1, 1 iteration, fresh mesh (all included)", t_fresh,
        f"[{out.report.solver}, CG {out.report.cg_iterations}] {spread()}")
    warm = sf.Mesh.from_csr(V, S, I)
    sf.flow(warm, 1.0)
    # one and ten iterations alternately, so that a drift of the (shared) machine between
    # two blocks of runs does not enter their ratio
    t1s, t10s = [], []
    for _ in range(R):
        t0 = time.perf_counter()
        sf.flow(warm, 1.0)
        t1s.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        out10 = sf.flow(warm, 1.0, iterations=10)
        t10s.append(time.perf_counter() - t0)
    t_warm, t10 = statistics.median(t1s), statistics.median(t10s)
    LAST_TIMES[:] = t1s
    row("flow λ=1, 1 iteration, warm topology", t_warm, spread())
    row("flow λ=1, 10 iterations (fixed operator), warm", t10,
        f"= {t10 / t_warm:.2f}x one iteration [{out10.report.solver}] (runs alternated with the row above)")
    for lam in (-10.0, -100.0):
        t, o = median_time(lambda: sf.flow(warm, lam), R)
        row(f"flow λ={lam:g}, 1 iteration, warm", t, f"[{o.report.solver}, CG {o.report.cg_iterations}]")
    for solver in ("cg", "cholesky", "lu"):
        if solver == "cholesky" and not sf.linalg.cholesky_available():
            continue
        for lam in (1.0, -100.0):
            t, o = median_time(lambda: sf.flow(warm, lam, solver=solver), max(1, R // 2) if solver != "cg" else R)
            row(f"  solver={solver:<8s} λ={lam:g}, warm", t)
    tb, _ = median_time(lambda: sf.flow(warm, 1.0, compat="blender"), R)
    row("flow λ=1 compat='blender', warm", tb)
    if sf.accel.available():
        with sf.accel.enabled(False):
            tn, _ = median_time(lambda: sf.flow(sf.Mesh.from_csr(V, S, I), 1.0), R)
            row("  without compiled kernels: λ=1, fresh", tn, f"(kernels: {tn / t_fresh:.2f}x faster)")
            wn = sf.Mesh.from_csr(V, S, I)
            sf.flow(wn, 1.0)
            tn1, _ = median_time(lambda: sf.flow(wn, 1.0), R)
            tn10, _ = median_time(lambda: sf.flow(wn, 1.0, iterations=10), R)
            row("  without compiled kernels: λ=1, warm", tn1)
            row("  without compiled kernels: 10 iterations, warm", tn10, f"= {tn10 / tn1:.2f}x one iteration")

    if args.quick or args.no_blender or not blender_rows(V, S, I, t_fresh, t_warm):
        print("  Blender: not measured (bpy not importable or --quick/--no-blender)")

    if not args.quick:
        res = subprocess.run([sys.executable, __file__, "--child-million", "--repeat", str(max(1, R // 2))],
                             capture_output=True, text=True)
        if res.returncode == 0:
            d = json.loads(res.stdout.strip().splitlines()[-1])
            print(f"1M-vertex case: {d['n']:,} vertices (camel, Catmull-Clark x3): flow λ=1 fresh "
                  f"{d['seconds']:.2f} s (first call in the process {d['first']:.2f} s), peak RSS "
                  f"{d['peak_mb']:.0f} MB (mesh alone {d['before_mb']:.0f} MB) "
                  f"[{d['solver']}, CG {d['cg']}, compiled kernels {'on' if d['kernels'] else 'off'}]")
        else:
            print("1M-vertex case failed:", res.stderr.strip().splitlines()[-1:])
    return 0


if __name__ == "__main__":
    sys.exit(main())
