"""Regenerate (or check) the Blender reference outputs in this folder with real Blender.

    python tests/data/blender/regenerate.py            # rewrite cases/*.npz and the timings in cases.json
    python tests/data/blender/regenerate.py --check    # compare only; exit 1 on a difference
    python tests/data/blender/regenerate.py smooth_torus_0 ...   # only these cases

Needs Blender as a Python module (``pip install bpy==5.0.1``, Python 3.11: the ``blender``
extra).  Every case is rerun from its own inputs — the mesh in ``meshes/NAME.npz``, the
parameters and vertex-group weights stored in the case — through the project's harness
``benchmarks/blender_ref.py`` (Blender's Laplacian Smooth and Subdivision Surface modifiers),
and the case file is rewritten with Blender's result.  Inputs are never changed.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[2]
#: the tolerance of --check, × the result's bounding-box diagonal (the same Blender agrees to ~0)
TOL = 1e-6


def harness():
    spec = importlib.util.spec_from_file_location("blender_ref", ROOT / "benchmarks" / "blender_ref.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("blender_ref", mod)
    spec.loader.exec_module(mod)
    return sys.modules["blender_ref"]


def rerun(br, case: str) -> tuple[dict, float]:
    """Blender's arrays for one case (the keys of its .npz) and the modifier's seconds."""
    stored = br.load_case(HERE, case)
    V, fs, fi = br.load_mesh(HERE, stored["mesh"])
    params = {k: v for k, v in stored["params"].items() if k != "weights"}
    weights = stored.get("weights")
    out = {"mesh": np.array(stored["mesh"]), "params": np.array(json.dumps(stored["params"]))}
    if weights is not None:
        out["weights"] = weights
    if case.startswith("subdiv_"):
        P, rfs, rfi, rw, secs = br.subdivision_surface(V, fs, fi, weights=weights, **params)
        out.update(result=P, result_face_sizes=rfs, result_face_indices=rfi)
        if rw is not None:
            out["result_weights"] = rw
    else:
        P, secs = br.laplacian_smooth(V, fs, fi, weights=weights, **params)
        out["result"] = P
    return out, secs


def differs(old: dict, new: dict) -> str:
    """'' when Blender's new arrays match the stored ones, else what differs."""
    diag = float(np.linalg.norm(old["result"].max(axis=0) - old["result"].min(axis=0)))
    if old["result"].shape != new["result"].shape:
        return f"result shape {new['result'].shape} != {old['result'].shape}"
    dev = float(np.abs(old["result"] - new["result"]).max()) / diag
    if dev > TOL:
        return f"result deviates by {dev:.2e} x the diagonal"
    for key in ("result_face_sizes", "result_face_indices"):
        if key in old and not np.array_equal(old[key], new[key]):
            return f"{key} differ"
    return ""


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="compare with the stored outputs; write nothing")
    ap.add_argument("cases", nargs="*", help="case names (default: every case in cases.json)")
    args = ap.parse_args(argv)
    br = harness()
    if not br.available():
        print("regenerate.py: Blender's bpy module is not importable: pip install bpy==5.0.1 (Python 3.11)",
              file=sys.stderr)
        return 2
    meta = json.loads((HERE / "cases.json").read_text())
    names = args.cases or sorted(meta["cases"])
    unknown = sorted(set(names) - set(meta["cases"]))
    if unknown:
        print(f"regenerate.py: unknown case(s): {', '.join(unknown)}", file=sys.stderr)
        return 2
    bad = 0
    for name in names:
        new, secs = rerun(br, name)
        old = dict(np.load(HERE / "cases" / f"{name}.npz"))
        why = differs(old, new)
        print(f"{name:60s} {'differs: ' + why if why else 'same'}")
        bad += bool(why)
        if not args.check:
            tmp = HERE / "cases" / f".{name}.tmp.npz"
            np.savez_compressed(tmp, **new)
            os.replace(tmp, HERE / "cases" / f"{name}.npz")
            meta["cases"][name]["blender_seconds"] = round(secs, 4)
    if not args.check:
        (HERE / "cases.json").write_text(json.dumps(meta, indent=1, sort_keys=True) + "\n")
    return 1 if args.check and bad else 0


if __name__ == "__main__":
    sys.exit(main())
