"""Sharp features on the command line: ``--feature-angle``, ``--sharp-edges FILE`` and
``--keep-marked-edges`` of enhance, smooth, flow, family and brush; ``info``'s counts; batch.

The meshes are built in tests/cli/hard_surface.py (a box of quads, the L-bracket with a fillet); which
vertices lie on a plane or a line comes from their construction.  With the options the flat sides
stay planar and the straight edges straight to 1e-9 of the diagonal; without them they bend.  The
command's output equals the library's call with the same sharp edges, bit for bit (OBJ writes
coordinates exactly).
"""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from conftest import run_cli
from hard_surface import EXACT, box_edge_pairs, box_obj, box_sets, flatness, l_bracket, quad_box

import shapeflow as sf
from shapeflow.batch.estimate import estimate_peak_bytes
from shapeflow.batch.operation import parse_operation, run_steps
from shapeflow.commands import BrushOptions, Collector, FamilyOptions, FlowOptions
from shapeflow.errors import ParameterError
from shapeflow.geometry.features import angle_sharp_edges

LAM = {"enhance": -20.0, "smooth": 20.0, "flow": -20.0}


def _strength(command):
    return ["--lambda", LAM[command]] if command == "flow" else ["--strength", abs(LAM[command])]


@pytest.fixture
def box(tmp_path):
    """A box of 3 × 3 quads per side as OBJ, its vertex sets, and its 36 box-edge pairs."""
    V, sides, info = quad_box()
    path = tmp_path / "box.obj"
    path.write_text(box_obj(V, sides))
    return path, info, box_edge_pairs(V, sides), V, sides


@pytest.fixture
def bracket(tmp_path):
    mesh, info = l_bracket()
    path = tmp_path / "bracket.obj"
    sf.save(path, mesh)
    return path, info, mesh


# --- flat stays flat ------------------------------------------------------------------------------

@pytest.mark.parametrize("command", ["enhance", "smooth", "flow"])
def test_the_feature_angle_keeps_a_box_of_quads_flat_and_it_bends_without(box, tmp_path, capsys, command):
    path, info, _, V, _ = box
    D = float(np.linalg.norm(V.max(0) - V.min(0)))
    plain, kept = tmp_path / "plain.obj", tmp_path / "kept.obj"
    assert run_cli([command, path, plain, *_strength(command), "-q"], capsys)[0] == 0
    code, _, err = run_cli([command, path, kept, *_strength(command), "--feature-angle", "30"], capsys)
    assert code == 0, err
    assert "36 sharp edges: 24 vertices follow their feature curves, 8 curve ends and corners stay" in err
    assert flatness(sf.load(plain).vertices, info) > 1e-3 * D        # bends
    out = sf.load(kept).vertices
    assert flatness(out, info) <= EXACT * D
    assert np.abs(out[info["corners"]] - V[info["corners"]]).max() <= EXACT * D
    assert np.array_equal(out, sf.flow(sf.load(path), LAM[command], feature_angle=30.0).vertices)


@pytest.mark.parametrize("command", ["enhance", "smooth"])
def test_the_feature_angle_keeps_the_l_bracket_machined_while_its_fillet_moves(bracket, tmp_path, capsys, command):
    path, info, mesh = bracket
    D = mesh.diagonal
    plain, kept = tmp_path / "plain.obj", tmp_path / "kept.obj"
    assert run_cli([command, path, plain, *_strength(command), "-q"], capsys)[0] == 0
    assert run_cli([command, path, kept, *_strength(command), "--feature-angle", "30", "-q"], capsys)[0] == 0
    assert flatness(sf.load(plain).vertices, info) > 1e-3 * D
    out = sf.load(kept).vertices
    assert flatness(out, info) <= EXACT * D
    assert np.abs(out[info["corners"]] - mesh.vertices[info["corners"]]).max() <= EXACT * D
    fillet = info["smooth"]
    assert np.linalg.norm(out[fillet] - mesh.vertices[fillet], axis=1).max() > 5e-3 * D


