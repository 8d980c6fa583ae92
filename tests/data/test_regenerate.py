"""tests/data/blender/regenerate.py writes back exactly what Blender returns, in the cases' own layout.

Blender itself is stood in for by a harness that answers with the stored results (the real run needs
bpy: the CI's Blender environment); what is checked is the script's part: every key of a case, its
inputs untouched, its parameters passed on, --check telling a difference."""

from __future__ import annotations

import importlib.util
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve().parent / "blender"


@pytest.fixture
def regen(tmp_path, monkeypatch):
    """The script, working on a copy of two cases, with a stand-in harness (``calls`` records them)."""
    spec = importlib.util.spec_from_file_location("regenerate", HERE / "regenerate.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    real = mod.harness()
    cases = ["smooth_grid_open_8", "subdiv_cylinder_ngon_catmull_clark_all_1"]
    (tmp_path / "cases").mkdir()
    shutil.copytree(HERE / "meshes", tmp_path / "meshes")
    for c in cases:
        shutil.copy(HERE / "cases" / f"{c}.npz", tmp_path / "cases")
    meta = json.loads((HERE / "cases.json").read_text())
    meta["cases"] = {c: meta["cases"][c] for c in cases}
    (tmp_path / "cases.json").write_text(json.dumps(meta))
    calls = []

    class Blender:
        load_case, load_mesh = staticmethod(real.load_case), staticmethod(real.load_mesh)
        shift = 0.0

        @staticmethod
        def available():
            return True

        @classmethod
        def laplacian_smooth(cls, V, fs, fi, weights=None, **p):
            calls.append(("smooth", p, weights))
            return real.load_case(HERE, cases[0])["result"] + cls.shift, 0.5

        @classmethod
        def subdivision_surface(cls, V, fs, fi, weights=None, **p):
            calls.append(("subdiv", p, weights))
            c = real.load_case(HERE, cases[1])
            return c["result"] + cls.shift, c["result_face_sizes"], c["result_face_indices"], c["result_weights"], 0.25

    monkeypatch.setattr(mod, "HERE", tmp_path)
    monkeypatch.setattr(mod, "harness", lambda: Blender)
    return mod, Blender, calls, cases, tmp_path


def test_rewritten_cases_hold_what_blender_returned(regen, capsys):
    mod, _, calls, cases, folder = regen
    assert mod.main([]) == 0
    for c in cases:
        old, new = np.load(HERE / "cases" / f"{c}.npz"), np.load(folder / "cases" / f"{c}.npz")
        assert sorted(old.files) == sorted(new.files)
        for k in old.files:
            assert np.array_equal(old[k], new[k]), (c, k)
    # the stored parameters and weights reached Blender; "weights" (the weights' name) is no modifier option
    stored = np.load(HERE / "cases" / f"{cases[0]}.npz")
    kind, params, weights = calls[0]
    assert kind == "smooth" and params == {k: v for k, v in json.loads(str(stored["params"])).items() if k != "weights"}
    assert np.array_equal(weights, stored["weights"])
    timings = json.loads((folder / "cases.json").read_text())["cases"]
    assert [timings[c]["blender_seconds"] for c in cases] == [0.5, 0.25]
    assert "same" in capsys.readouterr().out


def test_check_tells_a_difference_and_writes_nothing(regen, capsys):
    mod, blender, _, cases, folder = regen
    before = (folder / "cases" / f"{cases[0]}.npz").read_bytes()
    assert mod.main(["--check"]) == 0
    blender.shift = 1e-3
    assert mod.main(["--check", cases[0]]) == 1
    assert "differs: result deviates" in capsys.readouterr().out
    assert (folder / "cases" / f"{cases[0]}.npz").read_bytes() == before
    assert mod.main(["no_such_case"]) == 2


def test_without_blender_it_says_how_to_get_it(regen, capsys, monkeypatch):
    mod, blender, *_ = regen
    monkeypatch.setattr(blender, "available", staticmethod(lambda: False))
    assert mod.main([]) == 2
    assert "pip install bpy==5.0.1" in capsys.readouterr().err
