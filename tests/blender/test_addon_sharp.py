"""Keep Sharp Edges in the Blender extension, in real Blender (``bpy``).

The extension is built and installed as in ``test_blender_addon.py`` (its fixture and its
install driver are reused); a second ``bpy`` process runs this file's scenarios
(``_drive_sharp``) with the bundled shapeflow and scipy first on ``sys.path``, and saves
Blender's inputs and results.  The tests compare them with geometry (the sides of a cube and
the caps of a can stay flat) and with the library (this checkout).
``test_addon_creases.py`` runs the creased subdivision the same way (``run_in_blender``).
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import blender_driver as drv
import numpy as np
import pytest
import test_blender_addon as base
from test_blender_addon import extension_zip  # noqa: F401 - the built zip, a fixture

needs_bpy = base.needs_bpy
LAM = -10.0
#: (name, operator properties) of the Enhance runs on the marked cube; "marks" says how its edges are marked
CUBE_RUNS = [
    ("plain", "sharp", {}),
    ("marked_sharp", "sharp", dict(keep_sharp=True, sharp_by_angle=False)),
    ("marked_crease", "crease", dict(keep_sharp=True, sharp_by_angle=False)),
    ("angle", "none", dict(keep_sharp=True, sharp_marked=False, sharp_angle=math.radians(30.0))),
    ("nothing_marked", "none", dict(keep_sharp=True, sharp_by_angle=False)),
    ("both", "sharp", dict(keep_sharp=True, sharp_angle=math.radians(30.0), scheme="BLENDER", lam=-0.9,
                           iterations=2)),
]


# ==========================================================================
# the Blender side (python tests/blender/test_addon_sharp.py run OUT)
# ==========================================================================

def grid_cube(k: int = 4):
    """The cube [-1, 1]³, each side a k × k grid of quads (outward), the +x side and half the +y
    side cut into triangles, the vertices moved at random within their side or edge: vertices, faces
    (lists) and the vertex pairs of its 12 edges' segments."""
    t = np.linspace(-1.0, 1.0, k + 1)
    P = np.array([[x, y, z] for x in t for y in t for z in t])
    on = (np.abs(P) == 1.0).sum(axis=1)
    keep = np.flatnonzero(on > 0)
    index = -np.ones(len(P), dtype=np.int64)
    index[keep] = np.arange(keep.size)
    lat = index.reshape(k + 1, k + 1, k + 1)
    faces = []
    for axis in range(3):
        for side in (0, k):
            a, b = [d for d in range(3) if d != axis]
            for i in range(k):
                for j in range(k):
                    q = []
                    for di, dj in ((0, 0), (1, 0), (1, 1), (0, 1)):
                        ijk = [0, 0, 0]
                        ijk[axis], ijk[a], ijk[b] = side, i + di, j + dj
                        q.append(int(lat[tuple(ijk)]))
                    normal = np.zeros(3)
                    normal[axis] = 1.0 if side == k else -1.0
                    p = P[keep][q]
                    if np.cross(p[1] - p[0], p[2] - p[0]) @ normal < 0:
                        q = q[::-1]
                    if axis == 0 and side == k or axis == 1 and side == k and i < k // 2:
                        faces += [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]
                    else:
                        faces.append(q)
    V = P[keep]
    # move the vertices inside the sides and along the edges within their side or edge (multiples of
    # 1/64: exact in float32), so that the flow has something to even out in the plane
    rng = np.random.default_rng(5)
    free = np.abs(V) != 1.0
    V = V + np.where(free, np.round(rng.uniform(-0.15, 0.15, V.shape) * 64.0) / 64.0, 0.0)
    pairs = {tuple(sorted((f[m], f[(m + 1) % len(f)]))) for f in faces for m in range(len(f))}
    pairs = np.array(sorted(pairs))
    edge = ((np.abs(V[pairs[:, 0]]) == 1.0) & (np.abs(V[pairs[:, 1]]) == 1.0)).sum(axis=1) >= 2
    return V, faces, pairs[edge]