@pytest.mark.parametrize("suffix", [".txt", ".npy"])
def test_sharp_edges_from_a_file_equal_the_library_with_those_pairs(box, tmp_path, capsys, suffix):
    path, info, pairs, V, _ = box
    edges = tmp_path / f"edges{suffix}"
    if suffix == ".npy":
        np.save(edges, pairs[:, ::-1])                                     # either order of a pair
    else:
        edges.write_text("# the box's edges, 0-based\n\n" + "".join(f"{a} {b}  # edge\n" for a, b in pairs))
    out = tmp_path / "out.obj"
    code, _, err = run_cli(["smooth", path, out, "-s", "20", "--sharp-edges", edges, "-q"], capsys)
    assert (code, err) == (0, "")
    got = sf.load(out).vertices
    assert np.array_equal(got, sf.flow(sf.load(path), 20.0, sharp_edges=pairs).vertices)
    assert flatness(got, info) <= EXACT * float(np.linalg.norm(V.max(0) - V.min(0)))


def test_sharp_edges_follow_the_weld_of_a_file_split_at_its_seams(box, tmp_path, capsys):
    """A PLY whose sides have vertices of their own (split at every box edge): the pairs name the
    file's vertices; the command welds, maps them, and the sides stay flat."""
    _, _, pairs, V, sides = box
    split_v, split_f, split_pairs = [], [], []
    for quads in sides:
        ids = np.unique(np.array(quads))
        at = {int(old): len(split_v) + n for n, old in enumerate(ids)}
        split_v += list(V[ids])
        split_f += [[at[i] for i in q] for q in quads]
        side_edges = {(min(a, b), max(a, b)) for q in quads for a, b in zip(q, q[1:] + q[:1])}
        split_pairs += [(at[a], at[b]) for a, b in pairs.tolist() if (a, b) in side_edges]
    split_v = np.array(split_v)
    sf.save(tmp_path / "split.ply", sf.Mesh(split_v, split_f))
    (tmp_path / "e.txt").write_text("".join(f"{a} {b}\n" for a, b in split_pairs))
    code, _, err = run_cli(["enhance", tmp_path / "split.ply", tmp_path / "o.ply", "-s", "20",
                            "--sharp-edges", tmp_path / "e.txt"], capsys)
    assert code == 0, err
    assert "welded to 56 for the operator" in err and "36 sharp edges" in err
    out = sf.load(tmp_path / "o.ply").vertices
    assert out.shape == (96, 3)
    assert flatness(out, box_sets(split_v)) <= EXACT * 2.5
    code, _, err = run_cli(["enhance", tmp_path / "split.ply", tmp_path / "p.ply", "-s", "20", "-q"], capsys)
    assert flatness(sf.load(tmp_path / "p.ply").vertices, box_sets(split_v)) > 1e-3


# --- the file's own marked edges ------------------------------------------------------------------

@pytest.fixture(params=["groups", "tags"])
def marked(request, tmp_path):
    """The box with its edges marked by smoothing groups (one per side) or by 't crease' tags."""
    V, sides, info = quad_box()
    pairs = box_edge_pairs(V, sides)
    text = box_obj(V, sides, groups=True) if request.param == "groups" else box_obj(V, sides, creases=(pairs, 4.0))
    path = tmp_path / "marked.obj"
    path.write_text(text)
    source = "smoothing-group borders" if request.param == "groups" else "'t crease' tags"
    return path, info, source


def test_marked_edges_are_told_and_not_kept_by_default(marked, tmp_path, capsys):
    path, info, source = marked
    code, _, err = run_cli(["smooth", path, tmp_path / "o.obj", "-s", "20"], capsys)
    assert code == 0
    assert err.splitlines()[0] == (f"shapeflow smooth: {path} marks 36 sharp edges ({source}); "
                                   "pass --keep-marked-edges to keep them")
    got = sf.load(tmp_path / "o.obj").vertices
    assert np.array_equal(got, sf.flow(sf.load(path), 20.0).vertices)                  # the plain flow
    assert flatness(got, info) > 1e-3


