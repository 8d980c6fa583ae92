"""shapeflow's implicit step against the filters a user would pick instead, in one run.

    python benchmarks/bench_peers.py [--reps 7]

The mesh: Suzanne subdivided to ~126K vertices, triangulated for the triangle-only peers.  Each
row is a median of ``--reps`` runs taken in interleaved rounds (one run of every method per
round), fresh (a new mesh object each time, so no cached topology); peers that are not
installed are skipped (libigl, trimesh and pyvista are test dependencies; gpytoolbox,
robust_laplacian, pymeshlab and open3d are used when present).  Ratios are to shapeflow's one
implicit step (λ = 1, normalised operator) on the same triangles, in this run.  A second table
times shapeflow warm (the same mesh object again, topology and pattern cached) in rounds with
trimesh's filter.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import warnings

import numpy as np  # noqa: E402
from common import median_time, suzanne_126k  # noqa: E402  (first: it puts src/ on the path)

import shapeflow as sf  # noqa: E402
from shapeflow import accel  # noqa: E402
from shapeflow.geometry.measures import fan_triangles  # noqa: E402


def peers(V: np.ndarray, F: np.ndarray):
    """(name, callable) of every peer installed here, each doing its own whole job from arrays."""
    out = []
    try:
        import igl
        import scipy.sparse.linalg as sla

        def igl_step():
            L = igl.cotmatrix(V, F)
            M = igl.massmatrix(V, F, igl.MASSMATRIX_TYPE_VORONOI)
            return sla.spsolve((M - 1e-3 * L).tocsc(), M @ V)

        out.append(("libigl cotmatrix + massmatrix + spsolve (1 implicit step)", igl_step))
    except ImportError:
        pass
    try:
        import trimesh
        from trimesh.smoothing import filter_taubin

        out.append(("trimesh Taubin (10 iterations)",
                    lambda: filter_taubin(trimesh.Trimesh(V, F, process=False), iterations=10)))
    except ImportError:
        pass
    try:
        import pyvista as pv

        faces = np.hstack([np.full((F.shape[0], 1), 3), F]).reshape(-1)
        out.append(("pyvista windowed sinc (20 iterations)",
                    lambda: pv.PolyData(V, faces).smooth_taubin(n_iter=20)))
    except ImportError:
        pass
    try:
        import gpytoolbox as gpy
        import scipy.sparse.linalg as sla

        def gpy_step():
            L = gpy.cotangent_laplacian(V, F)
            M = gpy.massmatrix(V, F)
            return sla.spsolve((M + 1e-3 * L).tocsc(), M @ V)

        out.append(("gpytoolbox cotangent Laplacian + spsolve", gpy_step))
    except ImportError:
        pass
    try:
        import robust_laplacian
        import scipy.sparse.linalg as sla

        def rl_step():
            L, M = robust_laplacian.mesh_laplacian(V, F)
            return sla.spsolve((M + 1e-3 * L).tocsc(), M @ V)

        out.append(("robust_laplacian + spsolve", rl_step))
    except ImportError:
        pass
    try:
        import open3d as o3d

        def o3d_taubin():
            m = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(np.array(V)),   # open3d needs writable arrays
                                          o3d.utility.Vector3iVector(np.array(F, np.int32)))
            return m.filter_smooth_taubin(number_of_iterations=10)

        out.append(("open3d Taubin (10 iterations)", o3d_taubin))
    except ImportError:
        pass
    return out


def rounds(methods, reps: int) -> dict:
    """Each method's times from ``reps`` interleaved rounds (one run of every method per round), so a
    change of the machine's load touches every method alike."""
    samples = {name: [] for name, _ in methods}
    for _ in range(reps):
        for name, fn in methods:
            samples[name].append(median_time(fn, 1))
    return samples


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=7)
    ap.add_argument("--threads", default="auto", help="shapeflow's thread setting (auto or a number)")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    threads = args.threads if args.threads == "auto" else int(args.threads)
    suz = suzanne_126k()
    V = np.ascontiguousarray(suz.vertices)
    F = fan_triangles(suz)
    n_vertices, n_faces = suz.n_vertices, F.shape[0]
    with accel.use(threads=threads):
        sf.flow(sf.Mesh(V, F), 1.0)     # compiled kernels loaded; no mesh kept alive (docs/performance.md:
        #                                 a live mesh's heap makes glibc return the next one's pages)

        def ours():
            with accel.use(threads=threads):
                return sf.flow(sf.Mesh(V, F), 1.0)       # fresh: validation, topology, operator, solve

        methods = [("shapeflow, 1 implicit step (fresh mesh)", ours), *peers(V, F)]
        for _, fn in methods:
            fn()                                           # imports, first-call set-up
        samples = rounds(methods, args.reps)
        # warm: the same mesh object again (topology and pattern cached, as in an interactive session),
        # in rounds with the fastest explicit filter; apart, so the live mesh does not touch the rows above
        warm_mesh = sf.Mesh(V, F)
        sf.flow(warm_mesh, 1.0)
        warm_methods = [("shapeflow, 1 implicit step (warm mesh: topology cached)", lambda: sf.flow(warm_mesh, 1.0)),
                        *[(n, f) for n, f in methods if n.startswith("trimesh")]]
        warm = rounds(warm_methods, args.reps)
    rows = [(name, statistics.median(ts)) for name, ts in samples.items()]
    base = rows[0][1]
    print(f"shapeflow {sf.__version__}; {n_vertices:,} vertices, {n_faces:,} triangles; {os.cpu_count()} "
          f"cores, load average {os.getloadavg()[0]:.2f}; threads={threads}; median of {args.reps} runs\n")
    print("| method | time | ratio to shapeflow |")
    print("|---|---|---|")
    for name, t in rows:
        print(f"| {name} | {1e3 * t:.0f} ms | {t / base:.2f} |")
    wrows = [(name, statistics.median(ts)) for name, ts in warm.items()]
    print("\n| warm, in rounds of their own | time | ratio to shapeflow warm |")
    print("|---|---|---|")
    for name, t in wrows:
        print(f"| {name} | {1e3 * t:.0f} ms | {t / wrows[0][1]:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
