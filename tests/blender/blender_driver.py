"""The Blender side of test_blender_addon.py: the scenarios, run inside a ``bpy`` process.

``python tests/blender/blender_driver.py install ZIP OUT`` installs the extension zip as *Install from
Disk* does; ``python tests/blender/blender_driver.py run OUT`` (a second process, as after restarting
Blender) enables the installed add-on with its bundled shapeflow and scipy and runs every scenario.
Each saves Blender's inputs and results under OUT (``install.json``, ``results.json``,
``arrays.npz``), which the tests compare with the library and with Blender's own modifiers.
"""

from __future__ import annotations

import json
import os
import sys
import traceback
from pathlib import Path

import numpy as np

ADDON = "bl_ext.user_default.shapeflow"

class _Recorder:
    def __init__(self, out: Path):
        self.out = out
        self.results: dict = {}
        self.arrays: dict = {}

    def case(self, name, fn):
        try:
            info = fn() or {}
            self.results[name] = {"ok": True, **info}
        except Exception:  # noqa: BLE001 - reported to the test
            self.results[name] = {"ok": False, "error": traceback.format_exc()}

    def put(self, key, value):
        self.arrays[key] = np.asarray(value)

    def save(self):
        (self.out / "results.json").write_text(json.dumps(self.results, indent=1, default=str))
        np.savez_compressed(self.out / "arrays.npz", **self.arrays)


def _drive_install(zip_path: str, out: Path) -> None:
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    result = bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default",
                                                       enable_on_install=True)
    ext = Path(bpy.utils.user_resource("EXTENSIONS"))
    site = ext / ".local" / "lib" / f"python{sys.version_info[0]}.{sys.version_info[1]}" / "site-packages"
    info = dict(
        result=sorted(result),
        enabled=ADDON in {a.module for a in bpy.context.preferences.addons},
        operators=[hasattr(bpy.types, c) for c in ("OBJECT_OT_shapeflow_flow", "OBJECT_OT_shapeflow_family",
                                                   "OBJECT_OT_shapeflow_subdivide_enhance",
                                                   "OBJECT_OT_shapeflow_brush")],
        addon_files=sorted(os.listdir(ext / "user_default" / "shapeflow")),
        site_packages=sorted(os.listdir(site)) if site.is_dir() else [],
    )
    (out / "install.json").write_text(json.dumps(info, indent=1))


def _bpy_session():
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    return bpy


def _clear(bpy):
    for ob in list(bpy.data.objects):
        bpy.data.objects.remove(ob, do_unlink=True)
    for coll in list(bpy.data.collections):
        bpy.data.collections.remove(coll)
    for me in list(bpy.data.meshes):
        bpy.data.meshes.remove(me)
    for mat in list(bpy.data.materials):
        bpy.data.materials.remove(mat)


def _primitive(bpy, kind):
    ops = bpy.ops.mesh
    if kind == "monkey":
        ops.primitive_monkey_add()
    elif kind == "grid":  # open, with a wavy height field
        ops.primitive_grid_add(x_subdivisions=14, y_subdivisions=11, size=2.0)
    elif kind == "sphere":  # quads and triangle fans at the poles
        ops.primitive_uv_sphere_add(segments=20, ring_count=10, radius=1.0)
    elif kind == "cylinder":  # quads and two n-gon caps
        ops.primitive_cylinder_add(vertices=9, depth=2.0, end_fill_type="NGON")
    elif kind == "cube":
        ops.primitive_cube_add()
    else:
        raise ValueError(kind)
    ob = bpy.context.active_object
    if kind == "grid":
        V = _positions(ob.data)
        V[:, 2] = 0.15 * np.sin(3.0 * V[:, 0]) * np.cos(2.0 * V[:, 1])
        _set_positions(ob.data, V)
    return ob


def _positions(me):
    co = np.empty(3 * len(me.vertices), dtype=np.float32)
    me.vertices.foreach_get("co", co)
    return co.reshape(-1, 3).astype(np.float64)


def _set_positions(me, V):
    me.vertices.foreach_set("co", np.asarray(V, dtype=np.float32).ravel())
    me.update()


def _faces(me):
    m = len(me.polygons)
    sizes = np.empty(m, dtype=np.int32)
    me.polygons.foreach_get("loop_total", sizes)
    corners = np.empty(len(me.loops), dtype=np.int32)
    me.loops.foreach_get("vertex_index", corners)
    return sizes.astype(np.int64), corners.astype(np.int64)