def test_keep_marked_edges_equals_the_library_with_the_mesh_s_sharp_edges(marked, tmp_path, capsys):
    path, info, _ = marked
    code, _, err = run_cli(["smooth", path, tmp_path / "o.obj", "-s", "20", "--keep-marked-edges"], capsys)
    assert code == 0 and "marks" not in err and "36 sharp edges" in err
    got = sf.load(tmp_path / "o.obj").vertices
    assert np.array_equal(got, sf.flow(sf.load(path), 20.0, sharp_edges="mesh").vertices)
    assert flatness(got, info) <= EXACT * 2.5


def test_keep_marked_edges_says_when_the_file_marks_none_or_every_edge(box, tmp_path, capsys):
    path, _, _, V, sides = box
    code, _, err = run_cli(["smooth", path, tmp_path / "o.obj", "-s", "5", "--keep-marked-edges", "-q"], capsys)
    assert (code, err) == (0, f"shapeflow smooth: warning: --keep-marked-edges: {path} marks no sharp edge "
                              "(no smoothing-group border, no 't crease' tag)\n")
    flat_shaded = tmp_path / "flat.obj"                      # a flat-shaded export: 's off' on every face
    flat_shaded.write_text(box_obj(V, sides).replace("\nf ", "\ns off\nf ", 1))
    code, _, err = run_cli(["smooth", flat_shaded, tmp_path / "o.obj", "-s", "5", "--keep-marked-edges", "-q",
                            "--force"], capsys)
    assert (code, err) == (0, f"shapeflow smooth: warning: --keep-marked-edges: {flat_shaded} marks every edge "
                              "sharp (smoothing-group borders): no vertex off the boundary can move\n")
    assert np.array_equal(sf.load(tmp_path / "o.obj").vertices, sf.load(flat_shaded).vertices)


def test_the_options_are_a_union(box, tmp_path, capsys):
    """--feature-angle 100 finds no edge of a box; the file's pairs of one side's outline keep it."""
    path, _, pairs, V, _ = box
    top = pairs[np.isclose(V[pairs[:, 0], 2], 1.0) & np.isclose(V[pairs[:, 1], 2], 1.0)]
    np.save(tmp_path / "top.npy", top)
    run_cli(["smooth", path, tmp_path / "o.obj", "-s", "9", "--feature-angle", "100", "--sharp-edges",
             tmp_path / "top.npy", "-q"], capsys)
    m = sf.load(path)
    assert not angle_sharp_edges(m, 100.0).any()
    assert np.array_equal(sf.load(tmp_path / "o.obj").vertices, sf.flow(m, 9.0, sharp_edges=top).vertices)


# --- family, brush --------------------------------------------------------------------------------

def test_family_members_keep_the_box_flat_and_equal_the_library(box, tmp_path, capsys):
    path, info, _, V, _ = box
    code, _, err = run_cli(["family", path, tmp_path / "fam", "--lambdas", "-10,-20,5", "--feature-angle", "30",
                            "-q"], capsys)
    assert (code, err) == (0, "")
    members = sorted((tmp_path / "fam").iterdir())
    shapes = sf.family(sf.load(path), [-10.0, -20.0, 5.0], feature_angle=30.0)
    for member, expected in zip(members, shapes):
        got = sf.load(member).vertices
        assert np.array_equal(got, expected)
        assert flatness(got, info) <= EXACT * 2.5


