"""Creased subdivision in the Blender extension, against Blender's own Subdivision Surface modifier.

Subdivide and Enhance reads the object's edge creases (``crease_edge``), subdivides with them
and writes the sub-edges' creases (and the halves of edges marked Sharp) onto the new mesh.
Run in real Blender as ``test_addon_sharp.py`` runs (``run_in_blender``): each object is also
subdivided by Blender's modifier with Use Creases, and the results are compared as point sets
(Blender evaluates a grid per face, the library refines level by level).
"""

from __future__ import annotations

import sys
from pathlib import Path

import blender_driver as drv
import numpy as np
import pytest
from test_addon_sharp import diagonal, drive_main, edge_values, mark_edges, mesh_edges, needs_bpy, run_in_blender
from test_blender_addon import extension_zip  # noqa: F401 - the built zip, a fixture

#: creased objects: (kind, boundary, levels); each also subdivided by Blender's modifier
CREASE_CASES = [("cube", "SMOOTH", 2), ("cylinder", "SMOOTH", 2), ("grid", "KEEP_CORNERS", 2), ("cube", "SMOOTH", 3)]
BOUNDARY_SMOOTH = {"SMOOTH": "ALL", "KEEP_CORNERS": "PRESERVE_CORNERS"}


# ==========================================================================
# the Blender side (python tests/blender/test_addon_creases.py run OUT)
# ==========================================================================

def _evaluated(bpy, ob):
    dg = bpy.context.evaluated_depsgraph_get()
    dg.update()
    ev = ob.evaluated_get(dg)
    me = ev.to_mesh()
    out = dict(V=drv._positions(me), E=mesh_edges(me), sharp=edge_values(me, "sharp_edge"))
    fs, fi = drv._faces(me)
    out.update(fs=fs, fi=fi)
    ev.to_mesh_clear()
    return out


def _subsurf(bpy, ob, levels, boundary, use_creases=True):
    """A copy of the object with Blender's Subdivision Surface modifier, evaluated."""
    ref = bpy.data.objects.new(f"{ob.name} subsurf", ob.data.copy())
    bpy.context.scene.collection.objects.link(ref)
    mod = ref.modifiers.new("subsurf", "SUBSURF")
    mod.levels = levels
    mod.boundary_smooth = BOUNDARY_SMOOTH[boundary]
    mod.use_limit_surface = False
    mod.use_creases = use_creases
    return _evaluated(bpy, ref)


def _creased(bpy, kind):
    """A primitive with edge creases 0.3 … 1 (and a dart) and two edges marked Sharp."""
    ops = bpy.ops.mesh
    if kind == "cube":
        ops.primitive_cube_add(size=2.0)
    elif kind == "cylinder":  # quads and two heptagon caps
        ops.primitive_cylinder_add(vertices=7, depth=2.0, end_fill_type="NGON")
    else:  # an open grid of quads
        ops.primitive_grid_add(x_subdivisions=5, y_subdivisions=4, size=2.0)
    ob = bpy.context.active_object
    me = ob.data
    V = drv._positions(me)
    if kind == "grid":
        V[:, 2] = 0.3 * np.sin(2.0 * V[:, 0]) * np.cos(1.5 * V[:, 1])
        drv._set_positions(me, V)
    E = mesh_edges(me)
    crease = np.zeros(len(E), dtype=np.float32)
    pick = np.arange(len(E)) % 3 == 0                    # every third edge, values 0.3 … 1
    crease[pick] = np.resize(np.float32([0.3, 0.6, 0.9, 1.0, 0.45]), int(pick.sum()))
    attr = me.attributes.new("crease_edge", "FLOAT", "EDGE")
    attr.data.foreach_set("value", crease)
    mark_edges(me, E[[1, 2]], "sharp_edge", True)
    return ob, E, crease.astype(np.float64)


