"""Creases on the command line: ``subdivide`` takes an OBJ's ``t crease`` tags by default
(``--no-creases`` ignores them, ``--creases FILE`` replaces them) and writes the result's creases
back as ``t crease`` lines; ``render --feature-lines [DEG|marked]``.

Expected values: the library's ``sf.subdivide(..., creases=...)`` on the file as read, bit for bit
(OBJ writes coordinates exactly), tags parsed here with a regular expression, and one derivation:
a box whose twelve edges are infinitely sharp subdivides into a box (each side stays in its
plane), which a box without creases does not.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from conftest import MESHES, requires_data, run_cli
from hard_surface import EXACT, box_edge_pairs, box_obj, box_sets, flatness, quad_box

import shapeflow as sf
from shapeflow.commands import RenderOptions, operations_parser, options_from
from shapeflow.errors import ParameterError

TAG = re.compile(r"^t crease 2/1 (\d+) (\d+) (\S+)$", re.M)


def cube_cage(tmp_path, creases=None, extra: str = ""):
    """The cube [0, 2] × [0, 1] × [0, 1] of six quads as OBJ, with ``t crease`` tags."""
    V, sides, _ = quad_box(k=1)
    path = tmp_path / "cage.obj"
    path.write_text(box_obj(V, sides, creases=creases) + extra)
    return path, V, sides


def tags_of(path) -> tuple[np.ndarray, np.ndarray]:
    found = TAG.findall(path.read_text())
    return np.array([(int(a), int(b)) for a, b, _ in found]).reshape(-1, 2), np.array([float(s) for *_, s in found])


@pytest.fixture
def creased(tmp_path):
    """The cube cage with its four top edges creased (sharpness 2.5) and one bottom edge (10: infinite)."""
    V = quad_box(k=1)[0]
    _, _, sides = cube_cage(tmp_path)
    pairs = box_edge_pairs(V, sides)
    top = pairs[np.isclose(V[pairs, 2], 1.0).all(axis=1)]
    bottom = pairs[np.isclose(V[pairs, 2], 0.0).all(axis=1)][:1]
    path, _, _ = cube_cage(tmp_path, (np.r_[top, bottom], np.r_[[2.5] * 4, 10.0]))
    return path, np.r_[top, bottom]


@pytest.mark.parametrize("levels", [0, 1, 3])
def test_subdivide_takes_the_file_s_tags_and_equals_the_library(creased, tmp_path, capsys, levels):
    path, _ = creased
    out = tmp_path / "out.obj"
    code, _, err = run_cli(["subdivide", path, out, "--levels", levels], capsys)
    assert code == 0, err
    assert re.fullmatch(r"shapeflow subdivide: 8 vertices, 6 faces -> \d+ vertices, \d+ faces "
                        r"\(catmull-clark, \d levels?\) in \d+\.\d{3} s; 5 creased edges from the file's 't crease' "
                        r"tags \(--no-creases ignores them\)\n", err), err
    m = sf.load(path)
    expected = sf.subdivide(m, levels, creases="mesh")
    got = sf.load(out)
    assert np.array_equal(got.vertices, expected.vertices) and np.array_equal(got.face_indices, expected.face_indices)
    assert not np.array_equal(got.vertices, sf.subdivide(m, levels).vertices) or levels == 0
    # the result's creases as tags: the halves, sharpness 10·c² one level down per level
    pairs, s = tags_of(out)
    e_pairs, c = expected.creases
    keep = c > 0
    assert np.array_equal(pairs, e_pairs[keep]) and np.array_equal(s, np.minimum(10 * c[keep] ** 2, 10.0))
    assert sorted(set(np.round(s, 12))) == sorted({round(x, 12) for x in (max(2.5 - levels, 0), 10.0)} - {0.0})


def test_tag_vertex_numbers_count_from_0_as_opensubdiv_s_faces_from_1(tmp_path, capsys):
    # OpenSubdiv's tag form 't crease 2/1/0 v w s': v, w index the 'v' lines from 0 while 'f' counts from 1
    cube = ("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
            "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n"
            "t crease 2/1/0 0 1 2.0\nt crease 2/1/0 1 2 10\n")
    path = tmp_path / "cube.obj"
    path.write_text(cube)
    out = tmp_path / "out.obj"
    assert run_cli(["subdivide", path, out, "-l", "1", "-q"], capsys)[0] == 0
    plain = sf.Mesh(np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]],
                             float),
                    np.array([[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]))
    # the edges (0, 1) and (1, 2): the bottom's x = 0..1 at y = 0 and y = 0..1 at x = 1; sharpness s = 10·c²
    expected = sf.subdivide(plain, 1, creases=([[0, 1], [1, 2]], [np.sqrt(0.2), 1.0]))
    got = sf.load(out)
    assert np.array_equal(got.vertices, expected.vertices)
    # what is written back: tag numbers from 0, faces from 1, read here from the text alone
    text = out.read_text()
    faces = [[int(w) - 1 for w in ln.split()[1:]] for ln in text.splitlines() if ln.startswith("f ")]
    edges = {frozenset((f[i], f[(i + 1) % len(f)])) for f in faces for i in range(len(f))}
    pairs, s = tags_of(out)
    assert len(pairs) == 4 and all(frozenset(p) in edges for p in pairs.tolist())
    assert np.allclose(sorted(s.tolist()), [1.0, 1.0, 10.0, 10.0])       # one level softer; 10 stays infinite
    assert len(set(pairs.ravel().tolist())) == 5                         # two edges of two halves each: a chain


def test_the_written_tags_continue_the_same_surface(creased, tmp_path, capsys):
    path, _ = creased
    assert run_cli(["subdivide", path, tmp_path / "one.obj", "-l", "1", "-q"], capsys)[0] == 0
    assert run_cli(["subdivide", tmp_path / "one.obj", tmp_path / "two.obj", "-l", "1", "-q"], capsys)[0] == 0
    once = sf.subdivide(sf.load(path), 1, creases="mesh")
    assert np.array_equal(sf.load(tmp_path / "two.obj").vertices, sf.subdivide(once, 1, creases="mesh").vertices)


@requires_data
def test_the_rook_s_crease_tags_subdivide_as_the_library_says(tmp_path, capsys):
    rook = MESHES / "rook_cage_hybrid_open.obj"
    code, _, err = run_cli(["subdivide", rook, tmp_path / "r.obj", "-l", "2"], capsys)
    assert code == 0 and "; 280 creased edges from the file's 't crease' tags" in err
    expected = sf.subdivide(sf.load(rook), 2, creases="mesh")
    assert np.array_equal(sf.load(tmp_path / "r.obj").vertices, expected.vertices)
    assert len(tags_of(tmp_path / "r.obj")[0]) == 4 * 280


def test_no_creases_ignores_the_tags_and_writes_none(creased, tmp_path, capsys):
    path, _ = creased
    code, _, err = run_cli(["subdivide", path, tmp_path / "o.obj", "-l", "2", "--no-creases"], capsys)
    assert code == 0 and "creased" not in err and "warning" not in err
    assert np.array_equal(sf.load(tmp_path / "o.obj").vertices, sf.subdivide(sf.load(path), 2).vertices)
    assert "t crease" not in (tmp_path / "o.obj").read_text()


@pytest.mark.parametrize("suffix", [".txt", ".npy"])
def test_a_crease_file_replaces_the_tags(creased, tmp_path, capsys, suffix):
    path, pairs = creased
    values = np.array([0.3, 0.6, 1.0, 0.0, 0.45])
    f = tmp_path / f"c{suffix}"
    if suffix == ".npy":
        np.save(f, np.c_[pairs, values])
    else:
        rows = zip(pairs.tolist(), values.tolist())
        f.write_text("# i j crease\n" + "".join(f"{a} {b} {v!r}\n" for (a, b), v in rows))
    code, _, err = run_cli(["subdivide", path, tmp_path / "o.obj", "-l", "2", "--creases", f], capsys)
    assert code == 0 and f"; 4 creased edges from {f}\n" in err
    expected = sf.subdivide(sf.load(path), 2, creases=(pairs, values))
    assert np.array_equal(sf.load(tmp_path / "o.obj").vertices, expected.vertices)
    assert len(tags_of(tmp_path / "o.obj")[0]) == int((expected.creases[1] > 0).sum())


def test_infinitely_sharp_box_edges_keep_a_box_and_follow_the_weld(tmp_path, capsys):
    """A triangle-soup-like OBJ (every side its own four vertices) whose box edges are tagged on both
    copies: the command welds, maps the tags, and the sides stay in their planes."""
    V, sides, _ = quad_box(k=1)
    soup_v = np.concatenate([V[q] for side in sides for q in side])
    soup_f = np.arange(24).reshape(6, 4)
    pairs = np.concatenate([np.c_[f, np.roll(f, -1)] for f in soup_f])
    path = tmp_path / "soup.obj"
    path.write_text(box_obj(soup_v, [[list(f)] for f in soup_f.tolist()], creases=(pairs, 10.0)))
    code, _, err = run_cli(["subdivide", path, tmp_path / "o.obj", "-l", "3"], capsys)
    assert code == 0 and "welded to 8 before subdividing" in err and "24 creased edges" in err
    out = sf.load(tmp_path / "o.obj").vertices
    assert flatness(out, box_sets(out)) <= EXACT * 2.5
    assert len(box_sets(out)["sides"][0]) == 81                           # 8 × 8 quads on the side x = 0
    assert run_cli(["subdivide", path, tmp_path / "n.obj", "-l", "3", "--no-creases", "-q"], capsys)[0] == 0
    round_ = sf.load(tmp_path / "n.obj").vertices
    assert len(box_sets(round_)["sides"][0]) < 81                         # rounded off the box


def test_a_format_without_creases_says_it_loses_them(creased, tmp_path, capsys):
    path, _ = creased
    out = tmp_path / "o.ply"
    code, _, err = run_cli(["subdivide", path, out, "-l", "1", "-q"], capsys)
    assert (code, err) == (0, f"shapeflow subdivide: warning: {out}: the result's 10 creased edges are not written "
                              "(PLY cannot store creases; an OBJ output keeps them as 't crease' lines)\n")


def test_other_tagged_lines_are_named_when_the_numbering_changes(creased, tmp_path, capsys):
    path, _ = creased
    path.write_text(path.read_text() + "l 1 2\n")
    code, _, err = run_cli(["subdivide", path, tmp_path / "o.obj", "-l", "1", "-q"], capsys)
    assert (code, err) == (0, "shapeflow subdivide: warning: 1 'l'/'p'/'t' lines refer to the input's vertex "
                              "numbering, which subdivision changed: not written\n")
    text = (tmp_path / "o.obj").read_text()
    assert "\nl " not in text and len(tags_of(tmp_path / "o.obj")[0]) == 10


@pytest.mark.parametrize("content,args,line", [
    ("0 1 0.5\n1 3 1.5\n", [], "--creases '{f}': line 2: crease 1.5 is outside [0, 1] (Blender's edge crease; "
                                "1 is infinitely sharp)"),
    ("0 1 0.5\n0 7 0.5\n", [], "--creases '{f}': line 2: 0 7 is not an edge of the mesh"),
    ("0 1\n", [], "--creases '{f}': line 1: expected 'i j value' (two vertex numbers and a crease), got '0 1'"),
    ("0 1 nan\n", [], "--creases '{f}': line 1: crease nan is outside [0, 1] (Blender's edge crease; "
                      "1 is infinitely sharp)"),
    ("0 1 0.5\n", ["--no-creases"], "give --creases FILE or --no-creases, not both"),
])
def test_crease_file_errors_are_one_line(creased, tmp_path, capsys, content, args, line):
    path, _ = creased
    f = tmp_path / "c.txt"
    f.write_text(content)
    out = tmp_path / "o.obj"
    code, stdout, err = run_cli(["subdivide", path, out, "--creases", f, *args], capsys)
    assert (code, stdout, err) == (2, "", f"shapeflow subdivide: error: {line.format(f=f)}\n")
    assert not out.exists()


def test_a_malformed_tag_names_the_file(tmp_path, capsys):
    path, _, _ = cube_cage(tmp_path, extra="t crease 2/1 0 7 3.0\n")
    code, _, err = run_cli(["subdivide", path, tmp_path / "o.obj"], capsys)
    assert (code, err) == (2, f"shapeflow subdivide: error: {path}: 't crease' tags: row 0 (0, 7) is not an edge "
                              "of the mesh\n")
    assert run_cli(["subdivide", path, tmp_path / "o.obj", "--no-creases", "-q"], capsys)[0] == 0


# --- render --feature-lines -----------------------------------------------------------------------

@pytest.mark.parametrize("words,lines,inputs", [
    (["render", "a.obj", "o.png"], None, ["a.obj"]),
    (["render", "a.obj", "o.png", "--feature-lines"], 30.0, ["a.obj"]),
    (["render", "a.obj", "o.png", "--feature-lines", "45"], 45.0, ["a.obj"]),
    (["render", "a.obj", "o.png", "--feature-lines", "marked"], "marked", ["a.obj"]),
    (["render", "--feature-lines", "a.obj", "b.ply", "o.png"], 30.0, ["a.obj", "b.ply"]),
    (["render", "--feature-lines", "10", "a.obj", "o.png"], 10.0, ["a.obj"]),
])
def test_render_feature_lines_grammar(words, lines, inputs):
    args = operations_parser().parse_args(words)
    assert (options_from(args).feature_lines, args.input, args.output) == (lines, inputs, "o.png")


@pytest.mark.parametrize("value,message", [
    ("200", "--feature-lines must be <= 180, got 200"),
    ("sharp", "--feature-lines must be an angle in degrees or 'marked', got 'sharp'"),
    ("inf", "--feature-lines must be finite, got inf"),
])
def test_render_feature_lines_errors(value, message):
    with pytest.raises(ParameterError) as info:
        RenderOptions(feature_lines=value)
    assert str(info.value) == message


def _lines(png) -> int:
    """Pixels of the feature lines (black) on the clay surface (no colour field): the near-black ones."""
    img = np.asarray(__import__("PIL.Image", fromlist=["Image"]).open(png).convert("RGB")).astype(int)
    return int((img.max(axis=2) < 40).sum())


def test_render_draws_the_feature_lines(creased, tmp_path, capsys):
    from shapeflow import rendering

    if not rendering.available():
        pytest.skip("rendering unavailable (the render extra and offscreen OpenGL)")
    path, _ = creased
    shots = {}
    for name, extra in (("none", []), ("angle", ["--feature-lines"]), ("marked", ["--feature-lines", "marked"])):
        png = tmp_path / f"{name}.png"
        code, _, err = run_cli(["render", path, png, "--color", "none", "--view", "iso", "--size", "240x200", "-q",
                                *extra], capsys)
        assert code == 0, err
        shots[name] = _lines(png)
    assert shots["none"] == 0 and shots["angle"] > 200 and 0 < shots["marked"] < shots["angle"]