def can(n: int = 16, rings: int = 3):
    """A closed cylinder (radius 1, z in [-1, 1]): quad side with rings - 1 inner rings, caps of a quad ring
    and a triangle fan: vertices, faces and the vertex pairs of the two rims (the cap outlines)."""
    a = 2.0 * np.pi * np.arange(n) / n
    circle = np.c_[np.cos(a), np.sin(a)]
    side = [np.c_[circle, np.full(n, z)] for z in np.linspace(-1.0, 1.0, rings + 1)]
    V = np.vstack(side + [np.c_[0.5 * circle, np.full(n, z)] for z in (-1.0, 1.0)] + [[0, 0, -1.0], [0, 0, 1.0]])
    ring = lambda k: k * n + np.arange(n)        # noqa: E731 - ring k's vertex ids
    nxt = lambda r: np.roll(r, -1)               # noqa: E731
    faces = []
    for k in range(rings):                       # outward: counter-clockwise seen from outside
        lo, hi = ring(k), ring(k + 1)
        faces += np.c_[lo, nxt(lo), nxt(hi), hi].tolist()
    bottom, top, inner_b, inner_t = ring(0), ring(rings), ring(rings + 1), ring(rings + 2)
    cb, ct = len(V) - 2, len(V) - 1
    faces += np.c_[bottom, inner_b, nxt(inner_b), nxt(bottom)].tolist()
    faces += np.c_[top, nxt(top), nxt(inner_t), inner_t].tolist()
    faces += np.c_[inner_b, np.full(n, cb), nxt(inner_b)].tolist()
    faces += np.c_[inner_t, nxt(inner_t), np.full(n, ct)].tolist()
    rims = np.vstack([np.c_[bottom, nxt(bottom)], np.c_[top, nxt(top)]])
    return V.astype(np.float32).astype(np.float64), faces, rims   # as Blender stores them


def _mesh_object(bpy, name, V, faces):
    me = bpy.data.meshes.new(name)
    me.from_pydata([tuple(map(float, v)) for v in V], [], [list(map(int, f)) for f in faces])
    me.update()
    bad = me.attributes.get(".select_edge")   # Blender 5.0.1 types it INT32_2D here: edge selection crashes
    if bad is not None and bad.data_type != "BOOLEAN":
        me.attributes.remove(bad)
    ob = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(ob)
    bpy.context.view_layer.objects.active = ob
    ob.select_set(True)
    return ob


def mesh_edges(me):
    ev = np.empty(2 * len(me.edges), dtype=np.int32)
    me.edges.foreach_get("vertices", ev)
    return ev.reshape(-1, 2).astype(np.int64)


def mark_edges(me, pairs, name, value):
    """Set an EDGE attribute on the listed vertex pairs (independently of the add-on's bridge)."""
    E = np.sort(mesh_edges(me), axis=1)
    want = {tuple(p) for p in np.sort(np.asarray(pairs), axis=1).tolist()}
    rows = [i for i, e in enumerate(E.tolist()) if tuple(e) in want]
    assert len(rows) == len(want), "a marked pair is not an edge"
    dtype = "BOOLEAN" if isinstance(value, bool) else "FLOAT"
    attr = me.attributes.get(name) or me.attributes.new(name, dtype, "EDGE")
    vals = np.zeros(len(E), dtype=bool if dtype == "BOOLEAN" else np.float32)
    vals[rows] = value
    attr.data.foreach_set("value", vals)


def edge_values(me, name):
    attr = me.attributes.get(name)
    if attr is None:
        return None
    out = np.empty(len(me.edges), dtype=bool if attr.data_type == "BOOLEAN" else np.float32)
    attr.data.foreach_get("value", out)
    return out