def _drive_creases(out: Path) -> None:
    bpy = drv._bpy_session()
    rec = drv._Recorder(out)
    assert bpy.ops.preferences.addon_enable(module=drv.ADDON) == {"FINISHED"}

    # --- creased subdivision: the add-on against Blender's Subdivision Surface on the same object
    def creases():
        info = []
        for i, (kind, boundary, levels) in enumerate(CREASE_CASES):
            drv._clear(bpy)
            ob, E, crease = _creased(bpy, kind)
            ref = _subsurf(bpy, ob, levels, boundary)
            plain = _subsurf(bpy, ob, levels, boundary, use_creases=False)
            rec.put(f"crease{i}_V", drv._positions(ob.data))
            fs, fi = drv._faces(ob.data)
            rec.put(f"crease{i}_fs", fs)
            rec.put(f"crease{i}_fi", fi)
            rec.put(f"crease{i}_E", E)
            rec.put(f"crease{i}_values", crease)
            for key in ("V", "E", "sharp"):
                rec.put(f"crease{i}_blender_{key}", ref[key])
            rec.put(f"crease{i}_blender_plain", plain["V"])
            drv._activate(bpy, ob)
            r = bpy.ops.object.shapeflow_subdivide_enhance(levels=levels, boundary=boundary, lam=0.0)
            res = _evaluated(bpy, ob)
            rec.put(f"crease{i}_addon_V", res["V"])
            rec.put(f"crease{i}_addon_E", res["E"])
            rec.put(f"crease{i}_addon_sharp", res["sharp"])
            rec.put(f"crease{i}_addon_crease", edge_values(ob.data, "crease_edge"))
            ob.data.edges.foreach_set("select", np.ones(len(ob.data.edges), dtype=bool))  # a sound layer
            select_edge = ob.data.attributes[".select_edge"].data_type
            # one level by the add-on, then one by Blender's modifier = two levels by Blender at once
            drv._clear(bpy)
            ob, _, _ = _creased(bpy, kind)
            r1 = bpy.ops.object.shapeflow_subdivide_enhance(levels=1, boundary=boundary, lam=0.0)
            rec.put(f"crease{i}_chain", _subsurf(bpy, ob, levels - 1, boundary)["V"])
            # without Use Creases: Blender's modifier without them, and no creases written
            drv._clear(bpy)
            ob, _, _ = _creased(bpy, kind)
            r2 = bpy.ops.object.shapeflow_subdivide_enhance(levels=levels, boundary=boundary, lam=0.0,
                                                            use_creases=False)
            rec.put(f"crease{i}_nocrease", drv._positions(ob.data))
            info.append(dict(result=sorted(r), chain=sorted(r1), nocrease=sorted(r2), select_edge=select_edge,
                             nocrease_attr=ob.data.attributes.get("crease_edge") is not None))
        # Subdivide and Enhance with Keep Sharp Edges: the creased cube's sub-edges are what is kept
        drv._clear(bpy)
        ob, E, crease = _creased(bpy, "cube")
        r3 = bpy.ops.object.shapeflow_subdivide_enhance(levels=2, lam=-20.0, keep_sharp=True, sharp_by_angle=False)
        me = ob.data
        rec.put("enhance_out", drv._positions(me))
        fs, fi = drv._faces(me)
        rec.put("enhance_fs", fs)
        rec.put("enhance_fi", fi)
        rec.put("enhance_E", mesh_edges(me))
        rec.put("enhance_sharp", edge_values(me, "sharp_edge"))
        rec.put("enhance_crease", edge_values(me, "crease_edge"))
        return dict(cases=info, enhance=sorted(r3))

    rec.case("creases", creases)

    rec.case("creases", creases)
    rec.save()


# ==========================================================================
# the tests (pytest side)
# ==========================================================================

@pytest.fixture(scope="module")
def blender(extension_zip, tmp_path_factory):  # noqa: F811 - the imported fixture
    return run_in_blender(extension_zip, tmp_path_factory, Path(__file__).resolve())


def _match(ours, theirs, tol):
    """ours -> theirs vertex numbers, one to one, every point within tol (absolute)."""
    from scipy.spatial import cKDTree

    dist, j = cKDTree(theirs).query(ours)
    assert np.unique(j).size == j.size, "the matching is not one-to-one"
    return dist.max(), j


