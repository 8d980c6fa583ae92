"""Rendering speed on meshes of about a million faces (issue 7: at most 10 s).

    python benchmarks/bench_render.py [--repeat N] [--size WxH] [--mesh PATH]

Two meshes:

* ``grid``: a generated 1000 × 1000 height field of quads (1,000,000 faces);
* ``amo``: the shared ``amo_large_tri.obj`` (180k triangles) after one
  Catmull–Clark step (540k quads), each quad then split into two triangles
  (1.08M faces); skipped if the shared meshes or ``shapeflow.subdivide`` are
  not there.

Each is rendered (offscreen, 1200×900) plain, with edges, and coloured by
mean curvature (which includes computing the curvature); the median of
``--repeat`` runs is printed for each, the whole ``render()`` call timed,
PNG writing included.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import shapeflow as sf

HERE = Path(__file__).resolve().parent
SHARED = Path(os.environ.get("SHAPEFLOW_SHARED", HERE.parents[1] / "shared"))
LIMIT_S = 10.0


def grid_mesh(n: int = 1000) -> sf.Mesh:
    x, y = np.meshgrid(np.linspace(-1, 1, n + 1), np.linspace(-1, 1, n + 1))
    z = 0.15 * np.sin(5 * x) * np.cos(4 * y) + 0.05 * np.sin(23 * x * y)
    v = np.column_stack([x.ravel(), z.ravel(), -y.ravel()])  # y up
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    quads = np.stack([idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]], axis=-1).reshape(-1, 4)
    return sf.Mesh.from_csr(v, np.full(len(quads), 4), quads.ravel())


def amo_mesh(path: Path) -> sf.Mesh | None:
    if not path.exists():
        return None
    try:
        cc = sf.subdivide(sf.load(path), 1)
    except (AttributeError, ImportError):
        return None
    q = cc.face_indices.reshape(-1, 4)  # Catmull-Clark output is all quads
    tris = np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])
    return sf.Mesh.from_csr(cc.vertices, np.full(len(tris), 3), tris.ravel())


def bench(name: str, mesh: sf.Mesh, repeat: int, size, out_dir: str) -> list[float]:
    from shapeflow.rendering import render

    medians = []
    for label, kw in (("plain", dict(color="none")), ("edges", dict(color="none", edges=True)),
                      ("curvature", dict(color="curvature"))):
        times = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            render(mesh, os.path.join(out_dir, f"{name}_{label}.png"), view="iso", size=size, **kw)
            times.append(time.perf_counter() - t0)
        med = statistics.median(times)
        medians.append(med)
        print(f"{name:5s} {mesh.n_faces:>9d} faces  {label:9s}  median {med:6.2f} s  "
              f"(runs: {', '.join(f'{t:.2f}' for t in times)})", flush=True)
    return medians


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--size", default="1200x900")
    ap.add_argument("--mesh", default=str(SHARED / "meshes" / "amo_large_tri.obj"))
    ap.add_argument("--keep", metavar="DIR", help="keep the PNGs in DIR")
    a = ap.parse_args(argv)
    size = tuple(int(s) for s in a.size.split("x"))
    from shapeflow.rendering import available

    if not available():
        print("rendering is not available (pip install 'shapeflow[render]')", file=sys.stderr)
        return 1
    worst = 0.0
    with tempfile.TemporaryDirectory() as tmp:
        out = a.keep or tmp
        t0 = time.perf_counter()
        g = grid_mesh()
        print(f"grid mesh built in {time.perf_counter() - t0:.2f} s")
        worst = max(worst, *bench("grid", g, a.repeat, size, out))
        t0 = time.perf_counter()
        m = amo_mesh(Path(a.mesh))
        if m is None:
            print("amo: skipped (shared mesh or shapeflow.subdivide missing)")
        else:
            print(f"amo mesh built in {time.perf_counter() - t0:.2f} s")
            worst = max(worst, *bench("amo", m, a.repeat, size, out))
    print(f"slowest median {worst:.2f} s; limit {LIMIT_S:.0f} s: {'OK' if worst <= LIMIT_S else 'TOO SLOW'}")
    return 0 if worst <= LIMIT_S else 1


if __name__ == "__main__":
    sys.exit(main())
