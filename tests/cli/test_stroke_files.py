"""Stroke files: the schema is validated, hostile JSON is one line, the stroke's work is bounded."""

from __future__ import annotations

import json

import numpy as np
import pytest

import shapeflow as sf
from shapeflow.commands.brush import read_stroke
from shapeflow.errors import ParameterError

GOOD = {"lambda": -20, "radius": 0.2, "points": [[0, 0, 0], [0.5, 0, 0]]}


def write(tmp_path, content) -> str:
    p = tmp_path / "s.json"
    p.write_bytes(content if isinstance(content, bytes) else json.dumps(content).encode())
    return str(p)


@pytest.mark.parametrize("content,match", [
    (b"[" * 100_000 + b"]" * 100_000, "nested too deeply"),
    (b'{"lambda": [[[[[[' * 20000 + b"]" * 20, "nested too deeply|not valid JSON"),
    (b'{"lambda": ' + b"9" * 5000 + b', "radius": 0.2, "points": [[0, 0, 0]]}', "finite number"),
    (b'{"lambda": -1, "radius": 0.2, "points": [[0, 0, ' + b"1" * 5000 + b"]]}", "point 0"),
    (b'{"lambda": -1, "radius": 1e999, "points": [[0, 0, 0]]}', "finite"),
    (b"\xff\xfe{}", "not UTF-8"),
    (b'{"lambda": NaN, "radius": 0.2, "points": [[0, 0, 0]]}', "finite"),
    (b'{"lambda": -1, "radius": 0.2, "points": [[0, 0]]}', "point 0"),
    (b'{"lambda": -1, "radius": 0.2, "points": [[0, 0, true]]}', "point 0"),
    (b'{"lambda": -1, "radius": 0.2, "points": "abc"}', "points"),
    (b'{"lambda": -1, "radius": 0.2, "points": [[0, 0, 0]], "spacing": "1"}', "spacing"),
    (b'{"lambda": -1, "radius": 0.2, "points": [[0, 0, 0]], "extra": 1}', "unknown key"),
    (b'{"lambda": -1, "radius": -2, "points": [[0, 0, 0]]}', "radius"),
    (b'{"lambda": -1, "radius": 0.2, "points": [[0, 0, 0]], "falloff": 3}', "falloff"),
    (b'{"lambda": -1, "radius": 0.2, "points": [[0, 0, 0]], "brush": "paint"}', "brush"),
    (b"[1, 2]", "JSON object"),
])
def test_bad_stroke_files_are_one_parameter_error(tmp_path, content, match):
    with pytest.raises(ParameterError, match=match):
        read_stroke(write(tmp_path, content))


def test_stroke_file_size_is_bounded(tmp_path, monkeypatch):
    import shapeflow.commands.brush as cb

    monkeypatch.setattr(cb, "MAX_STROKE_BYTES", 100)
    with pytest.raises(ParameterError, match="at most 100"):
        read_stroke(write(tmp_path, {**GOOD, "points": [[0, 0, 0]] * 50}))


def test_default_spacing_applies_when_the_key_is_absent(tmp_path):
    s = read_stroke(write(tmp_path, GOOD))
    assert s["spacing"] == 0.25
    assert read_stroke(write(tmp_path, {**GOOD, "spacing": None}))["spacing"] is None
    assert read_stroke(write(tmp_path, {**GOOD, "spacing": 0.5}))["spacing"] == 0.5


def test_bom_is_accepted(tmp_path):
    assert read_stroke(write(tmp_path, b"\xef\xbb\xbf" + json.dumps(GOOD).encode()))["radius"] == 0.2


@pytest.mark.parametrize("spacing,match", [(1e-12, r"gives [0-9.e+]+ dabs; at most 1,000,000"), (-1, "spacing")])
def test_stroke_work_is_bounded_before_it_starts(spacing, match):
    mesh = sf.load_example("spot")
    brush = sf.Brush(mesh, lam=-10.0, radius=0.1)
    with pytest.raises(ParameterError, match=match):
        brush.stroke([mesh.vertices[0], mesh.vertices[100]], spacing=spacing)
    with pytest.raises(ParameterError, match="too long"):
        brush.dab_centers([[-1e308, 0, 0], [1e308, 0, 0]], spacing=0.25)
    assert np.array_equal(brush.vertices, mesh.vertices)


def test_cli_hostile_stroke_is_one_line(tmp_path, capsys):
    from shapeflow.cli import main

    path = write(tmp_path, b"[" * 100_000 + b"]" * 100_000)
    code = main(["brush", "example:spot", str(tmp_path / "o.ply"), "--stroke", path])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and "nested too deeply" in err
    assert not (tmp_path / "o.ply").exists()
