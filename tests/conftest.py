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

requires_shared = pytest.mark.skipif(SHARED is None,
                                     reason="shared/ (meshes and Blender fixtures) not found beside the repo")


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


# --------------------------------------------------------------------------
# SHAPEFLOW_REQUIRE_BPY=1 (CI's Blender environment): Blender must be there,
# and a test that would skip for want of Blender fails instead
# --------------------------------------------------------------------------

REQUIRE_BPY = os.environ.get("SHAPEFLOW_REQUIRE_BPY", "") == "1"


def pytest_sessionstart(session):
    import importlib.util

    if REQUIRE_BPY and importlib.util.find_spec("bpy") is None:
        raise pytest.UsageError("SHAPEFLOW_REQUIRE_BPY=1 but Blender's bpy module is not importable")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    rep = outcome.get_result()
    if REQUIRE_BPY and rep.skipped and "bpy" in str(rep.longrepr):
        rep.outcome = "failed"
        rep.longrepr = f"skipped for want of Blender although SHAPEFLOW_REQUIRE_BPY=1: {rep.longrepr}"