def _drive_sharp(out: Path) -> None:
    bpy = drv._bpy_session()
    rec = drv._Recorder(out)
    status = bpy.ops.preferences.addon_enable(module=drv.ADDON)
    modules = {name: sys.modules.get(f"{drv.ADDON}.{name}") for name in ("sharp", "panel")}

    def env():
        rna = {k: getattr(bpy.ops.object, f"shapeflow_{k}").get_rna_type() for k in (
            "flow", "family", "subdivide_enhance", "brush")}
        angle = rna["flow"].properties["sharp_angle"]
        return dict(enable=sorted(status), props={k: sorted(t.properties.keys()) for k, t in rna.items()},
                    angle=[angle.subtype, angle.default, angle.hard_min, angle.hard_max],
                    defaults={p: rna["flow"].properties[p].default for p in ("keep_sharp", "sharp_marked",
                                                                             "sharp_by_angle")},
                    use_creases=rna["subdivide_enhance"].properties["use_creases"].default,
                    object_setting=sorted(bpy.types.Object.bl_rna.properties["shapeflow"].fixed_type
                                          .properties.keys()))

    rec.case("env", env)

    V0, F0, cube_edges = grid_cube()
    rec.put("cube_V", V0)
    rec.put("cube_edges", cube_edges)
    C0, CF, rims = can()
    rec.put("can_V", C0)
    rec.put("can_rims", rims)

    def cube_object(marks, shape=(V0, F0, cube_edges)):
        drv._clear(bpy)
        ob = _mesh_object(bpy, "part", *shape[:2])
        if marks == "sharp":
            mark_edges(ob.data, shape[2], "sharp_edge", True)
        elif marks == "crease":
            mark_edges(ob.data, shape[2], "crease_edge", 0.5)
        return ob

    def can_object():
        return cube_object("sharp", (C0, CF, rims))

    # --- Enhance / Smooth on the cube: marked edges, creases, an angle, nothing
    def cube():
        results = {}
        for name, marks, props in CUBE_RUNS:
            ob = cube_object(marks)
            kw = dict(dict(lam=LAM), **props)
            results[name] = sorted(bpy.ops.object.shapeflow_flow(**kw))
            rec.put(f"cube_{name}", drv._positions(ob.data))
        fs, fi = drv._faces(ob.data)
        rec.put("cube_fs", fs)
        rec.put("cube_fi", fi)
        # the can: its rims marked, the caps stay flat while the side enhances
        for name, props in (("keep", dict(keep_sharp=True, sharp_by_angle=False)), ("plain", {})):
            ob = can_object()
            results[f"can_{name}"] = sorted(bpy.ops.object.shapeflow_flow(lam=LAM, **props))
            rec.put(f"can_{name}", drv._positions(ob.data))
        fs, fi = drv._faces(ob.data)
        rec.put("can_fs", fs)
        rec.put("can_fi", fi)
        # a loose edge marked Sharp (in no face) is left out, not an error
        ob = can_object()
        me = ob.data
        n = len(me.vertices)
        me.vertices.add(2)
        me.vertices[n].co, me.vertices[n + 1].co = (3.0, 0.0, 0.0), (3.0, 1.0, 0.0)
        me.edges.add(1)
        me.edges[-1].vertices = (n, n + 1)
        me.update()
        mark_edges(me, np.r_[rims, [[n, n + 1]]], "sharp_edge", True)
        results["loose"] = sorted(bpy.ops.object.shapeflow_flow(lam=LAM, keep_sharp=True, sharp_by_angle=False))
        rec.put("can_loose", drv._positions(me)[:n])
        # Edit Mode: the selected vertices only, sharp edges kept
        ob = can_object()
        me = ob.data
        sel = C0[:, 1] < 0.2
        me.polygons.foreach_set("select", np.zeros(len(me.polygons), dtype=bool))
        me.edges.foreach_set("select", np.zeros(len(me.edges), dtype=bool))
        me.vertices.foreach_set("select", sel)
        bpy.ops.object.mode_set(mode="EDIT")
        results["edit"] = sorted(bpy.ops.object.shapeflow_flow(lam=LAM, keep_sharp=True, sharp_by_angle=False))
        bpy.ops.object.mode_set(mode="OBJECT")
        rec.put("can_edit", drv._positions(me))
        rec.put("can_sel", sel)
        return results

    rec.case("cube", cube)

    # --- the family and the brush keep the marked edges too
    def family_brush():
        ob = can_object()
        r_family = bpy.ops.object.shapeflow_family(lam_start=0.0, lam_end=-20.0, count=3, keep_sharp=True,
                                                   sharp_by_angle=False)
        members = sorted((o for o in bpy.data.objects if "shapeflow_lam" in o), key=lambda o: o.location.x)
        for k, o in enumerate(members):
            rec.put(f"family{k}", drv._positions(o.data))
        stroke = np.array([[0.0, -1.0, 0.7], [0.6, -0.8, 1.0], [0.9, -0.2, 1.0]])   # over the top rim
        rec.put("brush_stroke", stroke)
        runs = {}
        for name, props in (("keep", dict(keep_sharp=True, sharp_by_angle=False)), ("plain", {})):
            ob = can_object()
            runs[name] = sorted(bpy.ops.object.shapeflow_brush(
                lam=-40.0, radius=0.8, spacing=0.25, falloff="SMOOTH",
                stroke=[{"name": "", "location": tuple(p)} for p in stroke], **props))
            rec.put(f"brush_{name}", drv._positions(ob.data))
        return dict(family=sorted(r_family), members=len(members), brush=runs)

    rec.case("family_brush", family_brush)

    # --- the sidebar shows the object's setting; its buttons start the operators with it
    def ui():
        from types import SimpleNamespace

        class Layout:
            def __init__(self, log):
                self.log = log

            def __getattr__(self, name):
                def call(*args, **kw):
                    if name == "operator":
                        ns = SimpleNamespace()
                        self.log.append(("operator", args[0], ns))
                        return ns
                    if name in ("prop", "prop_search"):
                        self.log.append((name, args[1], args[0]))
                    elif name == "label":
                        self.log.append(("label", kw.get("text", "")))
                    return Layout(self.log)
                return call

        ob = cube_object("sharp")
        ob.shapeflow.keep_sharp = True
        ob.shapeflow.sharp_by_angle = False
        ob.shapeflow.sharp_angle = math.radians(40.0)
        log = []
        owner = SimpleNamespace(layout=Layout(log))
        bpy.types.VIEW3D_PT_shapeflow.draw(owner, SimpleNamespace(active_object=ob))
        buttons = {x[1]: {k: getattr(x[2], k, None) for k in modules["sharp"].SHARP_PROPS}
                   for x in log if x[0] == "operator"}
        setting = sorted(x[1] for x in log if x[0] == "prop" and x[2] == ob.shapeflow)
        labels = [x[1] for x in log if x[0] == "label"]
        mlog = []
        bpy.types.VIEW3D_MT_shapeflow.draw(SimpleNamespace(layout=Layout(mlog)), SimpleNamespace(active_object=ob))
        menu = {x[1]: getattr(x[2], "keep_sharp", None) for x in mlog if x[0] == "operator"}
        redo = {}
        for key, idname in (("flow", "shapeflow_flow"), ("brush", "shapeflow_brush"),
                            ("subdivide", "shapeflow_subdivide_enhance")):
            cls = getattr(bpy.types, f"OBJECT_OT_{idname}")
            rna = getattr(bpy.ops.object, idname).get_rna_type()
            op = SimpleNamespace(**{p.identifier: getattr(p, "default", None) for p in rna.properties
                                    if p.identifier != "rna_type"})
            for name in ("draw_flow_options",):
                if hasattr(cls, name):
                    setattr(op, name, getattr(cls, name).__get__(op))
            rlog = []
            op.layout = Layout(rlog)
            cls.draw(op, SimpleNamespace(active_object=ob))
            redo[key] = sorted({x[1] for x in rlog if x[0] in ("prop", "prop_search")})
        return dict(buttons=buttons, setting=setting, labels=labels, menu=menu, redo=redo)

    rec.case("ui", ui)
    rec.save()