def test_the_brush_keeps_sharp_edges_and_the_inflate_brush_refuses_them(bracket, tmp_path, capsys):
    path, info, mesh = bracket
    corner = mesh.vertices[info["smooth"][0]]               # on the fillet, next to the sharp edges of the caps
    stroke = tmp_path / "s.json"
    stroke.write_text(f'{{"lambda": -40, "radius": 0.8, "points": [{corner.tolist()}]}}')
    code, _, err = run_cli(["brush", path, tmp_path / "o.obj", "--stroke", stroke, "--feature-angle", "30", "-q"],
                           capsys)
    assert (code, err) == (0, "")
    got = sf.load(tmp_path / "o.obj").vertices
    brush = sf.Brush(mesh, lam=-40.0, radius=0.8, feature_angle=30.0, undo_limit=0)
    brush.stroke(brush.dab_centers([corner], 0.25), spacing=None)
    assert np.array_equal(got, brush.mesh.vertices)
    assert flatness(got, info) <= EXACT * mesh.diagonal and np.abs(got - mesh.vertices).max() > 1e-3
    stroke.write_text(f'{{"brush": "inflate", "radius": 0.8, "points": [{corner.tolist()}]}}')
    code, _, err = run_cli(["brush", path, tmp_path / "i.obj", "--stroke", stroke, "--keep-marked-edges"], capsys)
    assert (code, err) == (2, f"shapeflow brush: error: stroke file '{stroke}': the inflate brush moves vertices "
                              "along their normals and keeps no sharp edges; --feature-angle, --sharp-edges and "
                              "--keep-marked-edges are for the enhance brush\n")
    assert not (tmp_path / "i.obj").exists()


# --- info -----------------------------------------------------------------------------------------

def test_info_counts_sharp_marked_and_creased_edges(tmp_path, capsys):
    V, sides, _ = quad_box()
    pairs = box_edge_pairs(V, sides)
    top = pairs[np.isclose(V[pairs[:, 0], 2], 1.0) & np.isclose(V[pairs[:, 1], 2], 1.0)]      # 4 × 3 edges
    path = tmp_path / "part.obj"
    path.write_text(box_obj(V, sides, groups=True, creases=(top, np.r_[[2.5] * 6, [10.0] * 6])))
    code, out, _ = run_cli(["info", path], capsys)
    assert code == 0
    lines = [ln.strip() for ln in out.splitlines() if ln.strip().startswith(("sharp edges", "creased edges"))]
    assert lines == [
        "sharp edges     36 at 30° (--feature-angle 30 keeps them); 36 marked by the file (36 smoothing-group "
        "borders, 12 in 't crease' tags): --keep-marked-edges keeps them",
        "creased edges   12 by 't crease' tags, sharpness 2.5 .. 10: subdivide creases them (--no-creases ignores "
        "them)"]
    plain = tmp_path / "plain.obj"
    plain.write_text(box_obj(V, sides))
    code, out, _ = run_cli(["info", plain], capsys)
    assert [ln.strip() for ln in out.splitlines() if "sharp edges" in ln or "creased" in ln] == [
        "sharp edges     36 at 30° (--feature-angle 30 keeps them); none marked by the file", "creased edges   none"]


def test_info_tells_a_malformed_crease_tag_as_a_warning(box, tmp_path, capsys):
    path = box[0]
    bad = tmp_path / "bad.obj"
    bad.write_text(path.read_text() + "t crease 1/1 0 2.0\n")         # well formed, but no edge: one vertex
    code, out, _ = run_cli(["info", bad], capsys)
    assert code == 0
    assert f"  warning: {bad}: 't crease' tags: 't crease 1/1' tag 0 does not list a chain of at least 2 " \
           "vertices and one sharpness or one per edge" in out.splitlines()
    code, _, err = run_cli(["smooth", bad, tmp_path / "o.obj", "-s", "1", "--keep-marked-edges"], capsys)
    assert code == 2 and err.startswith(f"shapeflow smooth: error: {bad}: 't crease' tags: 't crease 1/1' tag 0")
    worse = tmp_path / "worse.obj"                                      # a tag its own counts contradict
    worse.write_text(path.read_text() + "t crease 3/1 0 1 2.0\n")
    code, _, err = run_cli(["info", worse], capsys)
    assert code == 2 and err == f"shapeflow info: error: {worse}: line {len(path.read_text().splitlines()) + 1}: " \
                                "'t crease 3/1' declares 4 values; the line has 3\n"


# --- messages -------------------------------------------------------------------------------------

