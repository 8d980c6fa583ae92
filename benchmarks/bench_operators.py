"""Benchmark of mesh topology and operator assembly (issues 2 and 3).

    python benchmarks/bench_operators.py [--repeat N]

* loads the largest shared mesh (amo_large_tri.obj, 90K vertices) and derives
  its topology;
* on a ~1M-vertex all-quad mesh (camel_tri.obj after three Catmull-Clark
  steps: 937,730 vertices, cached in benchmarks/.cache/million.npz):
  topology derivation (target < 1 s) and building W (target < 1.5 s), fresh
  (sparse pattern included) and warm (pattern cached, new positions).
Medians of --repeat runs.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import shapeflow as sf  # noqa: E402
from shapeflow.operators.cotan import assemble as _assemble  # noqa: E402

SHARED = Path(os.environ.get("SHAPEFLOW_SHARED", HERE.parent.parent / "shared")) / "meshes"


def med(fn, repeat):
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts)


def topology_all(m):
    t = m.topology
    t.edges, t.boundary_edge_mask, t.boundary_vertex_mask, t.vertex_corner_count
    t.corner_next, t.corner_prev, t.corner_face, t.nonmanifold_edge_mask
    return t


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args(argv)
    R = args.repeat

    path = SHARED / "amo_large_tri.obj"
    t_load = med(lambda: sf.load(path), R)
    m = sf.load(path)
    V, S, I = m.vertices, m.face_sizes, m.face_indices
    t_mesh = med(lambda: sf.Mesh.from_csr(V, S, I), R)
    t_topo = med(lambda: topology_all(sf.Mesh.from_csr(V, S, I)), R) - t_mesh
    print(f"{path.name}: {m.n_vertices:,} vertices, {m.n_faces:,} faces; medians of {R}")
    print(f"  load OBJ                    {t_load * 1e3:8.1f} ms")
    print(f"  Mesh (validation)           {t_mesh * 1e3:8.1f} ms")
    print(f"  topology (edges, boundary)  {t_topo * 1e3:8.1f} ms")

    from bench_flow import million_mesh

    big = million_mesh()
    V, S, I = big.vertices, big.face_sizes, big.face_indices
    print(f"1M-vertex quad mesh: {big.n_vertices:,} vertices, {big.n_faces:,} faces")
    t_mesh = med(lambda: sf.Mesh.from_csr(V, S, I), R)
    t_topo = med(lambda: topology_all(sf.Mesh.from_csr(V, S, I)), R) - t_mesh
    print(f"  Mesh (validation)           {t_mesh * 1e3:8.1f} ms")
    print(f"  topology derivation         {t_topo * 1e3:8.1f} ms   (target < 1000 ms)")
    for scheme in ("tqlbo", "blender"):
        def fresh():
            mm = sf.Mesh.from_csr(V, S, I)
            topology_all(mm)
            t0 = time.perf_counter()
            sf.cotan_weights(mm, scheme)
            return time.perf_counter() - t0
        t_fresh = statistics.median(fresh() for _ in range(R))
        warm = sf.Mesh.from_csr(V, S, I)
        sf.cotan_weights(warm, scheme)
        t_warm = med(lambda: sf.cotan_weights(warm, scheme), R)
        t_raw = med(lambda: _assemble(warm, scheme, "relative"), R)
        print(f"  W, scheme={scheme:<7s} fresh {t_fresh * 1e3:7.1f} ms (target < 1500), "
              f"warm {t_warm * 1e3:7.1f} ms, pair weights only {t_raw * 1e3:7.1f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
