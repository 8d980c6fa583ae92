"""The Blender extension, built and installed into real Blender (``bpy``).

How it runs (bpy 5.0.1 as a Python module, headless):

1. ``python -m shapeflow.blender build --output DIR --platform linux-x64``
   builds the extension zip (the scipy wheel comes from pip's cache or PyPI);
   Blender's own validator (``bl_pkg/cli/blender_ext.py validate``) checks it.
2. A first ``bpy`` process, with ``BLENDER_USER_RESOURCES`` pointing at a
   temporary directory, installs the zip exactly as *Install from Disk* does:
   ``bpy.ops.extensions.package_install_files(filepath=..., repo="user_default",
   enable_on_install=True)``.  Blender unpacks the add-on to
   ``extensions/user_default/shapeflow`` and the wheels to
   ``extensions/.local/lib/python3.11/site-packages``.
3. A second ``bpy`` process (as after restarting Blender) puts that
   site-packages first on ``sys.path`` — so the *bundled* shapeflow and scipy
   are the ones used, not the ones of this checkout — enables the add-on with
   ``bpy.ops.preferences.addon_enable(module="bl_ext.user_default.shapeflow")``
   and runs every scenario (``blender_driver.py``, run as a script).  It
   saves Blender's inputs and results; the tests below compare them with the
   library (this checkout) and with Blender's own modifiers.

Skipped, with the reason, when ``bpy`` is not installed (``pip install
bpy==5.0.1``, Python 3.11 only).  Set ``SHAPEFLOW_UPDATE_DOCS_IMAGES=1`` to copy
the screenshot rendered here (Workbench) to ``docs/img/blender_family.png``.
"""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from blender_driver import COMPAT_CASES, FLOW_CASES

ROOT = Path(__file__).resolve().parents[2]
DRIVER = Path(__file__).resolve().with_name("blender_driver.py")
HAVE_BPY = importlib.util.find_spec("bpy") is not None
needs_bpy = pytest.mark.skipif(
    not HAVE_BPY, reason="Blender's bpy module is not installed (pip install bpy==5.0.1; Python 3.11 only)")
DOC_IMAGE = ROOT / "docs" / "img" / "blender_family.png"

FLOW_KEYWORDS = ["lam", "lam_border", "iterations", "normalized", "preserve_volume", "axes", "vertex_group",
                 "invert_weights", "scheme", "update"]


def _build(out: Path, *extra) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "shapeflow.blender", "build", "--output", str(out), *extra],
                          capture_output=True, text=True, timeout=900)


@pytest.fixture(scope="module")
def extension_zip(tmp_path_factory):
    out = tmp_path_factory.mktemp("dist")
    proc = _build(out, "--platform", "linux-x64")
    assert proc.returncode == 0, proc.stderr
    path = Path(proc.stdout.strip().splitlines()[-1])
    assert path.is_file()
    return path


def _run_driver(mode, *args, env, timeout):
    proc = subprocess.run([sys.executable, str(DRIVER), mode, *map(str, args)], env=env,
                          capture_output=True, text=True, timeout=timeout, cwd=str(ROOT))
    assert proc.returncode == 0, f"bpy driver '{mode}' failed:\n{proc.stdout[-4000:]}\n{proc.stderr[-6000:]}"
    return proc


class _Run:
    def __init__(self, out: Path):
        self.install = json.loads((out / "install.json").read_text())
        self.results = json.loads((out / "results.json").read_text())
        self.arrays = dict(np.load(out / "arrays.npz"))
        self.out = out

    def __getitem__(self, name):
        r = self.results[name]
        assert r["ok"], f"Blender scenario '{name}' failed:\n{r.get('error')}"
        return r


@pytest.fixture(scope="module")
def blender(extension_zip, tmp_path_factory):
    if not HAVE_BPY:
        pytest.skip("Blender's bpy module is not installed (pip install bpy==5.0.1; Python 3.11 only)")
    out = tmp_path_factory.mktemp("blender")
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(out / "user"), PYTHONDONTWRITEBYTECODE="1")
    _run_driver("install", extension_zip, out, env=env, timeout=600)
    _run_driver("run", out, env=env, timeout=1200)
    return _Run(out)


def _lib():
    import shapeflow as sf

    return sf


def _diag(V):
    return float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))


