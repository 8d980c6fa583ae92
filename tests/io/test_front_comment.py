"""The axis a model faces (``metadata["front"]``, the renderer's front view) survives PLY and OBJ as a
comment: ``comment shapeflow front -z`` / ``# shapeflow front -z``, written by the writers and read
back by the readers in that exact form only; every other comment stays a comment.  A saved Spot is
drawn from its face by ``render``'s default view, as the bundled one is."""

from __future__ import annotations

import numpy as np
import pytest
from plyfile import PlyData

import shapeflow as sf

TRIANGLE_OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
TRIANGLE_PLY = ("ply\nformat ascii 1.0\n{comments}element vertex 3\nproperty float x\nproperty float y\n"
                "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")


def _tri():
    return sf.Mesh(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]))


@pytest.mark.parametrize("ext", ["ply", "obj"])
@pytest.mark.parametrize("front", ["+x", "-x", "+y", "-y", "+z", "-z"])
def test_front_round_trips(tmp_path, ext, front):
    path = tmp_path / f"m.{ext}"
    sf.save(path, _tri().with_metadata(front=front))
    assert sf.load(path).metadata["front"] == front
    line = f"comment shapeflow front {front}\n" if ext == "ply" else f"# shapeflow front {front}\n"
    assert path.read_bytes().count(line.encode()) == 1


def test_a_saved_ply_says_it_to_other_readers(tmp_path):
    path = tmp_path / "spot.ply"
    sf.save(path, sf.load_example("spot"))
    assert "shapeflow front -z" in PlyData.read(str(path)).comments


def test_a_mesh_without_a_front_writes_none(tmp_path):
    for ext in ("ply", "obj"):
        path = tmp_path / f"m.{ext}"
        sf.save(path, _tri())
        assert b"shapeflow front" not in path.read_bytes()
        assert "front" not in sf.load(path).metadata
    sf.save(tmp_path / "odd.obj", _tri().with_metadata(front="forward"))   # not an axis: not written
    assert "front" not in (tmp_path / "odd.obj").read_text()


@pytest.mark.parametrize("comment,front", [
    ("shapeflow front -z", "-z"),
    ("shapeflow front +x", "+x"),
    ("shapeflow front  -z", None),          # only the exact form
    ("shapeflow front z", None),
    ("shapeflow front -w", None),
    ("Shapeflow front -z", None),
    ("shapeflow front: -z", None),
    ("shapeflow front -z please", None),
    ("front -z", None),
])
def test_only_the_exact_form_is_read(tmp_path, comment, front):
    ply = tmp_path / "m.ply"
    ply.write_text(TRIANGLE_PLY.format(comments=f"comment made by hand\ncomment {comment}\ncomment last\n"))
    obj = tmp_path / "m.obj"
    obj.write_text(f"# made by hand\n# {comment}\n# last\n" + TRIANGLE_OBJ)
    m_ply, m_obj = sf.load(ply), sf.load(obj)
    assert m_ply.metadata.get("front") == front and m_obj.metadata.get("front") == front
    kept = ["made by hand", "last"] if front else ["made by hand", comment, "last"]
    assert m_ply.metadata["ply"]["comment"] == kept
    assert m_obj.metadata["obj"]["comments"] == kept


def test_other_comments_come_back_unchanged(tmp_path):
    obj = tmp_path / "m.obj"
    obj.write_text("# exported by hand\n# shapeflow front -x\n" + TRIANGLE_OBJ)
    back = tmp_path / "back.obj"
    sf.save(back, sf.load(obj))
    lines = back.read_text().splitlines()
    assert lines[1:3] == ["# shapeflow front -x", "# exported by hand"]
    assert sf.load(back).metadata["obj"]["comments"] == ["exported by hand"]
    ply = tmp_path / "m.ply"
    ply.write_text(TRIANGLE_PLY.format(comments="comment scanner 7\ncomment shapeflow front +z\n"))
    sf.save(tmp_path / "back.ply", sf.load(ply))
    assert PlyData.read(str(tmp_path / "back.ply")).comments == ["written by shapeflow", "shapeflow front +z",
                                                                "scanner 7"]


@pytest.mark.parametrize("ext", ["ply", "obj"])
def test_a_saved_spot_is_drawn_from_its_face(tmp_path, ext, capsys):
    from shapeflow import rendering
    from shapeflow.cli import main

    if not rendering.available():
        pytest.skip("rendering unavailable (the render extra and offscreen OpenGL)")
    from PIL import Image

    saved = tmp_path / f"spot.{ext}"
    sf.save(saved, sf.load_example("spot"))
    stripped = tmp_path / f"stripped.{ext}"          # the same file without the comment
    stripped.write_bytes(saved.read_bytes().replace(b"shapeflow front -z", b"exported elsewhere"))

    def shot(*words):
        png = tmp_path / f"{len(list(tmp_path.iterdir()))}.png"
        assert main([*map(str, words), str(png), "--size", "160x120", "--no-colorbar", "-q"]) == 0
        return np.asarray(Image.open(png).convert("RGB")).astype(int)

    face = shot("render", "example:spot")
    assert np.array_equal(shot("render", saved), face)
    assert np.array_equal(shot("render", stripped, "--front", "-z"), face)
    assert not np.array_equal(shot("render", stripped), face)       # +z, a y-up file's default: its back
    assert np.array_equal(shot("render", stripped), shot("render", "example:spot", "--view", "back"))
