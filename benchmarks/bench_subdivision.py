"""Benchmark: Catmull–Clark level 2 of a 40,000-vertex quad mesh (→ 640,000 vertices).

Prints medians over ``--repeat`` runs (default 5) of

* ``subdivide(mesh, 2)``: both levels' sparse matrices built and applied to the
  positions (each as its two sparse factors), the new mesh built (the target
  is <= 1 s on the project's 2-core machine);
* the same with vertex weights (linear rule: a second, simple matrix per level);
* ``subdivision_matrix(mesh, levels=2)``: the composite 640K × 40K matrix;
* ``S @ V``: one frame of an animated cage once the matrix exists;

and, when Blender's ``bpy`` module is importable, Blender's Subdivision Surface
modifier on the same input in the same run (levels=2, use_limit_surface=False,
use_creases=False, via ``benchmarks/blender_ref.py``) and the ratio.

Input: a 200 × 200 quad torus (generated, 40,000 vertices, closed) and, when
``shapeflow.io`` can read it, Keenan Crane's Spot (``shared/meshes/spot_quad.obj``)
subdivided twice (46,850 vertices, with extraordinary vertices).

Run: ``python benchmarks/bench_subdivision.py [--repeat N] [--size N] [--no-blender | --blender-only]``.
"""

from __future__ import annotations

import argparse
import gc
import importlib.util
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

import shapeflow as sf  # noqa: E402
from shapeflow.subdivision import subdivide, subdivision_matrix  # noqa: E402


def torus(n: int, m: int, R: float = 2.0, r: float = 0.7) -> sf.Mesh:
    i, j = np.meshgrid(np.arange(n), np.arange(m), indexing="ij")
    th, ph = 2 * np.pi * i / n, 2 * np.pi * j / m
    V = np.stack([(R + r * np.cos(ph)) * np.cos(th), (R + r * np.cos(ph)) * np.sin(th), r * np.sin(ph)], -1)
    idx = lambda a, b: (a % n) * m + (b % m)  # noqa: E731
    F = np.stack([idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)], -1).reshape(-1, 4)
    return sf.Mesh(V.reshape(-1, 3), F)


def spot_sub2() -> sf.Mesh | None:
    env = [Path(os.environ["SHAPEFLOW_SHARED"])] if os.environ.get("SHAPEFLOW_SHARED") else []
    for shared in (*env, ROOT.parent / "shared", ROOT / "shared"):
        path = shared / "meshes" / "spot_quad.obj"
        if path.exists():
            break
    else:
        return None
    try:
        from shapeflow.io import load
    except ImportError:
        return None
    return subdivide(load(path), 2)


def median_time(fn, repeat: int) -> tuple[float, object]:
    samples = []
    out = None
    for _ in range(repeat):
        out = None
        gc.collect()
        t0 = time.perf_counter()
        out = fn()
        samples.append(time.perf_counter() - t0)
    return statistics.median(samples), out


def blender_harness():
    if importlib.util.find_spec("bpy") is None:
        return None, "bpy is not importable"
    path = ROOT / "benchmarks" / "blender_ref.py"
    if not path.exists():
        return None, "benchmarks/blender_ref.py is missing"
    spec = importlib.util.spec_from_file_location("blender_ref", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    if not mod.available():
        return None, "bpy failed to import"
    return mod, ""


def bench(name: str, mesh: sf.Mesh, repeat: int, br, blender_only: bool = False) -> None:
    print(f"\n{name}: {mesh.n_vertices:,} vertices, {mesh.n_faces:,} faces {mesh.face_count_by_size()}")
    if blender_only:
        blender_row(mesh, subdivide(mesh, 2), repeat, br)
        return
    rng = np.random.default_rng(0)
    weighted = mesh.with_weights(rng.uniform(size=mesh.n_vertices))

    # every run starts from a fresh topology (nothing cached from the run before)
    def fresh(m):
        return sf.Mesh.from_csr(m.vertices, m.face_sizes, m.face_indices,
                                attributes=dict(m.attributes))

    t_sub, out = median_time(lambda: subdivide(fresh(mesh), 2), repeat)
    print(f"  subdivide(levels=2)              {t_sub:8.3f} s  -> {out.n_vertices:,} vertices, "
          f"{out.n_faces:,} quads   (target <= 1 s)")
    t_w, _ = median_time(lambda: subdivide(fresh(weighted), 2), repeat)
    print(f"  subdivide(levels=2) + weights    {t_w:8.3f} s")
    t_mat, (S, _) = median_time(lambda: subdivision_matrix(fresh(mesh), levels=2), repeat)
    print(f"  subdivision_matrix(levels=2)     {t_mat:8.3f} s  ({S.shape[0]:,} x {S.shape[1]:,}, nnz {S.nnz:,})")
    t_apply, _ = median_time(lambda: S @ mesh.vertices, repeat)
    print(f"  S @ V (one animated frame)       {t_apply:8.3f} s")
    t_bl = blender_row(mesh, out, repeat, br)
    if t_bl:
        print(f"  ratio shapeflow / Blender        {t_sub / t_bl:8.2f}   (S @ V alone: {t_apply / t_bl:.3f})")


def blender_row(mesh: sf.Mesh, out: sf.Mesh, repeat: int, br) -> float | None:
    """Blender's Subdivision Surface (level 2) on ``mesh``, median seconds (None without bpy)."""
    if br is None:
        return None
    V, fs, fi = mesh.vertices, mesh.face_sizes, mesh.face_indices
    P, bfs, _, _, t_bl = br.subdivision_surface(V, fs, fi, levels=2, subdivision_type="CATMULL_CLARK",
                                                boundary_smooth="ALL", use_limit_surface=False, repeat=repeat)
    assert len(P) == out.n_vertices and len(bfs) == out.n_faces
    print(f"  Blender Subdivision Surface      {t_bl:8.3f} s  (levels=2, no limit surface, no creases; "
          f"median of {repeat})")
    return t_bl


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--size", type=int, default=200, help="torus of SIZE × SIZE vertices (default 200)")
    ap.add_argument("--no-blender", action="store_true", help="do not time Blender even if bpy is importable")
    ap.add_argument("--blender-only", action="store_true",
                    help="only Blender's modifier (for a Python with bpy but without the fast extra; "
                         "benchmarks/measure_all.py runs it so)")
    args = ap.parse_args(argv)

    br, why = (None, "--no-blender") if args.no_blender else blender_harness()
    print(f"shapeflow {sf.__version__}, numpy {np.__version__}; median of {args.repeat} runs")
    print("Blender: " + ("bpy " + __import__("bpy").app.version_string if br else f"not timed ({why})"))
    if args.blender_only and br is None:
        return 2
    bench(f"quad torus {args.size}x{args.size}", torus(args.size, args.size), args.repeat, br, args.blender_only)
    spot = spot_sub2()
    if spot is not None:
        bench("spot_quad.obj subdivided twice", spot, args.repeat, br, args.blender_only)
    return 0


if __name__ == "__main__":
    sys.exit(main())
