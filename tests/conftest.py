"""Shared test fixtures and helpers: the test data in tests/data, Spot, ``run_cli``, optional dependencies, a
temporary folder per test.

The meshes and Blender reference outputs the tests read are in the repository (tests/data,
provenance and licences in tests/data/SOURCES.md), so a fresh clone runs every test that needs
nothing beyond what ``pip install -e ".[all,test]"`` installs.
"""

from __future__ import annotations

import importlib
import json
import os
import tempfile
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data"
MESHES = DATA / "meshes"               # third-party meshes that may be redistributed (SOURCES.md)
FIXTURES = DATA / "blender"            # Blender 5.0.1's outputs on our inputs (SOURCES.md)

requires_data = pytest.mark.skipif(not (MESHES / "spot_tri.obj").is_file(),
                                   reason="tests/data is missing (a partial checkout?)")
#: the name the tests used when the meshes lived beside the repository; the same mark
requires_shared = requires_data


def shared_mesh_paths() -> list[Path]:
    """Every bundled test mesh (tests/data/meshes/*.obj), sorted by name."""
    return sorted(MESHES.glob("*.obj"))


def fixture_cases(kind_prefix: str = "") -> list[str]:
    """The bundled Blender reference cases whose name starts with ``kind_prefix``."""
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
# shared fixtures and helpers
# --------------------------------------------------------------------------

@pytest.fixture(scope="module")
def spot():
    """The bundled Spot (``example:spot``), loaded once per test module (a Mesh does not change)."""
    import shapeflow as sf

    return sf.load_example("spot")


def run_cli(args, capsys) -> tuple[int, str, str]:
    """``shapeflow ARGS`` run in this process: (exit code, stdout, stderr)."""
    from shapeflow.cli import main

    code = main([str(a) for a in args])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


# --------------------------------------------------------------------------
# optional dependencies
# --------------------------------------------------------------------------

def import_failure(module: str, what: str | None = None) -> str | None:
    """None when ``module`` imports; else why not, in one line naming the cause.

    Any exception counts, not only ModuleNotFoundError: a package that is installed but cannot
    load (open3d without the system's libusb-1.0.so.0 raises ImportError or OSError) is named
    with the original error."""
    what = what or module
    try:
        importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name and module.split(".")[0] == exc.name.split(".")[0]:
            return f"{what} is not installed"
        return f"{what} cannot be imported: {type(exc).__name__}: {exc}"
    except Exception as exc:       # noqa: BLE001 - a broken install or a missing system library
        return f"{what} cannot be imported: {type(exc).__name__}: {exc}"
    return None


def need(module: str, what: str | None = None):
    """The module, or skip the test (or the whole module, at import time) naming why it is not there.

    The replacement of ``pytest.importorskip`` for optional dependencies: ``o3d = need("open3d")``.
    ``what`` describes the dependency in the reason (default: the module's name)."""
    why = import_failure(module, what)
    if why is not None:
        pytest.skip(why, allow_module_level=True)
    return importlib.import_module(module)


# --------------------------------------------------------------------------
# hermetic tests: every test has its own temporary folder
# --------------------------------------------------------------------------

@pytest.fixture(autouse=True)
def own_temporary_folder(tmp_path_factory, monkeypatch):
    """TMPDIR (TEMP, TMP) and :data:`tempfile.tempdir` point at a folder of this test's own, for the
    test and everything it starts; both are restored afterwards.  What a test finds there, it made."""
    folder = tmp_path_factory.mktemp("tmp")
    for var in ("TMPDIR", "TEMP", "TMP"):
        monkeypatch.setenv(var, str(folder))
    monkeypatch.setattr(tempfile, "tempdir", str(folder))
    yield folder


# --------------------------------------------------------------------------
# SHAPEFLOW_REQUIRE_BPY=1 (CI's Blender environment): Blender must be there,
# and a test that would skip for want of Blender fails instead
# --------------------------------------------------------------------------

REQUIRE_BPY = os.environ.get("SHAPEFLOW_REQUIRE_BPY", "") == "1"


def pytest_sessionstart(session):
    import importlib.util
    import signal

    # a suite started in the background by a non-interactive shell (a CI script's `cmd &`, nohup)
    # inherits SIGINT ignored, and so would every process the tests start: the tests that press
    # Ctrl-C on a shapeflow process would wait for an exit that never comes. The processes start
    # as from a terminal instead (an ignored SIGINT stays ignored across exec; a handler does not).
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    if REQUIRE_BPY and importlib.util.find_spec("bpy") is None:
        raise pytest.UsageError("SHAPEFLOW_REQUIRE_BPY=1 but Blender's bpy module is not importable")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    rep = outcome.get_result()
    if REQUIRE_BPY and rep.skipped and "bpy" in str(rep.longrepr):
        rep.outcome = "failed"
        rep.longrepr = f"skipped for want of Blender although SHAPEFLOW_REQUIRE_BPY=1: {rep.longrepr}"