# ==========================================================================
# the tests (pytest side)
# ==========================================================================

def run_in_blender(zip_path, tmp_path_factory, script) -> base._Run:
    """Install the built extension into a fresh Blender user folder, then run ``script``'s scenarios
    (``python script run OUT`` in a second ``bpy`` process) and return what they saved."""
    if not base.HAVE_BPY:
        pytest.skip("Blender's bpy module is not installed (pip install bpy==5.0.1; Python 3.11 only)")
    out = tmp_path_factory.mktemp(Path(script).stem)
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(out / "user"), PYTHONDONTWRITEBYTECODE="1")
    base._run_driver("install", zip_path, out, env=env, timeout=600)
    proc = subprocess.run([sys.executable, str(script), "run", str(out)], env=env, capture_output=True, text=True,
                          timeout=1200, cwd=str(base.ROOT))
    assert proc.returncode == 0, f"bpy driver failed:\n{proc.stdout[-4000:]}\n{proc.stderr[-6000:]}"
    return base._Run(out)


def drive_main(argv, drive) -> int:
    """The base driver's "run" mode (the bundled shapeflow and scipy first on sys.path), running ``drive``."""
    drv._drive_run = drive
    return drv._driver_main(argv)


@pytest.fixture(scope="module")
def blender(extension_zip, tmp_path_factory):  # noqa: F811 - the imported fixture
    return run_in_blender(extension_zip, tmp_path_factory, Path(__file__).resolve())


