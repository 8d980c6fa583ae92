"""Per-vertex weights: one check (``shapeflow.mesh.weights``) behind every way weights come in.

Each hostile weight vector is built by hand with its first bad value at a known vertex; every
entry point (the flow's and the brushes' ``weights``, a mesh attribute named by a string, the
``"weight"`` attribute of a Mesh, ``.txt`` and ``.npy`` files, ``shapeflow subdivide --weights``
and ``shapeflow enhance --weights``) must refuse it with a ValueError subclass naming that vertex,
and accept the good vectors unchanged.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from conftest import run_cli
from meshgen import grid

import shapeflow as sf
from shapeflow.errors import MeshError, ParameterError
from shapeflow.mesh.weights import check_weights, resolve_weights

MESH = grid(4, 3)          # 20 vertices
N = MESH.n_vertices


def _bad(i: int, value: float, also: int | None = None) -> np.ndarray:
    w = np.linspace(0.0, 1.0, N)
    w[i] = value
    if also is not None:
        w[also] = value
    return w


#: (name, weights, first bad vertex, number of values out of [0, 1] or not finite)
HOSTILE = [
    ("above one", _bad(7, 1.5), 7, 1),
    ("negative", _bad(3, -0.25, also=11), 3, 2),
    ("nan", _bad(0, np.nan), 0, 1),
    ("inf", _bad(N - 1, np.inf), N - 1, 1),
    ("minus inf", _bad(5, -np.inf), 5, 1),
    ("just above one", _bad(9, np.nextafter(1.0, 2.0)), 9, 1),
]


@pytest.mark.parametrize("name,w,i,count", HOSTILE, ids=[h[0] for h in HOSTILE])
def test_parameters_name_the_first_bad_vertex(name, w, i, count):
    pattern = rf"^weights must lie in \[0, 1\]; vertex {i} has .* \({count} such vertices\)$"
    for call in (lambda: sf.flow(MESH, 1.0, weights=w), lambda: sf.FlowSolver(MESH, weights=w),
                 lambda: sf.Brush(MESH, radius=0.5, weights=w), lambda: sf.InflateBrush(MESH, radius=0.5, weights=w),
                 lambda: resolve_weights(MESH, w)):
        with pytest.raises(ParameterError, match=pattern):
            call()
    # the mesh's own "weight" attribute (a value that is not finite is refused for any attribute first)
    with pytest.raises(MeshError, match=pattern if np.isfinite(w).all() else rf"'weight' .* at vertex {i}$"):
        MESH.with_weights(w)


FINITE = [h for h in HOSTILE if np.isfinite(h[1]).all()]     # attributes are finite (Mesh checks that)


@pytest.mark.parametrize("name,w,i,count", FINITE, ids=[h[0] for h in FINITE])
def test_an_attribute_named_as_weights_is_checked_as_weights(name, w, i, count):
    m = MESH.with_attributes(mask=w)                      # any attribute may hold any finite number
    with pytest.raises(ParameterError, match=rf"^weights \(attribute 'mask'\) must lie in \[0, 1\]; vertex {i} "):
        sf.flow(m, 1.0, weights="mask")


@pytest.mark.parametrize("name,w,i,count", HOSTILE, ids=[h[0] for h in HOSTILE])
def test_files_name_the_file_and_the_line(name, w, i, count, tmp_path):
    txt = tmp_path / "w.txt"
    txt.write_text("# painted\n" + "\n".join(repr(float(x)) for x in w) + "\n")
    np.save(tmp_path / "w.npy", w)
    value = re.escape(repr(float(w[i])))
    what = "is not finite" if not np.isfinite(w[i]) else rf"is {value}, outside \[0, 1\] \({count} such values\)"
    with pytest.raises(MeshError, match=rf"w\.txt: line {i + 2}: weight of vertex {i} {what}"):
        sf.load_weights(txt, N)
    with pytest.raises(MeshError, match=rf"w\.npy: value {i}: weight of vertex {i} {what}"):
        sf.load_weights(tmp_path / "w.npy", N)


@pytest.mark.parametrize("command", [["subdivide"], ["enhance", "--strength", "1"]])
@pytest.mark.parametrize("name,w,i,count", HOSTILE[:3], ids=[h[0] for h in HOSTILE[:3]])
def test_commands_read_weight_files_through_the_same_check(command, name, w, i, count, tmp_path, capsys):
    """``subdivide --weights`` had a loader of its own that let values outside [0, 1] through to the
    mesh and named no file; now every command reads weights the same way."""
    src, out, wf = tmp_path / "in.ply", tmp_path / "out.ply", tmp_path / "w.txt"
    sf.save(src, MESH)
    wf.write_text("\n".join(repr(float(x)) for x in w) + "\n")
    code, _, err = run_cli([command[0], src, out, *command[1:], "--weights", wf], capsys)
    assert code != 0 and err.count("\n") == 1 and "Traceback" not in err
    assert f"w.txt: line {i + 1}: weight of vertex {i} " in err
    assert not out.exists()
    wf.write_text("0.5\n" * (N - 1))
    code, _, err = run_cli([command[0], src, out, *command[1:], "--weights", wf], capsys)
    assert code != 0 and f"w.txt: has {N - 1} weights but the mesh has {N} vertices" in err and not out.exists()


def test_shapes_and_lengths():
    shape = rf"^weights must have shape \({N},\) \(one per vertex\), got"
    with pytest.raises(ParameterError, match=rf"{shape} \({N - 1},\)"):
        sf.flow(MESH, 1.0, weights=np.ones(N - 1))
    with pytest.raises(ParameterError, match=rf"{shape} \({N}, 1\)"):
        sf.flow(MESH, 1.0, weights=np.ones((N, 1)))
    with pytest.raises(ParameterError, match="weights must be real numbers"):
        sf.flow(MESH, 1.0, weights=["a"] * N)
    with pytest.raises(ParameterError, match=r"the mesh has no attribute 'paint' \(attributes: none\)"):
        sf.flow(MESH, 1.0, weights="paint")
    m = MESH.with_attributes(rgb=np.zeros((N, 3)))
    with pytest.raises(ParameterError, match=rf"weights \(attribute 'rgb'\) must have shape \({N},\)"):
        sf.flow(m, 1.0, weights="rgb")
    with pytest.raises(MeshError, match=r"w\.txt: has 3 weights but the mesh has 4 vertices"):
        check_weights("w.txt", np.zeros(3), 4, lambda i: f"line {i + 1}")


def test_good_weights_pass_unchanged():
    w = np.linspace(0.0, 1.0, N)
    w[3] = np.nextafter(0.0, 1.0)                           # the smallest positive double is in range
    got = resolve_weights(MESH, w)
    assert got is not w and np.array_equal(got, w)
    assert np.array_equal(resolve_weights(MESH, w, invert=True), 1.0 - w)
    assert np.array_equal(resolve_weights(MESH, None), np.ones(N))
    assert np.array_equal(resolve_weights(MESH.with_weights(w), "weight"), w)
    assert np.array_equal(resolve_weights(MESH, list(w.astype(np.float32))), w.astype(np.float32))
    assert check_weights("weights", w, N) is w
