"""Load times of shapeflow's readers against trimesh, meshio and numpy-stl on the same files.

    python benchmarks/bench_io.py [--reps 7]

Files: the shared meshes as OBJ (as published), and the largest one (AMO, 90K vertices) also
written as binary PLY, binary STL and GLB.  Median wall time of ``--reps`` loads each (the
file in the page cache), printed as a Markdown table for docs/io.md.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import warnings
from pathlib import Path

from common import SHARED, median_time  # noqa: E402  (first: it puts src/ on the path)

import shapeflow as sf  # noqa: E402


def readers():
    out = {"shapeflow": lambda p: sf.load(p)}
    try:
        import trimesh

        out["trimesh"] = lambda p: trimesh.load(p, process=False, force="mesh")
    except ImportError:
        pass
    try:
        import meshio

        out["meshio"] = lambda p: meshio.read(p)
    except ImportError:
        pass
    try:
        from stl import mesh as stl_mesh

        out["numpy-stl"] = lambda p: stl_mesh.Mesh.from_file(str(p)) if str(p).endswith(".stl") else None
    except ImportError:
        pass
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=7)
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    tmp = Path(tempfile.mkdtemp())
    files = [SHARED / n for n in ("spot_quad.obj", "sword_quad_dominant_hybrid.obj", "amo_large_tri.obj")]
    amo = sf.load(files[-1])
    for ext in (".ply", ".stl", ".glb"):
        sf.save(tmp / f"amo{ext}", amo)
        files.append(tmp / f"amo{ext}")
    rd = readers()
    print(f"shapeflow {sf.__version__}; {os.cpu_count()} cores; load average {os.getloadavg()[0]:.2f}; "
          f"median of {args.reps} loads\n")
    print("| file | size | " + " | ".join(rd) + " |")
    print("|---|---|" + "---|" * len(rd))
    for p in files:
        cells = []
        for name, fn in rd.items():
            try:
                if fn(p) is None:
                    cells.append("–")
                    continue
                cells.append(f"{1e3 * median_time(lambda: fn(p), args.reps):.1f} ms")
            except Exception as exc:   # a reader that cannot read the file: say so in the table
                cells.append(f"fails ({type(exc).__name__})")
        print(f"| {p.name} | {p.stat().st_size / 1e6:.1f} MB | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
