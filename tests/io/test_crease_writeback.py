"""A subdivision's creases written from Python: an OBJ keeps them as ``t crease`` lines, any other
format says it drops them.  The reference is the definition of the tag (OpenSubdiv's sharpness
s = 10·c² of Blender's crease c), read back here with a parse of the file's text."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import shapeflow as sf
from shapeflow.geometry.features import file_creases


def creased():
    cage = sf.load_example("spot_cage")
    e = cage.topology.edges[:6]
    return sf.subdivide(cage, 1, creases=(e, np.array([1.0, 0.5, 0.25, 0.0, 1.0, 0.8])))


def test_an_obj_written_from_python_keeps_the_creases(tmp_path):
    out = creased()
    pairs, c = out.creases
    sf.save(tmp_path / "s.obj", out)
    lines = [ln.split() for ln in (tmp_path / "s.obj").read_text().splitlines() if ln.startswith("t crease")]
    got = {(int(a), int(b)): float(s) for _, _, _, a, b, s in lines}
    want = {(int(a), int(b)): 10.0 * v * v for (a, b), v in zip(pairs, c) if v > 0}
    assert got.keys() == want.keys() and all(abs(got[k] - want[k]) < 1e-12 for k in want)
    back = sf.load(tmp_path / "s.obj")
    bp, bs = file_creases(back)
    assert len(bp) == len(want)
    # and subdividing what was read continues the same surface as subdividing the result itself
    again = sf.subdivide(back, 1, creases="mesh")
    direct = sf.subdivide(out, 1, creases="mesh")
    np.testing.assert_allclose(again.vertices, direct.vertices, atol=1e-12 * out.diagonal)


@pytest.mark.parametrize("ext", [".ply", ".off", ".stl"])
def test_other_formats_say_they_drop_the_creases(tmp_path, ext):
    out = creased()
    n = int((np.asarray(out.creases[1]) > 0).sum())
    with warnings.catch_warnings(record=True) as got:
        warnings.simplefilter("always")
        sf.save(tmp_path / f"s{ext}", out)
    said = [str(w.message) for w in got if issubclass(w.category, sf.DataLossWarning)]
    assert any(f"the mesh's {n} creased edges are not written" in s for s in said), said