def _set_group(ob, name, w):
    """A vertex group from weights, written and read back independently of the add-on."""
    vg = ob.vertex_groups.new(name=name)
    w = np.asarray(w, dtype=np.float32)
    for val in np.unique(w):
        vg.add(np.flatnonzero(w == val).tolist(), float(val), "REPLACE")
    return _group_loop(ob, name)


def _group_loop(ob, name):
    gi = ob.vertex_groups[name].index
    out = np.zeros(len(ob.data.vertices))
    for v in ob.data.vertices:
        for g in v.groups:
            if g.group == gi:
                out[v.index] = g.weight
    return out


def _activate(bpy, ob):
    for o in bpy.context.view_layer.objects:
        o.select_set(False)
    ob.select_set(True)
    bpy.context.view_layer.objects.active = ob


FLOW_CASES = [
    ("monkey", {"lam": -10.0}, None),
    ("monkey", {"lam": 5.0, "iterations": 3, "update": "RECOMPUTE", "preserve_volume": True}, None),
    ("grid", {"lam": -20.0, "lam_border": 2.0, "axes": (False, False, True)}, None),
    ("sphere", {"lam": -30.0, "vertex_group": "w", "invert_weights": True, "normalized": False}, "ramp"),
    ("cylinder", {"lam": -15.0, "iterations": 2}, None),
    ("monkey", {"lam": 0.7, "scheme": "BLENDER", "iterations": 2, "vertex_group": "w"}, "ramp"),
]

COMPAT_CASES = [  # (mesh, operator properties) — the modifier gets the same settings
    ("monkey", {"lam": 0.5, "iterations": 2}, None),
    ("monkey", {"lam": -0.8, "iterations": 1, "preserve_volume": True}, None),
    ("grid", {"lam": 1.0, "lam_border": 0.5, "iterations": 1}, None),
    ("sphere", {"lam": 0.9, "iterations": 3, "vertex_group": "w", "invert_weights": True}, "ramp"),
    ("cylinder", {"lam": 0.6, "iterations": 1, "normalized": False}, None),
    ("monkey", {"lam": 1.0, "axes": (True, False, True), "preserve_volume": True}, None),
]


def _ramp(V):
    z = V[:, 2]
    return np.round(np.clip((z - z.min()) / (np.ptp(z) or 1.0), 0.0, 1.0), 3)


