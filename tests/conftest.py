"""Shared test fixtures: where the shared meshes and Blender fixtures live."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]


def _find_shared() -> Path | None:
    env = os.environ.get("SHAPEFLOW_SHARED")
    cands = [Path(env)] if env else []
    cands += [ROOT.parent / "shared", ROOT / "shared"]
    for c in cands:
        if (c / "meshes").is_dir():
            return c
    return None


SHARED = _find_shared()
MESHES = SHARED / "meshes" if SHARED else None
FIXTURES = SHARED / "fixtures" / "blender" if SHARED else None

requires_shared = pytest.mark.skipif(SHARED is None, reason="shared/ (meshes and Blender fixtures) not found beside the repo")


def shared_mesh_paths() -> list[Path]:
    return sorted(MESHES.glob("*.obj")) if MESHES else []


def fixture_cases(kind_prefix: str = "") -> list[str]:
    if FIXTURES is None:
        return []
    cases = json.loads((FIXTURES / "cases.json").read_text())["cases"]
    return sorted(k for k in cases if k.startswith(kind_prefix))


def load_fixture_mesh(name: str):
    import shapeflow as sf

    d = np.load(FIXTURES / "meshes" / f"{name}.npz")
    return sf.Mesh.from_csr(d["vertices"], d["face_sizes"], d["face_indices"])


def load_fixture_case(case: str) -> dict:
    d = np.load(FIXTURES / "cases" / f"{case}.npz")
    out = {k: d[k] for k in d.files}
    out["params"] = json.loads(str(out["params"]))
    out["mesh"] = str(out["mesh"])
    return out