def _flow_kwargs(props, weights):
    return dict(lam_border=props.get("lam_border", 0.0), iterations=props.get("iterations", 1),
                normalized=props.get("normalized", True), preserve_volume=props.get("preserve_volume", False),
                axes=props.get("axes", (True, True, True)), weights=weights,
                invert_weights=props.get("invert_weights", False),
                update="fixed" if props.get("scheme") == "BLENDER" else props.get("update", "FIXED").lower(),
                compat="blender" if props.get("scheme") == "BLENDER" else None)


# --- without bpy --------------------------------------------------------------------------------

def test_library_never_imports_bpy():
    code = ("import sys; sys.modules['bpy'] = None\n"
            "import shapeflow as sf, shapeflow.blender, shapeflow.blender.build, shapeflow.blender.__main__\n"
            "m = sf.Mesh([[0,0,0],[1,0,0],[1,1,0],[0,1,0.3]], [[0,1,2,3]])\n"
            "sf.flow(m, -1.0); sf.subdivide(m, 1); sf.family(m, [0.0, -1.0])\n"
            "assert sys.modules['bpy'] is None\n")
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)


def test_shapeflow_wheel(tmp_path):
    import shapeflow
    from shapeflow.blender.build import build_shapeflow_wheel

    p1 = build_shapeflow_wheel(tmp_path / "a")
    p2 = build_shapeflow_wheel(tmp_path / "b")
    assert p1.name == f"shapeflow-{shapeflow.__version__}-py3-none-any.whl"
    assert p1.read_bytes() == p2.read_bytes()  # reproducible
    with zipfile.ZipFile(p1) as zf:
        names = zf.namelist()
        assert "shapeflow/__init__.py" in names and "shapeflow/flow/solver.py" in names
        assert any(n.startswith("shapeflow/data/") for n in names)
        assert not any(n.startswith("shapeflow/blender") or "__pycache__" in n for n in names)
        meta = zf.read(f"shapeflow-{shapeflow.__version__}.dist-info/METADATA").decode()
        assert "Requires-Dist: numpy" in meta and "Requires-Dist: scipy" in meta and "extra ==" not in meta
        import base64
        import csv
        import hashlib
        import io

        rows = list(csv.reader(io.StringIO(zf.read(f"shapeflow-{shapeflow.__version__}.dist-info/RECORD").decode())))
        assert {r[0] for r in rows} == set(names)
        for name, digest, size in rows:
            if digest:
                data = zf.read(name)
                want = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
                assert digest == f"sha256={want}" and int(size) == len(data)


def test_manifest_template_and_cli_errors(tmp_path):
    from shapeflow.blender.build import render_manifest

    text = render_manifest("1.2.3", ["linux-x64"], ["a.whl", "b.whl"])
    import tomllib

    m = tomllib.loads(text)
    assert m["schema_version"] == "1.0.0" and m["id"] == "shapeflow" and m["type"] == "add-on"
    assert m["version"] == "1.2.3" and m["blender_version_min"] == "4.2.0"
    assert m["platforms"] == ["linux-x64"] and m["wheels"] == ["./wheels/a.whl", "./wheels/b.whl"]
    assert len(m["tagline"]) <= 64 and not m["tagline"].endswith(".")
    proc = _build(tmp_path, "--platform", "amiga-68k")
    assert proc.returncode == 2 and "invalid choice" in proc.stderr
    empty = tmp_path / "no-wheels"
    empty.mkdir()
    proc = _build(tmp_path / "o", "--platform", "windows-x64", "--offline", "--cache-dir", str(empty))
    assert proc.returncode == 2 and "no scipy" in proc.stderr and "--offline" in proc.stderr


# --- the built zip -----------------------------------------------------------------------------------

