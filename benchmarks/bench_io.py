"""Load times of shapeflow's readers against trimesh, meshio and numpy-stl on the same files.

    python benchmarks/bench_io.py [--reps 7] [--big-reps 5] [--shared DIR] [--no-big]

Files: the shared meshes as OBJ (as published), and the largest one (AMO, 90K vertices) also
written as binary PLY, binary STL and GLB; and four OBJ files of 45-100 MB made in a temporary
folder (removed at the end) from subdivided shared meshes: AMO subdivided once (540K quads, and
the same split into 1.08M triangles; plain ``f a b c`` lines) and Bob subdivided three times
(342K quads and 684K triangles with ``v/vt/vn`` corners), written by shapeflow (shortest
round-trip decimals).  Every reader loads each file once per round, rounds interleaved (the order
of the readers reversed every other round), in this one process; the table gives medians (the
files in the page cache) and shapeflow's time over trimesh's.  trimesh is timed as
``trimesh.load(path, process=False)`` and with ``maintain_order=True``, which keeps the file's
vertex order (shapeflow's) also where ``vt``/``vn`` corners differ.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np  # noqa: E402
from common import SHARED  # noqa: E402  (first: it puts src/ on the path)

import shapeflow as sf  # noqa: E402
from shapeflow.mesh.attributes import Indexed  # noqa: E402


def readers() -> dict:
    out = {"shapeflow": lambda p: sf.load(p)}
    try:
        import trimesh

        out["trimesh"] = lambda p: trimesh.load(p, process=False, force="mesh")
        out["trimesh, file order"] = lambda p: (trimesh.load(p, process=False, force="mesh", maintain_order=True)
                                                if str(p).endswith(".obj") else None)
    except ImportError:
        pass
    try:
        import meshio

        out["meshio"] = lambda p: None if "_sub" in p.name else meshio.read(p)   # (minutes on the large files)
    except ImportError:
        pass
    try:
        from stl import mesh as stl_mesh

        out["numpy-stl"] = lambda p: stl_mesh.Mesh.from_file(str(p)) if str(p).endswith(".stl") else None
    except ImportError:
        pass
    return out


def triangulated(mesh: sf.Mesh) -> sf.Mesh:
    """A mesh of quads split along the diagonal from each quad's first corner, corners kept."""
    def split(x):
        q = x.reshape(-1, 4)
        return np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]], axis=1).reshape(-1)

    corner = {k: Indexed(v.values, split(v.index)) for k, v in mesh.corner_attributes.items()}
    return sf.Mesh.from_csr(mesh.vertices, np.full(mesh.n_faces * 2, 3), split(mesh.face_indices),
                            corner_attributes=corner)


def large_files(shared: Path, folder: Path) -> list[Path]:
    """The four large OBJ files (see the module's text)."""
    amo = sf.subdivide(sf.load(shared / "amo_large_tri.obj"), 1)
    amo = sf.Mesh.from_csr(amo.vertices, amo.face_sizes, amo.face_indices)
    bob = sf.subdivide(sf.load(shared / "bob_quad.obj"), 3)
    bob = sf.Mesh.from_csr(bob.vertices, bob.face_sizes, bob.face_indices,
                           corner_attributes={k: bob.corner_attributes[k] for k in ("uv", "normal")})
    out = []
    for name, mesh in (("amo_sub1_tri", triangulated(amo)), ("amo_sub1_quad", amo),
                       ("bob_sub3_tri_vtn", triangulated(bob)), ("bob_sub3_quad_vtn", bob)):
        out.append(folder / f"{name}.obj")
        sf.save(out[-1], mesh)
    return out


def measure(files: list[Path], rd: dict, reps: int) -> dict:
    """{(file, reader): [seconds]}: ``reps`` rounds, each loading every file with every reader."""
    times: dict = {}
    for r in range(reps):
        for p in files:
            for name in (list(rd) if r % 2 == 0 else list(rd)[::-1]):
                if not isinstance(times.get((p, name), []), list):    # not this reader's format, or it failed
                    continue
                try:
                    t0 = time.perf_counter()
                    got = rd[name](p)
                    dt = time.perf_counter() - t0
                except Exception as exc:   # a reader that cannot read the file: say so in the table
                    times[(p, name)] = f"fails ({type(exc).__name__})"
                    continue
                if got is None:
                    times[(p, name)] = None
                else:
                    times.setdefault((p, name), []).append(dt)
    return times


def cell(t) -> str:
    if t is None:
        return "–"
    if isinstance(t, str):
        return t
    m = statistics.median(t)
    return f"{m:.2f} s" if m >= 1 else f"{1e3 * m:.1f} ms"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=7, help="rounds for the shared meshes")
    ap.add_argument("--big-reps", type=int, default=5, help="rounds for the large OBJ files")
    ap.add_argument("--shared", type=Path, default=SHARED, help="the folder of the shared meshes")
    ap.add_argument("--no-big", action="store_true", help="without the large OBJ files")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    tmp = Path(tempfile.mkdtemp())
    try:
        files = [args.shared / n for n in ("spot_quad.obj", "sword_quad_dominant_hybrid.obj", "amo_large_tri.obj")]
        amo = sf.load(files[-1])
        for ext in (".ply", ".stl", ".glb"):
            sf.save(tmp / f"amo{ext}", amo)
            files.append(tmp / f"amo{ext}")
        big = [] if args.no_big else large_files(args.shared, tmp)
        rd = readers()
        for fn in rd.values():       # imports and first-call set-up outside the rounds
            try:
                fn(files[2])
            except Exception:   # noqa: BLE001 - measured (and named) in the rounds
                pass
        times = measure(files, rd, args.reps)
        times.update(measure(big, rd, args.big_reps))
        print(f"shapeflow {sf.__version__}; {os.cpu_count()} cores; load average {os.getloadavg()[0]:.2f}; "
              f"medians of {args.reps} rounds ({args.big_reps} for the large files)\n")
        print("| file | size | " + " | ".join(rd) + " | shapeflow / trimesh |")
        print("|---|---|" + "---|" * (len(rd) + 1))
        for p in files + big:
            ratios = [statistics.median(times[(p, "shapeflow")]) / statistics.median(times[(p, t)])
                      for t in ("trimesh", "trimesh, file order") if isinstance(times.get((p, t)), list)]
            ratio = " / ".join(f"{x:.2f}" for x in ratios) or "–"
            print(f"| {p.name} | {p.stat().st_size / 1e6:.1f} MB | "
                  + " | ".join(cell(times.get((p, name))) for name in rd) + f" | {ratio} |")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
