"""Bit-for-bit snapshot of shapeflow's results, to compare two versions of the code.

Usage::

    python tools/snapshot.py dump OUT.npz [--shared DIR]   # run the battery, save every array
    python tools/snapshot.py compare A.npz B.npz           # exit 1 unless every array is bit-identical

The battery uses the public API only (so any two versions can be compared):
for every shared mesh it records the Laplacians (both schemes, plain and
normalised), cotangent weights, vertex areas, mean curvature, flows in paper
and Blender mode (smoothing, enhancement, border factor, weights, volume
preservation, several iterations, recomputed operator, each solver), a
``FlowSolver`` reused for two λ, a family, Catmull–Clark and simple
subdivision, a brush stroke and an inflate stroke, and the bytes each writer
produces; then every Blender fixture case.  Run it with
``SHAPEFLOW_KERNELS=0`` and ``SHAPEFLOW_KERNELS=force`` to cover both paths.
"""

from __future__ import annotations

import argparse
import hashlib
import io as _bytes_io
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SKIP = {"amo_large_tri"}          # the largest mesh: its flows add minutes, no code path the others miss


def _mesh_battery(sf, name, m, out):
    def put(key, a):
        out[f"{name}/{key}"] = np.asarray(a)

    put("load/V", m.vertices)
    put("load/F", m.face_indices)
    for scheme in ("tqlbo", "blender"):
        for norm in (False, True):
            L = sf.laplacian(m, normalized=norm, scheme=scheme).tocsr()
            L.sort_indices()
            put(f"L/{scheme}/{norm}/data", L.data)
            put(f"L/{scheme}/{norm}/indices", L.indices)
        cw = sf.cotan_weights(m, scheme)
        put(f"cw/{scheme}/pw", cw.pair_weights)
        put(f"cw/{scheme}/deg", cw.degree)
        put(f"cw/{scheme}/area", cw.ring_area)
    for kind in ("ring", "barycentric"):
        put(f"areas/{kind}", sf.vertex_areas(m, kind))
    put("H", sf.mean_curvature(m))
    n = m.n_vertices
    rng = np.random.default_rng(7)
    w = rng.random(n)
    runs = {
        "smooth": dict(lam=0.5),
        "enh": dict(lam=-3.0),
        "enh_border": dict(lam=-2.0, lam_border=0.5),
        "enh_w": dict(lam=-5.0, weights=w),
        "enh_vol": dict(lam=-4.0, preserve_volume=True, iterations=2),
        "enh_recompute": dict(lam=-1.0, iterations=2, update="recompute"),
        "enh_unnorm": dict(lam=-0.01, normalized=False),
        "enh_axes": dict(lam=-3.0, axes="xz"),
        "blender": dict(lam=-3.0, lam_border=0.3, compat="blender", iterations=2),
        "blender_vol": dict(lam=0.8, compat="blender", preserve_volume=True, weights=w),
        "cg": dict(lam=-3.0, solver="cg"),
        "lu": dict(lam=-3.0, solver="lu"),
        "cheb": dict(lam=-3.0, solver="chebyshev"),
        "huge": dict(lam=-1e9),
    }
    for key, kw in runs.items():
        lam = kw.pop("lam")
        put(f"flow/{key}", sf.flow(m, lam, **kw).vertices)
    fs = sf.FlowSolver(m, lam_border=0.2)
    put("solver/a", fs.run(-2.0).vertices)
    put("solver/b", fs.run(1.0, iterations=2, preserve_volume=True).vertices)
    fam = sf.family(m, [-4.0, -1.0, 0.5, 2.0])
    put("family", fam)
    fam2 = sf.family(m, [-2.0, 1.0], strategy="separate", preserve_volume=True, iterations=2)
    put("family_sep", fam2)
    for scheme in ("catmull-clark", "simple"):
        s = sf.subdivide(m.with_weights(w), 1, scheme=scheme)
        put(f"subdiv/{scheme}/V", s.vertices)
        put(f"subdiv/{scheme}/F", s.face_indices)
        put(f"subdiv/{scheme}/w", s.attributes["weight"])
    if n <= 60_000:
        lo, hi = m.vertices.min(0), m.vertices.max(0)
        pts = lo + (hi - lo) * np.array([[0.3, 0.5, 0.5], [0.5, 0.6, 0.5], [0.7, 0.5, 0.55]])
        pts = m.vertices[np.argmin(((m.vertices[None] - pts[:, None]) ** 2).sum(-1), axis=1)]
        r = 0.12 * m.diagonal
        b = sf.Brush(m, lam=-30.0, radius=r)
        b.stroke(pts)
        put("brush/stroke", b.mesh.vertices)
        b.undo()
        b.dab(pts[1])
        put("brush/dab", b.mesh.vertices)
        ib = sf.InflateBrush(m, radius=r, falloff="smooth")
        ib.stroke(pts)
        put("inflate/stroke", ib.mesh.vertices)
    with tempfile.TemporaryDirectory() as d:
        for ext, kw in ((".obj", {}), (".off", {}), (".ply", {"binary": True}), (".ply", {"binary": False})):
            p = Path(d) / f"m{ext}"
            sf.save(p, m.with_weights(w), **kw)
            data = p.read_bytes()
            put(f"save/{ext}/{kw.get('binary')}", np.frombuffer(hashlib.sha256(data).digest(), np.uint8))
            back = sf.load(p)
            put(f"reload/{ext}/{kw.get('binary')}", back.vertices)