def diagonal(V):
    return float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))


def _flatness(P) -> float:
    """Largest distance of the points P from their best-fit plane (SVD)."""
    c = P.mean(axis=0)
    return float(np.abs((P - c) @ np.linalg.svd(P - c)[2][2]).max())


def _side_flatness(V0, X) -> float:
    """The worst of the cube's six sides (vertices picked at the input): distance from the best-fit plane."""
    return max(_flatness(X[V0[:, axis] == s]) for axis in range(3) for s in (-1.0, 1.0))


def _cap_flatness(C0, X) -> float:
    """The worst of the can's two caps (vertices at z = ±1 at the input, rims included)."""
    return max(_flatness(X[C0[:, 2] == z]) for z in (-1.0, 1.0))


def _mesh(a, name):
    import shapeflow as sf

    return sf.Mesh.from_csr(a[f"{name}_V"], a[f"{name}_fs"], a[f"{name}_fi"])


@needs_bpy
def test_properties_and_object_setting(blender):
    env = blender["env"]
    assert env["enable"] == ["FINISHED"]
    for key in ("flow", "family", "subdivide_enhance", "brush"):
        assert {"keep_sharp", "sharp_marked", "sharp_by_angle", "sharp_angle"} <= set(env["props"][key]), key
    assert "use_creases" in env["props"]["subdivide_enhance"] and env["use_creases"] is True
    subtype, default, lo, hi = env["angle"]
    assert subtype == "ANGLE" and abs(default - math.radians(30.0)) < 1e-6 and lo == 0.0 and abs(hi - math.pi) < 1e-6
    assert env["defaults"] == {"keep_sharp": False, "sharp_marked": True, "sharp_by_angle": True}
    assert env["object_setting"] == sorted(["keep_sharp", "sharp_marked", "sharp_by_angle", "sharp_angle",
                                            "name", "rna_type"])


@needs_bpy
def test_marked_cube_stays_a_cube(blender):
    """Enhanced with its 12 edges marked (Sharp, or Crease 0.5), or with a 30° angle, every side of the
    cube (irregular quads and triangles) stays flat to 1e-9 of the diagonal, its edges and corners in
    place; without the option, or with nothing marked, the sides bulge."""
    info = blender["cube"]
    a = blender.arrays
    V0 = a["cube_V"]
    diag = diagonal(V0)
    assert all(r == ["FINISHED"] for k, r in info.items() if k != "ok"), info
    flat = {name: _side_flatness(V0, a[f"cube_{name}"]) / diag for name, _, _ in CUBE_RUNS}
    for name in ("marked_sharp", "marked_crease", "angle", "both"):
        assert flat[name] <= 1e-9, (name, flat[name])
        X = a[f"cube_{name}"]
        on = np.abs(V0) == 1.0      # coordinates on a side's plane: corners 3, edges 2, sides 1
        assert np.array_equal(X[on], V0[on]), name
    for name in ("plain", "nothing_marked"):
        assert flat[name] > 1e-2, (name, flat[name])


@needs_bpy
def test_marked_can_keeps_its_caps_flat_while_its_side_enhances(blender):
    a = blender.arrays
    C0 = a["can_V"]
    diag = diagonal(C0)
    keep, plain = a["can_keep"], a["can_plain"]
    side = np.abs(C0[:, 2]) < 1.0
    assert _cap_flatness(C0, keep) / diag <= 1e-9 and _cap_flatness(C0, plain) / diag > 1e-2
    assert float(np.abs(keep[side] - C0[side]).max()) / diag > 1e-2     # the round side still enhances
    rim = np.abs(C0[:, 2]) == 1.0
    r = np.linalg.norm(keep[rim & (np.linalg.norm(C0[:, :2], axis=1) > 0.99)][:, :2], axis=1)
    assert np.ptp(r) <= 1e-6 and abs(r[0] - 1.0) > 1e-3                  # the rims stay circles, resized