def _drive_run(out: Path) -> None:
    bpy = _bpy_session()
    rec = _Recorder(out)
    status = bpy.ops.preferences.addon_enable(module=ADDON)
    mods = {name: sys.modules.get(f"{ADDON}.{name}") for name in ("bridge", "operators", "brush_op", "panel")}

    def env():
        import scipy

        import shapeflow

        op = bpy.types.OBJECT_OT_shapeflow_flow
        rna = {k: getattr(bpy.ops.object, f"shapeflow_{k}").get_rna_type() for k in (
            "flow", "family", "subdivide_enhance", "brush")}
        props = {k.replace("_enhance", ""): sorted(t.properties.keys()) for k, t in rna.items()}
        options = {k: sorted(getattr(bpy.types, c).bl_options) for k, c in (
            ("flow", "OBJECT_OT_shapeflow_flow"), ("family", "OBJECT_OT_shapeflow_family"),
            ("subdivide", "OBJECT_OT_shapeflow_subdivide_enhance"), ("brush", "OBJECT_OT_shapeflow_brush"))}
        panel = bpy.types.VIEW3D_PT_shapeflow
        return dict(enable=sorted(status), blender=bpy.app.version_string, shapeflow_file=shapeflow.__file__,
                    scipy=scipy.__version__, scipy_file=scipy.__file__, numpy=np.__version__,
                    extensions=bpy.utils.user_resource("EXTENSIONS"), props=props, options=options,
                    idnames=[op.bl_idname], panel=[panel.bl_space_type, panel.bl_region_type, panel.bl_category],
                    scheme_items=[i.identifier for i in rna["flow"].properties["scheme"].enum_items],
                    update_items=[i.identifier for i in rna["flow"].properties["update"].enum_items])

    rec.case("env", env)

    # --- Enhance / Smooth Shape, Object Mode: compared with the library in the test
    def flow_cases():
        for i, (kind, props, weights) in enumerate(FLOW_CASES):
            _clear(bpy)
            ob = _primitive(bpy, kind)
            V = _positions(ob.data)
            fs, fi = _faces(ob.data)
            if weights:
                rec.put(f"flow{i}_w", _set_group(ob, "w", _ramp(V)))
            r = bpy.ops.object.shapeflow_flow(**props)
            assert r == {"FINISHED"}, r
            rec.put(f"flow{i}_V", V)
            rec.put(f"flow{i}_fs", fs)
            rec.put(f"flow{i}_fi", fi)
            rec.put(f"flow{i}_out", _positions(ob.data))
        return {"n": len(FLOW_CASES)}

    rec.case("flow", flow_cases)

    # --- Blender-compatible scheme against Blender's Laplacian Smooth modifier on the same object
    def compat_cases():
        for i, (kind, props, weights) in enumerate(COMPAT_CASES):
            _clear(bpy)
            ob = _primitive(bpy, kind)
            V = _positions(ob.data)
            if weights:
                _set_group(ob, "w", _ramp(V))
            ref = bpy.data.objects.new("reference", ob.data.copy())
            bpy.context.scene.collection.objects.link(ref)
            mod = ref.modifiers.new("smooth", "LAPLACIANSMOOTH")
            mod.lambda_factor = props["lam"]
            mod.lambda_border = props.get("lam_border", 0.0)
            mod.iterations = props.get("iterations", 1)
            mod.use_normalized = props.get("normalized", True)
            mod.use_volume_preserve = props.get("preserve_volume", False)
            mod.use_x, mod.use_y, mod.use_z = props.get("axes", (True, True, True))
            mod.vertex_group = props.get("vertex_group", "")
            mod.invert_vertex_group = props.get("invert_weights", False)
            dg = bpy.context.evaluated_depsgraph_get()
            dg.update()
            rec.put(f"compat{i}_modifier", _positions(ref.evaluated_get(dg).data))
            _activate(bpy, ob)
            r = bpy.ops.object.shapeflow_flow(scheme="BLENDER", **props)
            assert r == {"FINISHED"}, r
            rec.put(f"compat{i}_operator", _positions(ob.data))
            rec.put(f"compat{i}_V", V)
        return {"n": len(COMPAT_CASES)}

    rec.case("compat", compat_cases)

    # --- Edit Mode: only the selected vertices move
    def edit_mode():
        _clear(bpy)
        ob = _primitive(bpy, "monkey")
        me = ob.data
        V = _positions(me)
        sel = V[:, 0] > 0.1
        w = _set_group(ob, "w", _ramp(V))
        me.polygons.foreach_set("select", np.zeros(len(me.polygons), dtype=bool))
        me.edges.foreach_set("select", np.zeros(len(me.edges), dtype=bool))
        me.vertices.foreach_set("select", sel)
        me.vertices.foreach_set("hide", np.zeros(len(me.vertices), dtype=bool))
        bpy.ops.object.mode_set(mode="EDIT")
        r1 = bpy.ops.object.shapeflow_flow(lam=-20.0)
        mode_after = bpy.context.mode
        bpy.ops.object.mode_set(mode="OBJECT")
        out1 = _positions(me)
        seen = np.zeros(len(me.vertices), dtype=bool)
        me.vertices.foreach_get("select", seen)
        assert np.array_equal(seen, sel), "the selection did not survive the round trip"
        bpy.ops.object.mode_set(mode="EDIT")
        r2 = bpy.ops.object.shapeflow_flow(lam=-20.0, vertex_group="w", preserve_volume=True)
        bpy.ops.object.mode_set(mode="OBJECT")
        out2 = _positions(me)
        me.vertices.foreach_set("select", np.zeros(len(me.vertices), dtype=bool))
        bpy.ops.object.mode_set(mode="EDIT")
        bpy.ops.mesh.select_all(action="DESELECT")
        r3 = bpy.ops.object.shapeflow_flow(lam=-20.0)
        bpy.ops.object.mode_set(mode="OBJECT")
        out3 = _positions(me)
        fs, fi = _faces(me)
        for k, v in dict(V=V, sel=sel, w=w, out1=out1, out2=out2, out3=out3, fs=fs, fi=fi).items():
            rec.put(f"edit_{k}", v)
        return dict(results=[sorted(r1), sorted(r2), sorted(r3)], mode_after=mode_after)

    rec.case("edit", edit_mode)

    # --- shape keys: the active key is what gets edited (and what Edit Mode shows afterwards)
    def shape_keys():
        _clear(bpy)
        ob = _primitive(bpy, "monkey")
        ob.shape_key_add(name="Basis")
        key = ob.shape_key_add(name="Key1")
        co = np.empty(3 * len(key.data), dtype=np.float32)
        key.data.foreach_get("co", co)
        K = co.reshape(-1, 3).astype(np.float64)
        K[:, 2] += 0.3 * K[:, 0] ** 2
        key.data.foreach_set("co", K.astype(np.float32).ravel())
        ob.active_shape_key_index = 1
        basis = _positions(ob.data)
        r = bpy.ops.object.shapeflow_flow(lam=-10.0)
        bpy.ops.object.mode_set(mode="EDIT")
        bpy.ops.object.mode_set(mode="OBJECT")
        key.data.foreach_get("co", co)
        fs, fi = _faces(ob.data)
        for k, v in dict(K=K, key_after=co.reshape(-1, 3), basis=basis, basis_after=_positions(ob.data),
                         fs=fs, fi=fi).items():
            rec.put(f"sk_{k}", v)
        return dict(result=sorted(r))

    rec.case("shape_keys", shape_keys)

    # --- vertex groups: the Geometry Nodes reader against the per-vertex loop
    def groups():
        _clear(bpy)
        ob = _primitive(bpy, "sphere")
        V = _positions(ob.data)
        ws = [_set_group(ob, "a", _ramp(V)), _set_group(ob, "b", np.round(np.abs(V[:, 0]), 2))]
        bridge = mods["bridge"]
        fast = bridge._read_groups_nodes(bpy.context, ob, ["a", "b"])
        public = bridge.read_vertex_groups(bpy.context, ob, ["b", "a"])
        left = [o.name for o in bpy.data.objects] + [g.name for g in bpy.data.node_groups]
        dev = max(float(np.abs(f - w).max()) for f, w in zip(fast + public[::-1], ws + ws))
        return dict(dev=dev, left=left)

    rec.case("groups", groups)

    # --- Shape Family
    def family():
        _clear(bpy)
        ob = _primitive(bpy, "monkey")
        ob.location = (0.5, 0.0, 0.0)
        V = _positions(ob.data)
        fs, fi = _faces(ob.data)
        r = bpy.ops.object.shapeflow_family(lam_start=0.0, lam_end=-40.0, count=5, gap=0.2)
        members = sorted((o for o in bpy.data.objects if "shapeflow_lam" in o), key=lambda o: o.location.x)
        rec.put("family_V", V)
        rec.put("family_fs", fs)
        rec.put("family_fi", fi)
        for k, o in enumerate(members):
            rec.put(f"family_member{k}", _positions(o.data))
        bbox = [[min(c[0] for c in o.bound_box) + o.location.x, max(c[0] for c in o.bound_box) + o.location.x]
                for o in [ob, *members]]
        return dict(result=sorted(r), lams=[o["shapeflow_lam"] for o in members],
                    colors=[list(o.color) for o in members], x=[o.location.x for o in members],
                    bbox=bbox, materials=[[m.name for m in o.data.materials] for o in members],
                    collections=[o.users_collection[0].name for o in members])

    rec.case("family", family)

    # --- Subdivide and Enhance (vertex groups, UVs, materials carried)
    def subdivide():
        _clear(bpy)
        ob = _primitive(bpy, "monkey")
        me = ob.data
        V = _positions(me)
        fs, fi = _faces(me)
        w = _set_group(ob, "w", _ramp(V))
        other = _set_group(ob, "other", np.round((V[:, 0] > 0).astype(float) * 0.8, 3))
        red, blue = bpy.data.materials.new("red"), bpy.data.materials.new("blue")
        me.materials.append(red)
        me.materials.append(blue)
        mi = (np.arange(len(fs)) % 2).astype(np.int32)
        me.polygons.foreach_set("material_index", mi)
        smooth = (np.arange(len(fs)) % 3 == 0)
        me.polygons.foreach_set("use_smooth", smooth)
        uv_layer = me.uv_layers.new(name="UVMap") if not me.uv_layers else me.uv_layers[0]
        uv = np.empty(2 * len(me.loops), dtype=np.float32)
        uv_layer.data.foreach_get("uv", uv)
        r = bpy.ops.object.shapeflow_subdivide_enhance(levels=2, boundary="SMOOTH", weights_rule="SMOOTH",
                                                        lam=-30.0, vertex_group="w")
        me2 = ob.data
        fs2, fi2 = _faces(me2)
        uv2 = np.empty(2 * len(me2.loops), dtype=np.float32)
        me2.uv_layers[0].data.foreach_get("uv", uv2)
        mi2 = np.empty(len(me2.polygons), dtype=np.int32)
        me2.polygons.foreach_get("material_index", mi2)
        sm2 = np.empty(len(me2.polygons), dtype=bool)
        me2.polygons.foreach_get("use_smooth", sm2)
        for k, v in dict(V=V, fs=fs, fi=fi, w=w, other=other, mi=mi, smooth=smooth, uv=uv.reshape(-1, 2),
                         out=_positions(me2), fs2=fs2, fi2=fi2, w2=_group_loop(ob, "w"),
                         other2=_group_loop(ob, "other"), uv2=uv2.reshape(-1, 2), mi2=mi2, sm2=sm2).items():
            rec.put(f"sub_{k}", v)
        info = dict(result=sorted(r), groups=[g.name for g in ob.vertex_groups],
                    materials=[m.name for m in me2.materials], mesh_names=sorted(m.name for m in bpy.data.meshes))
        # one level, no flow: against Blender's own Subdivision Surface modifier
        _clear(bpy)
        ob = _primitive(bpy, "monkey")
        ref = bpy.data.objects.new("reference", ob.data.copy())
        bpy.context.scene.collection.objects.link(ref)
        mod = ref.modifiers.new("subsurf", "SUBSURF")
        mod.levels = 1
        mod.boundary_smooth = "ALL"
        mod.use_limit_surface = False
        mod.use_creases = False
        dg = bpy.context.evaluated_depsgraph_get()
        dg.update()
        ev = ref.evaluated_get(dg)
        tmp = ev.to_mesh()
        rec.put("sub_blender", _positions(tmp))
        ev.to_mesh_clear()
        _activate(bpy, ob)
        r1 = bpy.ops.object.shapeflow_subdivide_enhance(levels=1, boundary="SMOOTH", lam=0.0)
        rec.put("sub_level1", _positions(ob.data))
        return dict(info, result1=sorted(r1))

    rec.case("subdivide", subdivide)

    # --- the brush: scripted strokes, the interactive session without a window, ray casting
    def brush():
        _clear(bpy)
        brush_op = mods["brush_op"]
        info = {}
        for tag, loc, scale in (("plain", (0.0, 0.0, 0.0), 1.0), ("moved", (1.0, -2.0, 0.5), 2.0)):
            _clear(bpy)
            ob = _primitive(bpy, "sphere")
            bpy.ops.object.shapeflow_subdivide_enhance(levels=1, lam=0.0)
            ob.location = loc
            ob.scale = (scale, scale, scale)
            bpy.context.view_layer.update()
            V = _positions(ob.data)
            fs, fi = _faces(ob.data)
            t = np.linspace(0.0, 1.0, 7)
            local = np.c_[np.cos(t), np.sin(t), 0.2 * t]  # a path near the equator, object space
            local = local / np.linalg.norm(local, axis=1)[:, None]
            world = local * scale + np.asarray(loc)
            r = bpy.ops.object.shapeflow_brush(lam=-40.0, radius=0.5 * scale, spacing=0.25, falloff="SMOOTH",
                                               stroke=[{"name": "", "location": tuple(p)} for p in world])
            info[tag] = sorted(r)
            for k, v in dict(V=V, fs=fs, fi=fi, local=local, out=_positions(ob.data)).items():
                rec.put(f"brush_{tag}_{k}", v)

        # the interactive session, driven without a window (Drag Dot, Space, cancel); each session
        # gets its own library brush on the current positions, as the operator's invoke() does
        _clear(bpy)
        ob = _primitive(bpy, "sphere")
        V = _positions(ob.data)
        fs, fi = _faces(ob.data)
        s = brush_op.BrushSession(_library_brush(V, fs, fi, -40.0, 0.5), ob, lam=-40.0, radius=0.5,
                                  method="DRAG_DOT")
        a, b = np.array([1.0, 0.0, 0.0]), np.array([0.8, 0.6, 0.0])
        s.press(a)
        preview_a = _positions(ob.data)
        s.drag(b)
        preview_b = _positions(ob.data)
        s.release()
        committed = _positions(ob.data)
        s2 = brush_op.BrushSession(_library_brush(committed, fs, fi, -40.0, 0.5), ob, lam=-40.0,
                                   radius=0.5, method="SPACE", spacing=0.25)
        s2.press(a, invert=True)
        s2.drag(b, invert=True)
        s2.release()
        space = _positions(ob.data)
        s2.cancel()
        cancelled = _positions(ob.data)
        for k, v in dict(V=V, fs=fs, fi=fi, preview_a=preview_a, preview_b=preview_b, committed=committed,
                         space=space, cancelled=cancelled, space_dabs=np.array([p for p, _ in s2.dabs])).items():
            rec.put(f"session_{k}", v)
        info["dabs"] = [[list(p), inv] for p, inv in s.dabs]
        info["space_inverted"] = [inv for _, inv in s2.dabs]

        # ray cast on the object, and the radius circle
        _clear(bpy)
        ob = _primitive(bpy, "sphere")
        ob.location = (0.0, 0.0, 1.0)
        bpy.context.view_layer.update()
        hit = brush_op.ray_cast_object(ob, (0.0, -5.0, 1.0), (0.0, 1.0, 0.0))
        miss = brush_op.ray_cast_object(ob, (0.0, -5.0, 5.0), (0.0, 1.0, 0.0))
        circle = brush_op.circle_points((0.0, 0.0, 0.0), (0.0, 0.0, 2.0), 0.5, segments=16)
        info.update(hit=[list(map(float, hit[0])), list(map(float, hit[1]))], miss=miss is None,
                    circle_radius=[float(np.linalg.norm(circle, axis=1).min()),
                                   float(np.linalg.norm(circle, axis=1).max())],
                    circle_z=float(np.abs(circle[:, 2]).max()), circle_closed=bool(np.allclose(circle[0], circle[-1])))
        return info

    rec.case("brush", brush)

    # --- the modal operator's event handling, with a stand-in 3D view (bpy has no window here)
    def modal():
        from types import MethodType, SimpleNamespace

        from mathutils import Matrix

        _clear(bpy)
        ob = _primitive(bpy, "sphere")
        V = _positions(ob.data)
        fs, fi = _faces(ob.data)
        brush_op = mods["brush_op"]
        cls = bpy.types.OBJECT_OT_shapeflow_brush
        # an orthographic view from -Y, 200 × 200 pixels showing x, z in [-2, 2]
        view = Matrix(((1, 0, 0, 0), (0, 0, 1, 0), (0, -1, 0, -10), (0, 0, 0, 1)))
        near, far = 0.1, 100.0
        window = Matrix(((0.5, 0, 0, 0), (0, 0.5, 0, 0), (0, 0, -2 / (far - near), -(far + near) / (far - near)),
                         (0, 0, 0, 1)))
        rv3d = SimpleNamespace(view_matrix=view, perspective_matrix=window @ view, is_perspective=False,
                               view_perspective="ORTHO")
        region = SimpleNamespace(type="WINDOW", x=0, y=0, width=200, height=200)
        header = []
        area = SimpleNamespace(regions=[SimpleNamespace(type="HEADER"), region], type="VIEW_3D",
                               spaces=SimpleNamespace(active=SimpleNamespace(region_3d=rv3d)),
                               header_text_set=header.append, tag_redraw=lambda: None)
        context = SimpleNamespace(active_object=ob, window=SimpleNamespace(cursor_modal_restore=lambda: None))
        items = []
        op = SimpleNamespace(stroke=SimpleNamespace(clear=items.clear, add=lambda: items.append(SimpleNamespace())
                                                    or items[-1]),
                             stroke_invert="", replay_exact=False, radius=0.5)
        op._session = brush_op.BrushSession(_library_brush(V, fs, fi, -40.0, 0.5), ob, lam=-40.0, radius=0.5)
        op._area = area
        op._handle = bpy.types.SpaceView3D.draw_handler_add(brush_op._draw_callback, (op._session,), "WINDOW",
                                                            "POST_VIEW")
        op._hit = MethodType(cls._hit, op)
        op._end = MethodType(cls._end, op)

        def px(x, z):
            return int(round((x / 2.0 + 1.0) * 100)), int(round((z / 2.0 + 1.0) * 100))

        def ev(kind, value="NOTHING", at=(0.0, 0.0), ctrl=False, pixel=None):
            mx, my = pixel if pixel is not None else px(*at)
            return SimpleNamespace(type=kind, value=value, mouse_x=mx, mouse_y=my, ctrl=ctrl)

        log = []
        for e in (ev("MOUSEMOVE", at=(0.3, 0.2)), ev("LEFTMOUSE", "PRESS", at=(0.3, 0.2)),
                  ev("MOUSEMOVE", at=(0.5, 0.1)), ev("LEFTMOUSE", "RELEASE", at=(0.5, 0.1)),
                  ev("RIGHT_BRACKET", "PRESS"), ev("MOUSEMOVE", pixel=(500, 50)), ev("MIDDLEMOUSE", "PRESS"),
                  ev("MOUSEMOVE", at=(-0.4, 0.0)), ev("LEFTMOUSE", "PRESS", at=(-0.4, 0.0), ctrl=True),
                  ev("LEFTMOUSE", "RELEASE", at=(-0.4, 0.0), ctrl=True), ev("RET", "PRESS")):
            log.append(sorted(cls.modal(op, context, e)))
            if e.type == "MOUSEMOVE" and e.mouse_x < 200:
                hover = op._session.hover
                log[-1].append(None if hover is None else [round(float(x), 4) for x in hover[0]])
        after = _positions(ob.data)
        rec.put("modal_V", V)
        rec.put("modal_fs", fs)
        rec.put("modal_fi", fi)
        rec.put("modal_after", after)
        rec.put("modal_stroke", np.array([tuple(i.location) for i in items]))
        # Adjust Last Operation replays the recorded stroke: the same result from the original mesh
        _set_positions(ob.data, V)
        r = bpy.ops.object.shapeflow_brush(lam=-40.0, radius=op.radius, falloff="SMOOTH", replay_exact=True,
                                           stroke_invert=op.stroke_invert,
                                           stroke=[{"name": "", "location": tuple(i.location)} for i in items])
        rec.put("modal_replay", _positions(ob.data))
        # Esc: everything undone
        op2 = SimpleNamespace(**{k: getattr(op, k) for k in ("stroke", "stroke_invert", "replay_exact", "radius")})
        op2._session = brush_op.BrushSession(_library_brush(V, fs, fi, -40.0, 0.5), ob, lam=-40.0, radius=0.5)
        op2._area, op2._hit = area, MethodType(cls._hit, op2)
        op2._end = MethodType(cls._end, op2)
        op2._handle = bpy.types.SpaceView3D.draw_handler_add(brush_op._draw_callback, (op2._session,), "WINDOW",
                                                             "POST_VIEW")
        log2 = [sorted(cls.modal(op2, context, e)) for e in (
            ev("LEFTMOUSE", "PRESS", at=(0.0, 0.0)), ev("LEFTMOUSE", "RELEASE", at=(0.0, 0.0)),
            ev("ESC", "PRESS"))]
        return dict(log=log, log2=log2, radius=op.radius, invert=op.stroke_invert, replay=sorted(r),
                    cancelled_equal=bool(np.array_equal(_positions(ob.data), V)), header=[h for h in header])

    rec.case("modal", modal)

    # --- the sidebar panel, the menus and the redo panels, drawn into a recording stand-in layout
    def ui():
        from types import SimpleNamespace

        class Layout:
            def __init__(self, log):
                self.log = log

            def __getattr__(self, name):
                def call(*args, **kw):
                    if name == "operator":
                        self.log.append(("operator", args[0]))
                        return SimpleNamespace()
                    if name in ("prop", "prop_search"):
                        self.log.append((name, args[1]))
                    elif name in ("label", "menu"):
                        self.log.append((name, kw.get("text", args[0] if args else "")))
                    return Layout(self.log)
                return call

            def __setattr__(self, name, value):
                object.__setattr__(self, name, value)

        def draw(fn, owner, context):
            log = []
            owner.layout = Layout(log)
            fn(owner, context)
            return log

        _clear(bpy)
        ob = _primitive(bpy, "monkey")
        ob.vertex_groups.new(name="w")
        ctx = SimpleNamespace(active_object=ob)
        out = {}
        out["panel_object"] = [x[1] for x in draw(bpy.types.VIEW3D_PT_shapeflow.draw, SimpleNamespace(), ctx)
                               if x[0] == "operator"]
        bpy.ops.object.mode_set(mode="EDIT")
        out["panel_edit"] = [x[1] for x in draw(bpy.types.VIEW3D_PT_shapeflow.draw, SimpleNamespace(), ctx)
                             if x[0] == "operator"]
        bpy.ops.object.mode_set(mode="OBJECT")
        out["menu"] = [x[1] for x in draw(bpy.types.VIEW3D_MT_shapeflow.draw, SimpleNamespace(), ctx)
                       if x[0] == "operator"]
        for key, idname in (("flow", "shapeflow_flow"), ("family", "shapeflow_family"),
                            ("subdivide", "shapeflow_subdivide_enhance"), ("brush", "shapeflow_brush")):
            cls = getattr(bpy.types, f"OBJECT_OT_{idname}")
            rna = getattr(bpy.ops.object, idname).get_rna_type()
            owner = SimpleNamespace(**{p.identifier: getattr(p, "default", None) for p in rna.properties
                                       if p.identifier != "rna_type"})
            for name in ("draw_flow_options", "solver_options", "run_options"):
                if hasattr(cls, name):
                    setattr(owner, name, getattr(cls, name).__get__(owner))
            out[f"redo_{key}"] = sorted({x[1] for x in draw(cls.draw, owner, ctx) if x[0] in ("prop", "prop_search")})
        return out

    rec.case("ui", ui)

    # --- a screenshot: a shape family on a subdivided Suzanne, Workbench, headless
    def render():
        _clear(bpy)
        path = _render_family(bpy, out / "blender_family.png")
        img = bpy.data.images.load(str(path))
        px = np.empty(img.size[0] * img.size[1] * 4, dtype=np.float32)
        img.pixels.foreach_get(px)
        px = px.reshape(-1, 4)[:, :3]
        return dict(path=str(path), size=list(img.size), std=float(px.std()),
                    colourful=float(np.mean(px.max(axis=1) - px.min(axis=1) > 0.2)))

    rec.case("render", render)

    # --- disabling removes everything
    def disable():
        r = bpy.ops.preferences.addon_disable(module=ADDON)
        return dict(result=sorted(r), left=[hasattr(bpy.types, c) for c in (
            "OBJECT_OT_shapeflow_flow", "OBJECT_OT_shapeflow_family", "OBJECT_OT_shapeflow_subdivide_enhance",
            "OBJECT_OT_shapeflow_brush", "VIEW3D_PT_shapeflow")])

    rec.case("disable", disable)
    rec.save()