def dump(path: str, shared: Path) -> None:
    sys.path.insert(0, str(ROOT / "src"))
    import shapeflow as sf

    out: dict[str, np.ndarray] = {}
    for p in sorted((shared / "meshes").glob("*.obj")):
        if p.stem in SKIP:
            continue
        print(p.stem, flush=True)
        _mesh_battery(sf, p.stem, sf.load(p), out)
    fix = shared / "fixtures" / "blender"
    cases = json.loads((fix / "cases.json").read_text())["cases"]
    for case in sorted(cases):
        c = np.load(fix / "cases" / f"{case}.npz")
        prm = json.loads(str(c["params"]))
        d = np.load(fix / "meshes" / f"{cases[case]['mesh']}.npz")
        mesh = sf.Mesh.from_csr(d["vertices"], d["face_sizes"], d["face_indices"])
        weights = c["weights"] if "weights" in c.files else None
        if cases[case]["kind"] == "laplacian_smooth":
            r = sf.flow(mesh, prm["lambda_factor"], lam_border=prm["lambda_border"], iterations=prm["iterations"],
                        normalized=prm["use_normalized"], preserve_volume=prm["use_volume_preserve"],
                        axes=(prm["use_x"], prm["use_y"], prm["use_z"]), weights=weights,
                        invert_weights=prm["invert_vertex_group"], compat="blender")
            out[f"fixture/{case}"] = r.vertices
        else:
            scheme = {"CATMULL_CLARK": "catmull-clark", "SIMPLE": "simple"}[prm["subdivision_type"]]
            boundary = {"ALL": "smooth", "PRESERVE_CORNERS": "keep-corners"}[prm["boundary_smooth"]]
            if weights is not None:
                mesh = mesh.with_weights(weights)
            r = sf.subdivide(mesh, prm["levels"], scheme=scheme, boundary=boundary)
            out[f"fixture/{case}/V"] = r.vertices
            out[f"fixture/{case}/F"] = r.face_indices
    buf = _bytes_io.BytesIO()
    np.savez(buf, **out)
    Path(path).write_bytes(buf.getvalue())
    print(f"{len(out)} arrays -> {path}")


def compare(a: str, b: str) -> int:
    A, B = np.load(a), np.load(b)
    bad = sorted(set(A.files) ^ set(B.files))
    for k in sorted(set(A.files) & set(B.files)):
        x, y = A[k], B[k]
        if x.dtype != y.dtype or x.shape != y.shape or x.tobytes() != y.tobytes():
            bad.append(k)
    print(f"{len(A.files)} vs {len(B.files)} arrays; {len(bad)} differ")
    for k in bad[:50]:
        print("  ", k)
    return 1 if bad else 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    d = sub.add_parser("dump")
    d.add_argument("out")
    d.add_argument("--shared", type=Path, default=ROOT.parent / "shared")
    c = sub.add_parser("compare")
    c.add_argument("a")
    c.add_argument("b")
    args = ap.parse_args()
    if args.cmd == "dump":
        dump(args.out, args.shared)
        return 0
    return compare(args.a, args.b)


if __name__ == "__main__":
    sys.exit(main())