def test_zip_layout_and_blender_validator(extension_zip):
    with zipfile.ZipFile(extension_zip) as zf:
        names = zf.namelist()
        import tomllib

        manifest = tomllib.loads(zf.read("blender_manifest.toml").decode())
    addon = {"blender_manifest.toml", "__init__.py", "bridge.py", "operators.py", "brush_op.py", "panel.py"}
    assert addon <= set(names)
    wheels = [n for n in names if n.startswith("wheels/")]
    assert sorted("./" + w for w in wheels) == sorted(manifest["wheels"])
    assert any(w.startswith("wheels/scipy-") and "manylinux" in w and "cp311" in w for w in wheels)
    assert any(w.startswith("wheels/shapeflow-") for w in wheels)
    assert not any("numpy" in w for w in wheels)  # Blender's own numpy is used
    assert manifest["platforms"] == ["linux-x64"]
    if not HAVE_BPY:
        pytest.skip("Blender's validator ships with bpy")
    spec = importlib.util.find_spec("bpy")
    base = Path(spec.submodule_search_locations[0])
    cli = next(base.glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
    tags = next(base.glob("*/scripts/modules/_bpy_internal/extensions/tags.py"))
    proc = subprocess.run([sys.executable, str(cli), "validate", "--valid-tags", str(tags), str(extension_zip)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and "Success" in proc.stdout, proc.stdout + proc.stderr


# --- inside Blender -----------------------------------------------------------------------------------

@needs_bpy
def test_install_from_disk(blender):
    inst = blender.install
    assert inst["result"] == ["FINISHED"] and inst["enabled"] and all(inst["operators"])
    assert {"__init__.py", "blender_manifest.toml", "operators.py"} <= set(inst["addon_files"])
    assert any(n.startswith("scipy") for n in inst["site_packages"])
    assert "shapeflow" in inst["site_packages"]


@needs_bpy
def test_bundled_wheels_are_used(blender):
    env = blender["env"]
    assert env["enable"] == ["FINISHED"]
    ext = env["extensions"]
    assert env["shapeflow_file"].startswith(ext) and env["scipy_file"].startswith(ext)
    from shapeflow.blender.build import SCIPY_VERSION

    assert env["scipy"] == SCIPY_VERSION


@needs_bpy
def test_operator_ids_properties_and_undo(blender):
    env = blender["env"]
    assert env["idnames"] == ["object.shapeflow_flow"]
    for name in ("flow", "family", "subdivide", "brush"):
        assert {"REGISTER", "UNDO"} <= set(env["options"][name]), name
    for kw in FLOW_KEYWORDS:
        assert kw in env["props"]["flow"], kw
    for kw in FLOW_KEYWORDS[1:]:
        assert kw in env["props"]["family"] and kw in env["props"]["subdivide"], kw
    assert {"lam_start", "lam_end", "count"} <= set(env["props"]["family"])
    assert {"levels", "boundary", "weights_rule", "lam"} <= set(env["props"]["subdivide"])
    assert {"lam", "radius", "falloff", "spacing", "stroke", "stroke_method"} <= set(env["props"]["brush"])
    assert env["scheme_items"] == ["PAPER", "BLENDER"] and env["update_items"] == ["FIXED", "RECOMPUTE"]
    assert env["panel"] == ["VIEW_3D", "UI", "ShapeFlow"]


@needs_bpy
@pytest.mark.parametrize("i", range(len(FLOW_CASES)))
def test_flow_matches_library(blender, i):
    blender["flow"]
    sf = _lib()
    a = blender.arrays
    kind, props, weights = FLOW_CASES[i]
    V, fs, fi = a[f"flow{i}_V"], a[f"flow{i}_fs"], a[f"flow{i}_fi"]
    w = a[f"flow{i}_w"] if weights else None
    ref = sf.flow(sf.Mesh.from_csr(V, fs, fi), props["lam"], **_flow_kwargs(props, w)).vertices
    out = a[f"flow{i}_out"]
    dev = float(np.abs(out - ref).max()) / _diag(V)
    moved = float(np.abs(out - V).max()) / _diag(V)
    assert moved > 1e-3, (kind, props, moved)
    assert dev <= 1e-6, (kind, props, dev)


@needs_bpy
@pytest.mark.parametrize("i", range(len(COMPAT_CASES)))
def test_blender_scheme_matches_laplacian_smooth_modifier(blender, i):
    blender["compat"]
    a = blender.arrays
    op, mod, V = a[f"compat{i}_operator"], a[f"compat{i}_modifier"], a[f"compat{i}_V"]
    assert float(np.abs(mod - V).max()) / _diag(V) > 1e-4  # the modifier did something
    dev = float(np.abs(op - mod).max()) / _diag(mod)
    assert dev <= 1e-5, (COMPAT_CASES[i], dev)


@needs_bpy
def test_edit_mode_moves_only_selected(blender):
    info = blender["edit"]
    sf = _lib()
    a = {k[5:]: v for k, v in blender.arrays.items() if k.startswith("edit_")}
    assert info["results"][:2] == [["FINISHED"], ["FINISHED"]] and info["mode_after"] == "EDIT_MESH"
    assert info["results"][2] == ["CANCELLED"]  # nothing selected
    V, sel = a["V"], a["sel"].astype(bool)
    assert 0 < sel.sum() < len(sel)
    mesh = sf.Mesh.from_csr(V, a["fs"], a["fi"])
    # first run: weights = selection mask
    assert np.array_equal(a["out1"][~sel], V[~sel])  # bit-identical
    ref = sf.flow(mesh, -20.0, weights=sel.astype(float)).vertices
    assert float(np.abs(a["out1"] - ref).max()) / _diag(V) <= 1e-6
    assert float(np.abs(a["out1"][sel] - V[sel]).max()) > 1e-3
    # second run (from the first result): vertex group × selection, volume kept on the selected part only
    assert np.array_equal(a["out2"][~sel], a["out1"][~sel])
    ref2 = np.array(sf.flow(mesh.with_vertices(a["out1"]), -20.0, weights=a["w"] * sel,
                            preserve_volume=True).vertices)
    ref2[~sel] = a["out1"][~sel]
    assert float(np.abs(a["out2"] - ref2).max()) / _diag(V) <= 1e-6
    assert np.array_equal(a["out3"], a["out2"])  # nothing selected: nothing moved


@needs_bpy
def test_shape_keys_edit_the_active_key(blender):
    info = blender["shape_keys"]
    sf = _lib()
    a = {k[3:]: v for k, v in blender.arrays.items() if k.startswith("sk_")}
    assert info["result"] == ["FINISHED"]
    ref = sf.flow(sf.Mesh.from_csr(a["K"], a["fs"], a["fi"]), -10.0).vertices
    assert float(np.abs(a["key_after"] - ref).max()) / _diag(ref) <= 1e-6  # survived an Edit Mode round trip
    assert np.array_equal(a["basis_after"], a["basis"])  # the Basis is untouched


@needs_bpy
def test_vertex_group_reader(blender):
    info = blender["groups"]
    assert info["dev"] <= 1e-7
    assert not any(n.startswith(".shapeflow") for n in info["left"])  # temporary data removed


@needs_bpy
def test_family(blender):
    info = blender["family"]
    sf = _lib()
    a = blender.arrays
    lams = np.linspace(0.0, -40.0, 5)
    assert np.allclose(info["lams"], lams)
    V = a["family_V"]
    mesh = sf.Mesh.from_csr(V, a["family_fs"], a["family_fi"])
    shapes = sf.family(mesh, lams)
    for k, lam in enumerate(lams):
        out = a[f"family_member{k}"]
        assert float(np.abs(out - shapes[k]).max()) / _diag(V) <= 1e-6
        single = sf.flow(mesh, lam).vertices
        assert float(np.abs(out - single).max()) / _diag(V) <= 1e-4  # family = flow per λ (CG tolerance)
    assert np.array_equal(a["family_member0"], V)  # λ = 0
    # side by side, left to right, no overlaps; a colour ramp from the first to the last colour
    bbox = np.array(info["bbox"])
    assert np.all(bbox[1:, 0] > bbox[:-1, 1])
    cols = np.array(info["colors"])
    assert np.allclose(cols[0], (0.12, 0.36, 0.85, 1.0), atol=1e-6)
    assert np.allclose(cols[-1], (0.95, 0.42, 0.10, 1.0), atol=1e-6)
    assert np.all(np.diff(cols[:, 0]) > 0) and np.all(np.diff(cols[:, 2]) < 0)
    assert all(len(m) == 1 for m in info["materials"]) and len({m[0] for m in info["materials"]}) == 5
    assert len(set(info["collections"])) == 1


@needs_bpy
def test_subdivide_and_enhance(blender):
    info = blender["subdivide"]
    sf = _lib()
    a = {k[4:]: v for k, v in blender.arrays.items() if k.startswith("sub_")}
    assert info["result"] == ["FINISHED"] and info["result1"] == ["FINISHED"]
    V = a["V"]
    coarse = sf.Mesh.from_csr(V, a["fs"], a["fi"]).with_weights(a["w"])
    fine = sf.subdivide(coarse, 2, boundary="smooth", weights_rule="smooth")
    ref = sf.flow(fine, -30.0, weights="weight").vertices
    assert np.array_equal(a["fs2"], fine.face_sizes) and np.array_equal(a["fi2"], fine.face_indices)
    assert float(np.abs(a["out"] - ref).max()) / _diag(V) <= 1e-6
    # vertex groups carried: the enhancement group by the chosen rule, the others likewise
    assert float(np.abs(a["w2"] - fine.weights).max()) <= 1e-6
    S, _ = sf.subdivision_matrix(coarse, levels=2, scheme="catmull-clark")
    assert float(np.abs(a["other2"] - S @ a["other"]).max()) <= 1e-6
    assert set(info["groups"]) == {"w", "other"}
    # materials and smooth flags: every face's 4^levels... quads inherit them
    reps = np.repeat(np.arange(len(a["fs"])), a["fs"])        # level 1: one quad per corner
    reps = np.repeat(reps, 4)                                   # level 2: four per quad
    assert np.array_equal(a["mi2"], a["mi"][reps]) and np.array_equal(a["sm2"], a["smooth"][reps])
    assert info["materials"] == ["red", "blue"]
    # UVs: linear subdivision of the corner values (checked on the first level's structure)
    uv, fs = a["uv"], a["fs"]
    start = np.r_[0, np.cumsum(fs)[:-1]]
    face = np.repeat(np.arange(len(fs)), fs)
    k = np.arange(len(uv))
    pos = k - start[face]
    nxt = np.where(pos + 1 == fs[face], start[face], k + 1)
    prv = np.where(pos == 0, start[face] + fs[face] - 1, k - 1)
    centre = np.array([uv[s:s + n].mean(axis=0) for s, n in zip(start, fs)])
    lvl1 = np.stack([uv, (uv + uv[nxt]) / 2, centre[face], (uv[prv] + uv) / 2], axis=1).reshape(-1, 2)
    lvl2 = a["uv2"].reshape(len(lvl1) // 4, 4, 4, 2)  # level-1 quad q -> its 4 level-2 quads
    assert np.allclose(lvl2[:, :, 0].reshape(-1, 2), lvl1, atol=1e-6)  # level-2 quads start at level-1 corners
    # the old mesh was replaced, not left behind
    assert not any(n.endswith(".001") for n in info["mesh_names"])
    # one level without the flow = Blender's Subdivision Surface modifier (Catmull–Clark, no limit surface)
    from scipy.spatial import cKDTree

    blend, ours = a["blender"], a["level1"]
    assert blend.shape == ours.shape
    assert float(cKDTree(blend).query(ours)[0].max()) / _diag(blend) <= 1e-6


@needs_bpy
def test_brush_scripted_stroke_matches_library(blender):
    info = blender["brush"]
    sf = _lib()
    a = blender.arrays
    for tag, scale in (("plain", 1.0), ("moved", 2.0)):
        assert info[tag] == ["FINISHED"]
        V = a[f"brush_{tag}_V"]
        mesh = sf.Mesh.from_csr(V, a[f"brush_{tag}_fs"], a[f"brush_{tag}_fi"])
        b = sf.Brush(mesh, lam=-40.0, radius=0.5, falloff="smooth")  # world radius 0.5·scale in object space
        b.stroke(a[f"brush_{tag}_local"], spacing=0.25)
        out = a[f"brush_{tag}_out"]
        assert float(np.abs(out - V).max()) > 1e-3
        assert float(np.abs(out - b.vertices).max()) / _diag(V) <= 1e-6, tag


@needs_bpy
def test_brush_session_drag_dot_space_and_cancel(blender):
    info = blender["brush"]
    sf = _lib()
    a = {k[8:]: v for k, v in blender.arrays.items() if k.startswith("session_")}
    V, fs, fi = a["V"], a["fs"], a["fi"]
    diag = _diag(V)
    ref = sf.Brush(sf.Mesh.from_csr(V, fs, fi), lam=-40.0, radius=0.5, falloff="smooth")
    # Drag Dot: the preview follows the mouse; on release only the dab under the mouse is applied
    ref.preview([1.0, 0.0, 0.0])
    assert float(np.abs(a["preview_a"] - ref.preview_mesh.vertices).max()) / diag <= 1e-6
    ref.preview([0.8, 0.6, 0.0])
    assert float(np.abs(a["preview_b"] - ref.preview_mesh.vertices).max()) / diag <= 1e-6
    ref.commit()
    assert np.array_equal(a["preview_b"], a["committed"])
    assert float(np.abs(a["committed"] - ref.vertices).max()) / diag <= 1e-6
    assert float(np.abs(a["preview_a"] - a["preview_b"]).max()) > 1e-3
    assert len(info["dabs"]) == 1 and np.allclose(info["dabs"][0][0], [0.8, 0.6, 0.0])
    # Space: a dab at the press point, then every 0.25 × radius along the drag, with −λ (Ctrl held)
    d = a["space_dabs"]
    assert len(d) == 1 + int(np.linalg.norm([0.2, 0.6, 0.0]) / 0.125 + 1e-9)
    assert np.allclose(d[0], [1.0, 0.0, 0.0]) and np.allclose(np.linalg.norm(np.diff(d, axis=0), axis=1), 0.125)
    assert all(info["space_inverted"])
    ref2 = sf.Brush(sf.Mesh.from_csr(a["committed"], fs, fi), lam=40.0, radius=0.5, falloff="smooth")
    for c in d:
        ref2.dab(c)
    assert float(np.abs(a["space"] - ref2.vertices).max()) / diag <= 1e-6
    # Esc / right click: the mesh the session started from
    assert np.array_equal(a["cancelled"], a["committed"])
    # ray cast and radius circle
    hit, normal = np.array(info["hit"][0]), np.array(info["hit"][1])
    assert abs(hit[1] + 1.0) < 0.05 and abs(hit[0]) < 0.05 and abs(hit[2] - 1.0) < 0.05
    assert normal[1] < -0.9 and info["miss"]
    assert np.allclose(info["circle_radius"], 0.5) and info["circle_z"] < 1e-12 and info["circle_closed"]


@needs_bpy
def test_brush_modal_events(blender):
    info = blender["modal"]
    sf = _lib()
    a = {k[6:]: v for k, v in blender.arrays.items() if k.startswith("modal_")}
    log = info["log"]
    # hover: a ray cast from the stand-in view hits the unit sphere in front (y < 0)
    hover = np.array(log[0][-1])
    assert log[0][0] == "RUNNING_MODAL" and np.allclose(hover[[0, 2]], [0.3, 0.2], atol=0.02) and hover[1] < -0.8
    assert [e[0] for e in log[1:5]] == ["RUNNING_MODAL"] * 4
    assert log[5] == ["PASS_THROUGH"] and log[6] == ["PASS_THROUGH"]  # outside the view; navigation
    assert log[-1] == ["FINISHED"] and info["header"] == [None, None]  # help text cleared: finish, then Esc
    assert abs(info["radius"] - 0.55) < 1e-9 and info["invert"] == "01"
    # what was recorded and applied: the Drag Dot dab at the release point, then one with −λ (Ctrl)
    stroke = a["stroke"]
    assert len(stroke) == 2 and np.allclose(stroke[0][[0, 2]], [0.5, 0.1], atol=0.02)
    V = a["V"]
    b = sf.Brush(sf.Mesh.from_csr(V, a["fs"], a["fi"]), lam=-40.0, radius=0.5, falloff="smooth")
    b.dab(stroke[0])
    b.radius, b.lam = 0.55, 40.0
    b.dab(stroke[1])
    assert float(np.abs(a["after"] - b.vertices).max()) / _diag(V) <= 1e-6
    assert float(np.abs(a["replay"] - a["after"]).max()) / _diag(V) <= 1e-6 and info["replay"] == ["FINISHED"]
    assert info["log2"][-1] == ["CANCELLED"] and info["cancelled_equal"]


@needs_bpy
def test_panel_menus_and_redo_panels(blender):
    info = blender["ui"]
    ops = ["object.shapeflow_flow", "object.shapeflow_family", "object.shapeflow_subdivide_enhance",
           "object.shapeflow_brush"]
    assert info["panel_object"] == ops and info["menu"] == ops
    assert info["panel_edit"] == ["object.shapeflow_flow"]
    assert set(FLOW_KEYWORDS) <= set(info["redo_flow"])
    assert set(FLOW_KEYWORDS[1:]) | {"lam_start", "lam_end", "count", "gap"} <= set(info["redo_family"])
    assert set(FLOW_KEYWORDS) | {"levels", "boundary", "weights_rule"} <= set(info["redo_subdivide"])
    assert {"lam", "radius", "falloff", "stroke_method", "spacing", "vertex_group"} <= set(info["redo_brush"])


@needs_bpy
def test_render_screenshot(blender):
    info = blender["render"]
    path = Path(info["path"])
    assert path.is_file() and info["size"][0] == 1200 and 200 < info["size"][1] < 400
    assert info["std"] > 0.05 and info["colourful"] > 0.05  # not blank: coloured shapes on white
    if os.environ.get("SHAPEFLOW_UPDATE_DOCS_IMAGES"):
        DOC_IMAGE.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(path, DOC_IMAGE)


@needs_bpy
def test_disable_unregisters_everything(blender):
    info = blender["disable"]
    assert info["result"] == ["FINISHED"] and not any(info["left"])