def _library_brush(V, fs, fi, lam, radius):
    import shapeflow as sf

    return sf.Brush(sf.Mesh.from_csr(V, fs, fi), lam=lam, radius=radius, falloff="smooth")


def _render_family(bpy, path: Path) -> Path:
    """Suzanne (subdivided twice) and its family for λ = 0 … −240: figure 1 of the paper, in Blender."""
    from mathutils import Vector

    scene = bpy.context.scene
    bpy.ops.mesh.primitive_monkey_add()
    ob = bpy.context.active_object
    ob.rotation_euler = (0.0, 0.0, 0.0)
    assert bpy.ops.object.shapeflow_subdivide_enhance(levels=2, lam=0.0) == {"FINISHED"}
    ob.data.polygons.foreach_set("use_smooth", np.ones(len(ob.data.polygons), dtype=bool))
    ob.data.update()
    assert bpy.ops.object.shapeflow_family(lam_start=0.0, lam_end=-240.0, count=5, gap=0.3,
                                           color_start=(0.10, 0.40, 0.90, 1.0),
                                           color_end=(0.95, 0.40, 0.08, 1.0)) == {"FINISHED"}
    ob.hide_render = True
    members = sorted((o for o in bpy.data.objects if "shapeflow_lam" in o), key=lambda o: o.location.x)
    pts = np.concatenate([_positions(o.data) @ np.array(o.matrix_world.to_3x3()).T + np.array(o.location)
                          for o in members])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    for o in members:  # λ under each member
        curve = bpy.data.curves.new(f"label {o.name}", type="FONT")
        curve.body = f"λ = {o['shapeflow_lam']:g}"
        curve.align_x = "CENTER"
        curve.align_y = "BOTTOM"
        curve.size = 0.3
        label = bpy.data.objects.new(curve.name, curve)
        label.location = (o.location.x, lo[1] - 0.5, lo[2] - 0.42)
        label.rotation_euler = (1.5708, 0.0, 0.0)
        label.color = (0.2, 0.2, 0.2, 1.0)
        scene.collection.objects.link(label)
    bottom, top = lo[2] - 0.55, hi[2] + 0.15
    span_x = (hi[0] - lo[0]) + 0.4
    width = 1200
    height = int(round(width * (top - bottom) / span_x))
    cam = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = span_x
    cam.location = Vector((0.5 * (lo[0] + hi[0]), -10.0, 0.5 * (top + bottom)))
    cam.rotation_euler = (1.5708, 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.display.shading.light = "STUDIO"
    scene.display.shading.color_type = "OBJECT"
    scene.display.shading.show_cavity = True
    scene.display.shading.show_shadows = False
    scene.view_settings.view_transform = "Standard"
    if scene.world is None:
        scene.world = bpy.data.worlds.new("world")
    scene.world.color = (1.0, 1.0, 1.0)
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGB"
    scene.render.image_settings.compression = 90
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    return path


def _driver_main(argv) -> int:
    mode, out = argv[0], Path(argv[-1])
    out.mkdir(parents=True, exist_ok=True)
    if mode == "install":
        _drive_install(argv[1], out)
    elif mode == "run":
        # As in a Blender started after the install: the extension's site-packages goes first, so
        # the bundled shapeflow and scipy are used (not this checkout's, nor the host's scipy).
        import bpy

        site = Path(bpy.utils.user_resource("EXTENSIONS")) / ".local" / "lib" / \
            f"python{sys.version_info[0]}.{sys.version_info[1]}" / "site-packages"
        sys.path[:] = [str(site)] + [p for p in sys.path if p != str(site)]
        for name in [m for m in sys.modules if m.split(".")[0] in ("shapeflow", "scipy")]:
            del sys.modules[name]
        _drive_run(out)
    else:
        raise SystemExit(f"unknown mode {mode}")
    return 0


if __name__ == "__main__":
    sys.exit(_driver_main(sys.argv[1:]))