@needs_bpy
@pytest.mark.parametrize("i", range(len(CREASE_CASES)))
def test_creased_subdivision_equals_blenders_modifier(blender, i):
    """Subdivide and Enhance (λ = 0) with the object's creases = Blender's Subdivision Surface with Use
    Creases on the same object, to 1e-5 of the diagonal; one level by the add-on and the next by Blender's
    modifier (reading the creases the add-on wrote) = Blender's two levels at once."""
    info = blender["creases"]["cases"][i]
    a = {k[len(f"crease{i}_"):]: v for k, v in blender.arrays.items() if k.startswith(f"crease{i}_")}
    assert info["result"] == info["chain"] == info["nocrease"] == ["FINISHED"]
    assert info["select_edge"] == "BOOLEAN"    # the new mesh's edge selection can be written
    ref = a["blender_V"]
    diag = diagonal(ref)
    assert ref.shape == a["addon_V"].shape
    dev, j = _match(a["addon_V"], ref, 1e-5 * diag)
    assert dev / diag <= 1e-5, dev / diag
    # the creases matter here: Blender's result without them is elsewhere
    assert float(np.abs(a["blender_plain"] - ref).max()) / diag > 1e-3
    # the creases written on the new mesh continue the same surface in Blender's own modifier
    dev_chain, _ = _match(a["chain"], ref, 1e-5 * diag)
    assert dev_chain / diag <= 1e-5, dev_chain / diag
    # without Use Creases: Blender's modifier without them, and no crease attribute
    dev_plain, _ = _match(a["nocrease"], a["blender_plain"], 1e-5 * diag)
    assert dev_plain / diag <= 1e-5 and not info["nocrease_attr"]
    # edges marked Sharp: their halves are marked on the new mesh, as Blender's modifier marks them
    ours = {tuple(sorted(j[e])) for e in a["addon_E"][a["addon_sharp"].astype(bool)].tolist()}
    theirs = {tuple(sorted(e)) for e in a["blender_E"][a["blender_sharp"].astype(bool)].tolist()}
    kind, _, levels = CREASE_CASES[i]
    assert len(theirs) == 2 * 2 ** levels and ours == theirs


def _coarse(a, i):
    import shapeflow as sf

    p = f"crease{i}_"
    E, c = a[p + "E"], a[p + "values"]
    return sf.Mesh.from_csr(a[p + "V"], a[p + "fs"], a[p + "fi"]), (E[c > 0], c[c > 0])


@needs_bpy
@pytest.mark.parametrize("i", range(len(CREASE_CASES)))
def test_written_creases_go_one_level_down_per_level(blender, i):
    """A crease c (sharpness 10c²) leaves 2^levels sub-edges with sqrt((10c² − levels)/10), c = 1 stays 1
    (Blender's sharpness rule, derived here); they sit where the library's subdivision puts them."""
    import shapeflow as sf

    a = blender.arrays
    kind, boundary, levels = CREASE_CASES[i]
    p = f"crease{i}_"
    values = a[p + "values"]
    got = {tuple(sorted(e)): float(c) for e, c in zip(a[p + "addon_E"].tolist(), a[p + "addon_crease"])}
    s = 10.0 * values[values > 0] ** 2
    left = np.where(s >= 10.0, 1.0, np.sqrt(np.clip(s - levels, 0.0, None) / 10.0))
    want = np.sort(np.repeat(left[left > 0], 2 ** levels))
    assert want.size and np.allclose(np.sort([v for v in got.values() if v > 0]), want, atol=1e-6), kind
    coarse, creases = _coarse(a, i)
    lib = sf.subdivide(coarse, levels, boundary=boundary.lower().replace("_", "-"), creases=creases)
    assert float(np.abs(lib.vertices - a[p + "addon_V"]).max()) <= 1e-6 * diagonal(lib.vertices)  # same numbering
    pairs, vals = lib.creases
    assert all(abs(got[tuple(sorted(e))] - v) <= 1e-6 for e, v in zip(pairs.tolist(), vals))


@needs_bpy
def test_subdivide_and_enhance_keeps_the_sub_edges(blender):
    """Creased cube, two levels, enhanced with Keep Sharp Edges (marked): the sub-edges with a crease left
    or a Sharp mark are the sharp edges, as the library's flow with those pairs computes it."""
    import shapeflow as sf

    assert blender["creases"]["enhance"] == ["FINISHED"]
    a = blender.arrays
    X, E = a["enhance_out"], a["enhance_E"]
    marked = E[a["enhance_sharp"].astype(bool) | (a["enhance_crease"] > 0)]
    coarse, creases = _coarse(a, 0)
    before = sf.subdivide(coarse, 2, creases=creases)
    assert len(marked) == 2 * 4 + 4 * int((creases[1] > np.sqrt(0.2)).sum())   # Sharp halves, creases left
    ref = sf.flow(before, -20.0, sharp_edges=marked)
    diag = diagonal(X)
    assert float(np.abs(X - ref.vertices).max()) / diag <= 1e-6
    assert float(np.abs(sf.flow(before, -20.0).vertices - ref.vertices).max()) / diag > 1e-3


if __name__ == "__main__":
    sys.exit(drive_main(sys.argv[1:], _drive_creases))