@needs_bpy
def test_keep_sharp_matches_the_library(blender):
    import shapeflow as sf

    a = blender.arrays
    mesh = _mesh(a, "cube")
    E = a["cube_edges"]
    diag = diagonal(mesh.vertices)
    ref = {
        "plain": sf.flow(mesh, LAM),
        "marked_sharp": sf.flow(mesh, LAM, sharp_edges=E),
        "marked_crease": sf.flow(mesh, LAM, sharp_edges=E),
        "angle": sf.flow(mesh, LAM, feature_angle=30.0),
        "nothing_marked": sf.flow(mesh, LAM),
        "both": sf.flow(mesh, -0.9, iterations=2, compat="blender", feature_angle=30.0, sharp_edges=E),
    }
    for name, r in ref.items():
        assert float(np.abs(a[f"cube_{name}"] - r.vertices).max()) / diag <= 1e-6, name
    can, rims = _mesh(a, "can"), a["can_rims"]
    keep = sf.flow(can, LAM, sharp_edges=rims).vertices
    assert float(np.abs(a["can_keep"] - keep).max()) / diag <= 1e-6
    assert float(np.abs(a["can_plain"] - sf.flow(can, LAM).vertices).max()) / diag <= 1e-6
    # a loose edge marked Sharp is left out
    assert float(np.abs(a["can_loose"] - keep).max()) / diag <= 1e-6
    # Edit Mode: the selection as weights, sharp edges kept, the rest exactly in place
    sel = a["can_sel"].astype(bool)
    X = a["can_edit"]
    assert np.array_equal(X[~sel], can.vertices[~sel])
    edit = sf.flow(can, LAM, weights=sel.astype(float), sharp_edges=rims).vertices
    assert float(np.abs(X - edit).max()) / diag <= 1e-6 and float(np.abs(X - can.vertices).max()) > 1e-3


@needs_bpy
def test_family_and_brush_keep_sharp_edges(blender):
    import shapeflow as sf

    info = blender["family_brush"]
    a = blender.arrays
    can, rims = _mesh(a, "can"), a["can_rims"]
    C0 = can.vertices
    diag = diagonal(C0)
    assert info["family"] == ["FINISHED"] and info["members"] == 3
    shapes = sf.family(can, [0.0, -10.0, -20.0], sharp_edges=rims)
    for k in range(3):
        assert float(np.abs(a[f"family{k}"] - shapes[k]).max()) / diag <= 1e-6
        assert _cap_flatness(C0, a[f"family{k}"]) / diag <= 1e-9
    assert float(np.abs(a["family2"] - C0).max()) / diag > 1e-2
    assert info["brush"] == {"keep": ["FINISHED"], "plain": ["FINISHED"]}
    b = sf.Brush(can, lam=-40.0, radius=0.8, falloff="smooth", sharp_edges=rims)
    b.stroke(a["brush_stroke"], spacing=0.25)
    keep, plain = a["brush_keep"], a["brush_plain"]
    assert float(np.abs(keep - b.vertices).max()) / diag <= 1e-6
    assert float(np.abs(keep - C0).max()) / diag > 1e-3
    assert _cap_flatness(C0, keep) / diag <= 1e-9
    assert _cap_flatness(C0, plain) / diag > 1e-3     # the same stroke without the option bends the cap


@needs_bpy
def test_sidebar_setting_and_redo_panels(blender):
    """The sidebar shows the object's Keep Sharp Edges setting; its buttons and the menu's start the
    operators with it; each redo panel shows the options."""
    info = blender["ui"]
    want = {"keep_sharp": True, "sharp_marked": True, "sharp_by_angle": False}
    for idname in ("object.shapeflow_flow", "object.shapeflow_family", "object.shapeflow_subdivide_enhance",
                   "object.shapeflow_brush"):
        got = info["buttons"][idname]
        assert {k: got[k] for k in want} == want and abs(got["sharp_angle"] - math.radians(40.0)) < 1e-6, idname
        assert info["menu"][idname] is True
    assert info["setting"] == sorted(["keep_sharp", "sharp_marked", "sharp_by_angle", "sharp_angle"])
    assert f"{len(blender.arrays['cube_edges'])} marked edges" in info["labels"]
    for key in ("flow", "brush", "subdivide"):
        assert {"keep_sharp", "sharp_marked", "sharp_by_angle", "sharp_angle"} <= set(info["redo"][key]), key
    assert "use_creases" in info["redo"]["subdivide"]


if __name__ == "__main__":
    sys.exit(drive_main(sys.argv[1:], _drive_sharp))