EDGE_FILES = {
    "columns.txt": "0 1\n# a comment\n\n1 2 3\n",
    "word.txt": "0 1\n1 x\n",
    "half.txt": "0 1\n1.5 2\n",
    "negative.txt": "0 1\n-1 2\n",
    "range.txt": "0 1\n\n  # far\n0 999\n",
    "notedge.txt": "0 1\n0 55\n0 54\n",
    "empty.txt": "# nothing\n\n",
    "latin.txt": b"0 1 \xe9\n",
    "huge.txt": "0 1\n1e30 2\n",
    "bom.txt": b"\xef\xbb\xbf\n0 1\n0 55\n",
}


@pytest.mark.parametrize("name,line", [
    ("columns.txt", "--sharp-edges '{p}': line 4: expected 'i j' (two vertex numbers), got '1 2 3'"),
    ("word.txt", "--sharp-edges '{p}': line 2: expected 'i j' (two vertex numbers), got '1 x'"),
    ("half.txt", "--sharp-edges '{p}': line 2: 1.5 2 is not a pair of vertex numbers (whole numbers from 0)"),
    ("negative.txt", "--sharp-edges '{p}': line 2: -1 2 is not a pair of vertex numbers (whole numbers from 0)"),
    ("range.txt", "--sharp-edges '{p}': line 4: vertex 999 is outside the mesh's 56 vertices (0-based: 0 .. 55)"),
    ("notedge.txt", "--sharp-edges '{p}': line 2: 0 55 is not an edge of the mesh (2 such lines)"),
    ("empty.txt", "--sharp-edges '{p}' lists no edge; expected 'i j' (two vertex numbers) per line"),
    ("latin.txt", "--sharp-edges '{p}': not UTF-8 text"),
    ("huge.txt", "--sharp-edges '{p}': line 2: 1e+30 2 is not a pair of vertex numbers (whole numbers from 0)"),
    ("bom.txt", "--sharp-edges '{p}': line 3: 0 55 is not an edge of the mesh"),
    ("missing.txt", "--sharp-edges '{p}': no such file"),
    ("wide.npy", "--sharp-edges '{p}': must be a (k, 2) array of numbers, 'i j' (two vertex numbers) per row; "
                 "got shape (3, 3) of float64"),
    ("far.npy", "--sharp-edges '{p}': row 1: vertex 56 is outside the mesh's 56 vertices (0-based: 0 .. 55)"),
    ("fake.npy", "--sharp-edges '{p}': not a NumPy .npy file (its first bytes are not NumPy's)"),
    ("trunc.npy", "--sharp-edges '{p}': the header declares 1000000000000 rows, but only 0 bytes follow "
                  "(a truncated file)"),
    ("object.npy", "--sharp-edges '{p}': must be a (k, 2) array of numbers, 'i j' (two vertex numbers) per row; "
                   "got shape (1, 2) of object"),
])
def test_edge_file_errors_name_the_option_the_file_and_the_line(box, tmp_path, capsys, name, line):
    path = box[0]
    p = tmp_path / name
    if name in EDGE_FILES:
        p.write_bytes(EDGE_FILES[name] if isinstance(EDGE_FILES[name], bytes) else EDGE_FILES[name].encode())
    elif name == "wide.npy":
        np.save(p, np.zeros((3, 3)))
    elif name == "far.npy":
        np.save(p, np.array([[0, 1], [0, 56]]))
    elif name == "fake.npy":
        p.write_text("0 1\n")
    elif name == "trunc.npy":                    # a hostile header: 16 TB declared, nothing after it
        with open(p, "wb") as f:
            np.lib.format.write_array_header_1_0(f, {"descr": "<f8", "fortran_order": False, "shape": (10**12, 2)})
    elif name == "object.npy":
        np.save(p, np.array([[0, None]], dtype=object), allow_pickle=True)
    out = tmp_path / "out.obj"
    code, stdout, err = run_cli(["smooth", path, out, "-s", "5", "--sharp-edges", p], capsys)
    assert (code, stdout, err) == (2, "", f"shapeflow smooth: error: {line.format(p=p)}\n")
    assert not out.exists()


@pytest.mark.parametrize("args,line", [
    (["--feature-angle", "181"], "--feature-angle must be <= 180, got 181"),
    (["--feature-angle", "-1"], "--feature-angle must be >= 0, got -1"),
    (["--feature-angle", "nan"], "--feature-angle must be finite, got nan"),
    (["--feature-angle", "sharp"], "--feature-angle must be a number, got 'sharp' (see 'shapeflow enhance --help')"),
    (["--sharp-edges", "mesh"], "--sharp-edges 'mesh': no such file (the input's own marked edges: "
                                "--keep-marked-edges)"),
    (["--keep-marked"], None),
])
def test_feature_option_errors_are_one_line(box, tmp_path, capsys, args, line):
    out = tmp_path / "out.obj"
    code, stdout, err = run_cli(["enhance", box[0], out, "-s", "5", *args, "-q"], capsys)
    if line is None:                                   # a unique prefix of --keep-marked-edges
        assert code == 0
        return
    assert (code, stdout, err) == (2, "", f"shapeflow enhance: error: {line}\n")
    assert not out.exists()


# --- the options from Python and in a batch -------------------------------------------------------

def test_the_edge_file_is_read_with_the_options_and_ships_with_them(box, tmp_path):
    path, _, pairs, _, _ = box
    np.save(tmp_path / "e.npy", pairs)
    o = FlowOptions(command="smooth", strength=20.0, sharp_edges=str(tmp_path / "e.npy"), quiet=True)
    (tmp_path / "e.npy").unlink()                             # read already: a worker needs no file
    again = pickle.loads(pickle.dumps(o))
    from shapeflow.commands import run

    run(again, str(path), str(tmp_path / "o.obj"))
    expected = sf.flow(sf.load(path), 20.0, sharp_edges=pairs)
    assert np.array_equal(sf.load(tmp_path / "o.obj").vertices, expected.vertices)
    with pytest.raises(ParameterError, match=r"^--feature-angle must be <= 180, got 200$"):
        FamilyOptions(lambdas="-5", feature_angle=200.0)
    with pytest.raises(ParameterError, match=r"^--sharp-edges 'nope.txt': no such file$"):
        BrushOptions(stroke="s.json", sharp_edges="nope.txt")


def test_a_batch_shares_the_options_and_its_memory_estimate_is_unchanged(box, tmp_path):
    path, info, pairs, _, _ = box
    np.savetxt(tmp_path / "e.txt", pairs, fmt="%d")
    op = parse_operation(f"smooth -s 20 --feature-angle 30 --sharp-edges {tmp_path / 'e.txt'} --keep-marked-edges "
                         "--then subdivide -l 1 --no-creases")
    smooth, sub = op.options
    assert (smooth.feature_angle, smooth.keep_marked_edges, sub.no_creases) == (30.0, True, True)
    assert np.array_equal(smooth.sharp_file.pairs, pairs)
    plain = parse_operation("smooth -s 20 --then subdivide -l 1")
    for n in (1_000, 5_000_000):
        assert estimate_peak_bytes(n, op.options) == estimate_peak_bytes(n, plain.options)
    report = Collector()
    run_steps(op, str(path), str(tmp_path / "b.obj"), str(tmp_path), report)
    expected = sf.subdivide(sf.flow(sf.load(path), 20.0, feature_angle=30.0, sharp_edges=pairs), 1)
    assert np.array_equal(sf.load(tmp_path / "b.obj").vertices, expected.vertices)
    assert any("--keep-marked-edges" in m and "marks no sharp edge" in m for m in report.messages)
    with pytest.raises(ParameterError) as exc:
        parse_operation("enhance -s 5 --sharp-edges missing.txt")
    assert str(exc.value) == ("the operation (enhance -s 5 --sharp-edges missing.txt): --sharp-edges 'missing.txt': "
                              "no such file")
