"""Run real Blender (the ``bpy`` module) on shapeflow meshes.

Reference outputs and timings from Blender's own *Laplacian Smooth* and
*Subdivision Surface* modifiers, for benchmarks and comparisons.

Install Blender as a Python module with ``pip install bpy==5.0.1`` (Python 3.11
only; ~375 MB wheel, ~820 MB installed; note that it pins ``numpy<2``).  This
module imports without ``bpy``: ``bpy`` is imported lazily inside the functions,
and :func:`available` says whether it can be imported.

Meshes are passed in the CSR layout used by the fixtures: ``vertices`` (n, 3),
``face_sizes`` (m,), ``face_indices`` (sum(face_sizes),), each face listed by its
corners in loop order.  Blender stores positions in float32, so the inputs are
rounded to float32 on the way in; results come back as float64.

Public functions::

    available() -> bool
    make_object(vertices, face_sizes, face_indices, weights=None, name="obj") -> bpy.types.Object
    laplacian_smooth(vertices, face_sizes, face_indices, *, lambda_factor, lambda_border=0.0,
                     iterations=1, use_normalized=True, use_volume_preserve=False,
                     use_x=True, use_y=True, use_z=True, weights=None,
                     invert_vertex_group=False, repeat=1) -> (positions, seconds_median)
    subdivision_surface(vertices, face_sizes, face_indices, *, levels=1,
                        subdivision_type="CATMULL_CLARK", boundary_smooth="ALL",
                        weights=None, repeat=1, use_limit_surface=False, creases=None)
        -> (positions, face_sizes, face_indices, result_weights or None, seconds_median)
    set_edge_creases(mesh, pairs, values) -> None
    crease_fixtures(out_dir) -> [paths]
    clear_scene() -> None
    suzanne_sub4() -> (vertices, face_sizes, face_indices)
    main()

``last_timing`` (module global) holds the details of the most recent timed call:
every sample and the cost of the same re-evaluation with the modifier disabled.

Run ``python benchmarks/blender_ref.py`` to re-run every fixture case in
``shared/fixtures/blender/cases.json`` and print the deviations and timings;
``--suzanne`` also times Laplacian Smooth on the 126,290-vertex Suzanne-sub4;
``--crease-fixtures tests/data/blender_creases`` writes the creased-subdivision fixtures
(:data:`CREASE_CASES`) and stops.
"""

from __future__ import annotations

import json
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CACHE_DIR = Path(__file__).resolve().parent / ".cache"
WEIGHT_GROUP = "weights"
_TAG = "shapeflow_blender_ref"  # custom property marking the objects this module created

#: Details of the last timed evaluation: {"what", "samples", "baseline"} (seconds).
last_timing: dict = {}

_session_ready = False


# --------------------------------------------------------------------------- session


def available() -> bool:
    """True when Blender's ``bpy`` module can be imported."""
    try:
        import bpy  # noqa: F401
    except Exception:  # ImportError, or a broken install
        return False
    return True


def _bpy():
    import bpy

    global _session_ready
    if not _session_ready:
        # bpy-as-a-module starts with the factory startup file: a Cube, a Camera
        # and a Light.  Start from an empty scene so nothing but our objects is
        # evaluated by the depsgraph.
        bpy.ops.wm.read_factory_settings(use_empty=True)
        _session_ready = True
    return bpy


def clear_scene() -> None:
    """Delete every object (and its mesh) that this module created.

    Called at the start and end of :func:`laplacian_smooth` and
    :func:`subdivision_surface`, so repeated calls do not accumulate data
    blocks.  Objects not created here are left alone.
    """
    if not available():
        return
    bpy = _bpy()
    meshes = []
    for ob in list(bpy.data.objects):
        if ob.get(_TAG):
            if ob.type == "MESH" and ob.data is not None:
                meshes.append(ob.data)
            bpy.data.objects.remove(ob, do_unlink=True)
    for me in meshes:
        if me.users == 0:
            bpy.data.meshes.remove(me)
    for me in list(bpy.data.meshes):  # meshes made by make_object whose object is gone
        if me.get(_TAG) and me.users == 0:
            bpy.data.meshes.remove(me)


# --------------------------------------------------------------------------- building


def _as_csr(vertices, face_sizes, face_indices):
    V = np.ascontiguousarray(np.asarray(vertices, dtype=np.float64).reshape(-1, 3))
    fs = np.ascontiguousarray(np.asarray(face_sizes, dtype=np.int64).ravel())
    fi = np.ascontiguousarray(np.asarray(face_indices, dtype=np.int64).ravel())
    if fs.size and fs.min() < 3:
        raise ValueError("every face needs at least 3 corners")
    if int(fs.sum()) != fi.size:
        raise ValueError(f"sum(face_sizes)={int(fs.sum())} but len(face_indices)={fi.size}")
    if fi.size and (fi.min() < 0 or fi.max() >= len(V)):
        raise ValueError("face_indices out of range")
    return V, fs, fi


def make_object(vertices, face_sizes, face_indices, weights=None, name="obj"):
    """Build a Blender mesh object from CSR arrays, link it to the scene, return it.

    Bulk construction: ``mesh.vertices.add`` / ``loops.add`` / ``polygons.add``
    followed by ``foreach_set`` on ``co``, ``vertex_index``, ``loop_start`` and
    ``loop_total``; no Python loop over vertices or faces.  ``mesh.update(
    calc_edges=True)`` derives the edges; ``mesh.validate()`` then checks the
    result.  validate() may delete or rewrite invalid elements (degenerate or
    duplicate faces, repeated vertices in a face, ...), which would silently
    break the correspondence with the input, so the positions, corner vertices
    and face offsets are read back afterwards and a ValueError is raised if
    anything changed.  For valid input it changes nothing (checked on every
    fixture mesh); vertex order and face order are the input's.

    ``weights`` (n,) in [0, 1] become the vertex group ``"weights"``: one
    ``group.add(indices, w, 'REPLACE')`` call per *distinct* weight value
    (``np.unique``), which is the fastest route the Python API has (vertex
    groups are not exposed to ``foreach_set`` nor as attributes).  Every vertex
    is assigned, weight 0 included.
    """
    bpy = _bpy()
    V, fs, fi = _as_csr(vertices, face_sizes, face_indices)
    n, m, nl = len(V), len(fs), len(fi)
    loop_start = np.zeros(m, dtype=np.int32)
    if m:
        np.cumsum(fs[:-1], out=loop_start[1:])

    me = bpy.data.meshes.new(name)
    me[_TAG] = True
    me.vertices.add(n)
    me.loops.add(nl)
    me.polygons.add(m)
    co32 = V.astype(np.float32).ravel()
    me.vertices.foreach_set("co", co32)
    me.loops.foreach_set("vertex_index", fi.astype(np.int32))
    me.polygons.foreach_set("loop_start", loop_start)
    me.polygons.foreach_set("loop_total", fs.astype(np.int32))
    me.update(calc_edges=True)
    me.validate(verbose=False, clean_customdata=False)

    # validate() must not have changed anything we rely on.
    problems = []
    if (len(me.vertices), len(me.loops), len(me.polygons)) != (n, nl, m):
        problems.append(f"counts {(n, nl, m)} -> {(len(me.vertices), len(me.loops), len(me.polygons))}")
    else:
        back = np.empty(3 * n, dtype=np.float32)
        me.vertices.foreach_get("co", back)
        if not np.array_equal(back, co32):
            problems.append("vertex positions changed")
        corner = np.empty(nl, dtype=np.int32)
        me.loops.foreach_get("vertex_index", corner)
        if not np.array_equal(corner, fi):
            problems.append("corner vertices changed")
        ls = np.empty(m, dtype=np.int32)
        me.polygons.foreach_get("loop_start", ls)
        if not np.array_equal(ls, loop_start):
            problems.append("face offsets changed")
    if problems:
        bpy.data.meshes.remove(me)
        raise ValueError("Blender's Mesh.validate() altered the input mesh (invalid input?): " + "; ".join(problems))

    ob = bpy.data.objects.new(name, me)
    ob[_TAG] = True
    bpy.context.scene.collection.objects.link(ob)

    if weights is not None:
        w = np.asarray(weights, dtype=np.float64).ravel()
        if w.shape != (n,):
            raise ValueError(f"weights must have shape ({n},), got {w.shape}")
        if not np.all(np.isfinite(w)) or w.min() < 0.0 or w.max() > 1.0:
            raise ValueError("weights must lie in [0, 1]")
        vg = ob.vertex_groups.new(name=WEIGHT_GROUP)
        values, inverse = np.unique(w.astype(np.float32), return_inverse=True)
        order = np.argsort(inverse, kind="stable")
        bounds = np.searchsorted(inverse[order], np.arange(len(values) + 1))
        for k, value in enumerate(values):
            vg.add(order[bounds[k] : bounds[k + 1]].tolist(), float(value), "REPLACE")
    return ob


def _read_positions(mesh) -> np.ndarray:
    out = np.empty(3 * len(mesh.vertices), dtype=np.float32)
    mesh.vertices.foreach_get("co", out)
    return out.reshape(-1, 3).astype(np.float64)


def _read_faces(mesh):
    m = len(mesh.polygons)
    sizes = np.empty(m, dtype=np.int32)
    starts = np.empty(m, dtype=np.int32)
    mesh.polygons.foreach_get("loop_total", sizes)
    mesh.polygons.foreach_get("loop_start", starts)
    corner = np.empty(len(mesh.loops), dtype=np.int32)
    mesh.loops.foreach_get("vertex_index", corner)
    expected = np.zeros(m, dtype=np.int64)
    if m:
        np.cumsum(sizes[:-1], out=expected[1:])
    if not np.array_equal(starts, expected):  # not contiguous in face order: gather
        corner = np.concatenate([corner[s : s + k] for s, k in zip(starts, sizes)])
    return sizes.astype(np.int64), corner.astype(np.int64)


def _read_group_weights(ob_eval, mesh):
    """Weights of the ``"weights"`` vertex group on an evaluated mesh.

    The Python API has no bulk accessor for deform-vertex weights, so this is a
    loop over vertices (about 1 µs each); it runs outside the timed region.
    """
    gi = ob_eval.vertex_groups.find(WEIGHT_GROUP)
    if gi < 0:
        return None
    w = np.zeros(len(mesh.vertices), dtype=np.float64)
    for v in mesh.vertices:
        for g in v.groups:
            if g.group == gi:
                w[v.index] = g.weight
    return w


# --------------------------------------------------------------------------- timing


def _time_modifier(ob, mod, repeat, *, force_mesh=False):
    """Evaluate ``ob`` ``repeat`` times with ``mod`` switched on; return samples.

    The object is built and the depsgraph is created and evaluated with the
    modifier *disabled* (``show_viewport = False``) before any clock runs.  Each
    sample then switches the modifier on and times ``depsgraph.update()``
    (plus, with ``force_mesh``, the first access to the evaluated mesh — see
    :func:`subdivision_surface`), after which the modifier is switched off and
    the depsgraph updated again, untimed.  What is timed is therefore the
    re-evaluation of this one object's modifier stack; its cost without the
    modifier (a copy-on-evaluation of the mesh that shares the arrays, ~0.1 ms)
    is measured the same way and stored in ``last_timing["baseline"]``.
    """
    bpy = _bpy()
    mod.show_viewport = False
    dg = bpy.context.evaluated_depsgraph_get()

    def baseline_sample():
        ob.update_tag(refresh={"DATA"})
        t0 = time.perf_counter()
        dg.update()
        if force_mesh:
            len(ob.evaluated_get(dg).data.vertices)
        return time.perf_counter() - t0

    baseline = baseline_sample()
    samples = []
    for k in range(max(1, int(repeat))):
        mod.show_viewport = True
        t0 = time.perf_counter()
        dg.update()
        if force_mesh:
            len(ob.evaluated_get(dg).data.vertices)  # realizes the deferred subdivision
        samples.append(time.perf_counter() - t0)
        if k + 1 < repeat:
            mod.show_viewport = False
            dg.update()
    return dg, samples, baseline


# --------------------------------------------------------------------------- modifiers


def laplacian_smooth(
    vertices,
    face_sizes,
    face_indices,
    *,
    lambda_factor,
    lambda_border=0.0,
    iterations=1,
    use_normalized=True,
    use_volume_preserve=False,
    use_x=True,
    use_y=True,
    use_z=True,
    weights=None,
    invert_vertex_group=False,
    repeat=1,
):
    """Blender's Laplacian Smooth modifier on a mesh; returns (positions, seconds).

    Every setting is written explicitly: a new modifier in Blender 5 has
    ``use_volume_preserve=True`` and ``lambda_factor = lambda_border = 0.01``.
    ``weights`` (n,) become the vertex group the modifier reads
    (``invert_vertex_group`` applies to it; without weights it has no effect).

    Timing (``seconds`` is the median of ``repeat`` samples): the object is
    created and the depsgraph evaluated with the modifier disabled before the
    clock starts; each sample enables the modifier and times
    ``depsgraph.update()``, i.e. the modifier's evaluation (matrix build and
    OpenNL solves) plus Blender's negligible per-object bookkeeping (measured
    ~0.1 ms on a 126k-vertex mesh, kept in ``last_timing["baseline"]``).  The
    positions are read with ``foreach_get`` from ``obj.evaluated_get(depsgraph)``
    outside the timed region.  Returns float64 positions (n, 3), in the input's
    vertex order (the modifier never reorders).
    """
    _bpy()   # imports Blender (and checks it is there)
    clear_scene()
    try:
        ob = make_object(vertices, face_sizes, face_indices, weights=weights, name="smooth")
        mod = ob.modifiers.new("LaplacianSmooth", "LAPLACIANSMOOTH")
        mod.show_viewport = False
        mod.lambda_factor = float(lambda_factor)
        mod.lambda_border = float(lambda_border)
        mod.iterations = int(iterations)
        mod.use_normalized = bool(use_normalized)
        mod.use_volume_preserve = bool(use_volume_preserve)
        mod.use_x, mod.use_y, mod.use_z = bool(use_x), bool(use_y), bool(use_z)
        mod.vertex_group = WEIGHT_GROUP if weights is not None else ""
        mod.invert_vertex_group = bool(invert_vertex_group)
        dg, samples, baseline = _time_modifier(ob, mod, repeat)
        me_eval = ob.evaluated_get(dg).data
        if len(me_eval.vertices) != len(ob.data.vertices):
            raise RuntimeError("evaluated mesh has a different vertex count")
        positions = _read_positions(me_eval)
    finally:
        clear_scene()
    last_timing.clear()
    last_timing.update(what="laplacian_smooth", samples=samples, baseline=baseline)
    return positions, statistics.median(samples)


def subdivision_surface(
    vertices,
    face_sizes,
    face_indices,
    *,
    levels=1,
    subdivision_type="CATMULL_CLARK",
    boundary_smooth="ALL",
    weights=None,
    repeat=1,
    use_limit_surface=False,
    creases=None,
):
    """Blender's Subdivision Surface modifier (creases off unless ``creases`` is given).

    Returns ``(positions (N,3) float64, face_sizes, face_indices, result_weights
    or None, seconds_median)``.  ``result_weights`` is the ``"weights"`` vertex
    group as Blender interpolated it onto the subdivided mesh (read from the
    evaluated mesh).  Blender lists the original vertices first; the order of
    the new ones is Blender's own.  ``use_limit_surface`` defaults to False
    (plain Catmull-Clark points) as in the fixtures.

    Timing quirk: Blender defers the last Subdivision Surface modifier (a mesh
    "wrapper" kept for GPU subdivision, also in background mode), so
    ``depsgraph.update()`` alone costs microseconds and the subdivision runs on
    the first access to the evaluated mesh.  Each timed sample therefore
    includes that first access.  OpenSubdiv's topology refiner is cached by
    Blender between re-evaluations of an unchanged mesh, so samples after the
    first can be a little faster.
    """
    if subdivision_type not in ("CATMULL_CLARK", "SIMPLE"):
        raise ValueError("subdivision_type must be 'CATMULL_CLARK' or 'SIMPLE'")
    if boundary_smooth not in ("ALL", "PRESERVE_CORNERS"):
        raise ValueError("boundary_smooth must be 'ALL' or 'PRESERVE_CORNERS'")
    _bpy()   # imports Blender (and checks it is there)
    clear_scene()
    try:
        ob = make_object(vertices, face_sizes, face_indices, weights=weights, name="subdiv")
        if creases is not None:
            set_edge_creases(ob.data, *creases)
        mod = ob.modifiers.new("Subdivision", "SUBSURF")
        mod.show_viewport = False
        mod.subdivision_type = subdivision_type
        mod.levels = int(levels)  # viewport level: the depsgraph here is VIEWPORT
        mod.render_levels = int(levels)
        mod.boundary_smooth = boundary_smooth
        mod.use_limit_surface = bool(use_limit_surface)
        mod.use_creases = creases is not None
        mod.use_custom_normals = False
        dg, samples, baseline = _time_modifier(ob, mod, repeat, force_mesh=True)
        ob_eval = ob.evaluated_get(dg)
        me = ob_eval.to_mesh()
        try:
            positions = _read_positions(me)
            sizes, corners = _read_faces(me)
            result_weights = _read_group_weights(ob_eval, me) if weights is not None else None
        finally:
            ob_eval.to_mesh_clear()
    finally:
        clear_scene()
    last_timing.clear()
    last_timing.update(what="subdivision_surface", samples=samples, baseline=baseline)
    return positions, sizes, corners, result_weights, statistics.median(samples)


def set_edge_creases(me, pairs, values) -> None:
    """Write creases (vertex pairs (k, 2), values (k,)) to the ``crease_edge`` EDGE attribute of ``me``.

    Blender's edges come from ``calc_edges``; each pair is looked up among them (ValueError if a
    pair is not an edge).  Bulk ``foreach_get``/``foreach_set``, no loop over edges.
    """
    E = np.empty(2 * len(me.edges), dtype=np.int32)
    me.edges.foreach_get("vertices", E)
    E = np.sort(E.reshape(-1, 2).astype(np.int64), axis=1)
    n = max(len(me.vertices), 1)
    keys = E[:, 0] * n + E[:, 1]
    order = np.argsort(keys)
    p = np.sort(np.asarray(pairs, dtype=np.int64).reshape(-1, 2), axis=1)
    want = p[:, 0] * n + p[:, 1]
    pos = order[np.minimum(np.searchsorted(keys[order], want), len(order) - 1)]
    if len(want) and not np.array_equal(keys[pos], want):
        raise ValueError("a crease names a vertex pair that is not an edge of the mesh")
    c = np.zeros(len(E), dtype=np.float32)
    c[pos] = np.asarray(values, dtype=np.float32).reshape(-1)
    attr = me.attributes.get("crease_edge") or me.attributes.new("crease_edge", "FLOAT", "EDGE")
    attr.data.foreach_set("value", c)


# --------------------------------------------------------------------------- Suzanne


def suzanne_sub4(cache: bool = True):
    """Blender's Suzanne subdivided 4 times: 126,290 vertices, 125,952 quads.

    Built with ``bpy.ops.mesh.primitive_monkey_add()`` and a Subdivision Surface
    modifier at level 4 with Blender's defaults (Catmull-Clark, limit surface
    on, as for the fixture mesh ``suzanne_sub2``), creases off.  Returns
    ``(vertices float64 (n,3), face_sizes int64, face_indices int64)``.  The
    result is cached in ``benchmarks/.cache/suzanne_sub4.npz`` and loaded from
    there without needing ``bpy``.
    """
    path = CACHE_DIR / "suzanne_sub4.npz"
    if cache and path.exists():
        d = np.load(path)
        return d["vertices"], d["face_sizes"], d["face_indices"]
    if not available():
        raise RuntimeError(f"bpy is not installed and {path} does not exist")
    bpy = _bpy()
    clear_scene()
    try:
        bpy.ops.mesh.primitive_monkey_add()
        ob = bpy.context.active_object
        ob[_TAG] = True
        ob.data[_TAG] = True
        V0, fs0, fi0 = _read_positions(ob.data), *_read_faces(ob.data)
    finally:
        clear_scene()
    V, fs, fi, _, _ = subdivision_surface(V0, fs0, fi0, levels=4, use_limit_surface=True)
    if cache:
        CACHE_DIR.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp.npz")
        np.savez_compressed(tmp, vertices=V, face_sizes=fs, face_indices=fi)
        os.replace(tmp, path)
    return V, fs, fi


# --------------------------------------------------------------------------- crease fixtures


def _crease_meshes() -> dict:
    """The small meshes of the crease fixtures, built with NumPy: (vertices, face lists, creases (pairs, values))."""
    rng = np.random.default_rng(2026)
    out = {}
    # triangles: an icosahedron, creased along a closed loop of edges and a dart
    t = (1 + 5 ** 0.5) / 2
    V = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t],
                  [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], float)
    F = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6],
         [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10],
         [8, 6, 7], [9, 8, 1]]
    out["tri"] = (V, F, ([[0, 11], [11, 5], [5, 1], [1, 0], [3, 6]], [1.0, 0.45, 0.2, 0.7, 0.3]))
    # quads: a box, 2 × 2 quads a side, its edges creased (1, 1/2, 1/4, 0.1 ...), one dart inside a side
    g = np.linspace(-1, 1, 3)
    P = np.array([[x, y, z] for x in g for y in g for z in g])
    P = P[np.abs(P).max(axis=1) == 1]
    key = {tuple(p): i for i, p in enumerate(P.tolist())}
    F = []
    for axis in range(3):
        for sgn in (-1, 1):
            u, v = [a for a in range(3) if a != axis]
            for i in range(2):
                for j in range(2):
                    corner = []
                    for du, dv in ((0, 0), (1, 0), (1, 1), (0, 1)):
                        q = [0.0, 0.0, 0.0]
                        q[axis], q[u], q[v] = sgn, g[i + du], g[j + dv]
                        corner.append(key[tuple(q)])
                    F.append(corner if (sgn > 0) == (axis != 1) else corner[::-1])
    edges = {tuple(sorted((f[k], f[(k + 1) % 4]))) for f in F for k in range(4)}
    box_edges = np.array([e for e in sorted(edges) if (np.abs(P[list(e)]) == 1).sum(axis=1).min() >= 2])
    vals = rng.choice([1.0, 0.5, 0.25, 0.1, 0.8], size=len(box_edges))
    dart = [[key[(1.0, 0.0, 0.0)], key[(1.0, 1.0, 0.0)]]]
    P = P * [1.0, 0.8, 0.6] + 0.03 * rng.standard_normal(P.shape)
    out["quad"] = (P, F, (np.r_[box_edges, dart], np.r_[vals, 0.6]))
    # n-gons: a hexagonal prism with hexagon caps, one side split into triangles
    a = np.arange(6) * np.pi / 3
    V = np.r_[np.c_[np.cos(a), np.sin(a), np.zeros(6)], np.c_[0.8 * np.cos(a), 0.8 * np.sin(a), np.ones(6)]]
    F = [[5, 4, 3, 2, 1, 0], [6, 7, 8, 9, 10, 11], [0, 1, 7], [0, 7, 6]] + \
        [[k, k + 1, k + 7, k + 6] for k in range(1, 5)] + [[5, 0, 6, 11]]
    rim = [[k, (k + 1) % 6] for k in range(6)] + [[6 + k, 6 + (k + 1) % 6] for k in range(6)]
    out["ngon"] = (V, F, (rim + [[0, 6], [3, 9]], [0.6] * 6 + [1.0, 0.35, 0.9, 0.15, 0.5, 0.75] + [0.2, 1.0]))
    # open: a 4 × 3 grid of quads and triangles and a pentagon, creases inside and onto the border
    xs, ys = np.meshgrid(np.arange(5.0), np.arange(4.0), indexing="ij")
    V = np.c_[xs.ravel(), ys.ravel(), 0.3 * np.sin(xs.ravel()) * np.cos(ys.ravel())]
    idx = lambda i, j: i * 4 + j  # noqa: E731
    F = []
    for i in range(4):
        for j in range(3):
            q = [idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)]
            if (i, j) in ((1, 1), (2, 0)):
                F += [q[:3], [q[0], q[2], q[3]]]
            elif (i, j) != (3, 2):
                F.append(q)
    V = np.r_[V, [[3.5, 3.6, 0.1]]]                           # a pentagon on the border
    F.append([idx(3, 2), idx(4, 2), idx(4, 3), len(V) - 1, idx(3, 3)])
    cre = [[idx(1, 0), idx(1, 1)], [idx(1, 1), idx(1, 2)], [idx(1, 2), idx(1, 3)], [idx(0, 2), idx(1, 2)],
           [idx(1, 2), idx(2, 2)], [idx(2, 2), idx(3, 2)], [idx(3, 1), idx(3, 2)]]
    out["open"] = (V, F, (cre, [1.0, 0.55, 0.25, 0.4, 0.85, 0.12, 1.0]))
    return out


#: crease fixture cases: name -> (mesh, levels, boundary_smooth, with weights)
CREASE_CASES = {
    "tri_1": ("tri", 1, "ALL", False), "tri_3": ("tri", 3, "ALL", True),
    "quad_2": ("quad", 2, "ALL", False), "quad_3": ("quad", 3, "ALL", True),
    "ngon_1": ("ngon", 1, "ALL", True), "ngon_2": ("ngon", 2, "ALL", False), "ngon_3": ("ngon", 3, "ALL", False),
    "open_all_1": ("open", 1, "ALL", False), "open_all_2": ("open", 2, "ALL", True),
    "open_all_3": ("open", 3, "ALL", False), "open_corners_1": ("open", 1, "PRESERVE_CORNERS", True),
    "open_corners_2": ("open", 2, "PRESERVE_CORNERS", False), "open_corners_3": ("open", 3, "PRESERVE_CORNERS", True),
}


def crease_fixtures(out_dir) -> list:
    """Run Blender's Subdivision Surface with creases on every :data:`CREASE_CASES` case and write
    ``<case>.npz`` files to ``out_dir``: the input (float32-exact positions, faces, creases, weights)
    and Blender's result (positions, faces, interpolated weights).  Returns the files written."""
    import bpy

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    meshes = _crease_meshes()
    written = []
    for name, (mesh, levels, boundary, with_weights) in CREASE_CASES.items():
        V, F, (pairs, values) = meshes[mesh]
        V = np.asarray(V, float).astype(np.float32).astype(np.float64)     # what Blender stores
        fs = np.array([len(f) for f in F], np.int32)
        fi = np.concatenate([np.asarray(f) for f in F]).astype(np.int32)
        pairs = np.asarray(pairs, np.int32).reshape(-1, 2)
        values = np.asarray(values, np.float32)
        w = np.linspace(0.0, 1.0, len(V)).astype(np.float32) if with_weights else None
        P, rfs, rfi, rw, _ = subdivision_surface(V, fs, fi, levels=levels, boundary_smooth=boundary, weights=w,
                                                 creases=(pairs, values))
        data = dict(vertices=V, face_sizes=fs, face_indices=fi, crease_edges=pairs, crease_values=values,
                    levels=levels, boundary_smooth=boundary, result=P.astype(np.float32),
                    result_face_sizes=rfs.astype(np.int32), result_face_indices=rfi.astype(np.int32),
                    blender=bpy.app.version_string)
        if w is not None:
            data.update(weights=w, result_weights=rw.astype(np.float32))
        path = out_dir / f"{name}.npz"
        np.savez_compressed(path, **data)
        written.append(path)
    return written


# --------------------------------------------------------------------------- main


def _find_fixtures() -> Path | None:
    env = os.environ.get("SHAPEFLOW_SHARED")
    cands = [Path(env)] if env else []
    cands += [ROOT.parent / "shared", ROOT / "shared", Path("/work/shared")]
    for c in cands:
        if (c / "fixtures" / "blender" / "cases.json").is_file():
            return c / "fixtures" / "blender"
    return None


def load_mesh(fixtures: Path, name: str):
    d = np.load(fixtures / "meshes" / f"{name}.npz")
    return d["vertices"], d["face_sizes"], d["face_indices"]


def load_case(fixtures: Path, case: str) -> dict:
    d = np.load(fixtures / "cases" / f"{case}.npz")
    out = {k: d[k] for k in d.files}
    out["params"] = json.loads(str(out["params"]))
    out["mesh"] = str(out["mesh"])
    return out


def diagonal(points) -> float:
    p = np.asarray(points, dtype=np.float64)
    return float(np.linalg.norm(p.max(axis=0) - p.min(axis=0)))


def run_case(fixtures: Path, case: str, repeat: int = 1) -> dict:
    """Re-run one fixture case; return deviations relative to the bbox diagonal."""
    from scipy.spatial import cKDTree

    c = load_case(fixtures, case)
    V, fs, fi = load_mesh(fixtures, c["mesh"])
    p = dict(c["params"])
    weights = c.get("weights")
    p.pop("weights", None)
    diag = diagonal(c["result"])
    if case.startswith("subdiv_"):
        P, rfs, rfi, rw, secs = subdivision_surface(V, fs, fi, weights=weights, repeat=repeat, **p)
        same_shape = P.shape == c["result"].shape
        dev_set = float(cKDTree(P).query(c["result"])[0].max()) / diag
        dev_ord = float(np.abs(P - c["result"]).max()) / diag if same_shape else float("inf")
        out = dict(kind="subdivision", dev=dev_set, dev_ordered=dev_ord,
                   faces_equal=bool(np.array_equal(rfs, c["result_face_sizes"])
                                    and np.array_equal(rfi, c["result_face_indices"])))
        if rw is not None and "result_weights" in c:
            out["weight_dev"] = float(np.abs(rw - c["result_weights"]).max()) if same_shape else float("inf")
    else:
        P, secs = laplacian_smooth(V, fs, fi, weights=weights, repeat=repeat, **p)
        out = dict(kind="laplacian_smooth", dev=float(np.abs(P - c["result"]).max()) / diag)
    out["seconds"] = secs
    return out


def time_suzanne(repeat: int = 3) -> tuple[float, int, list[float]]:
    V, fs, fi = suzanne_sub4()
    _, secs = laplacian_smooth(V, fs, fi, lambda_factor=1.0, lambda_border=0.0, iterations=1,
                               use_normalized=True, use_volume_preserve=False, repeat=repeat)
    return secs, len(V), list(last_timing["samples"])


def main(argv=None) -> int:
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=1, help="timing samples per case")
    ap.add_argument("--suzanne", action="store_true", 
                    help="also time Laplacian Smooth on Suzanne-sub4 (3 samples, ~30 s)")
    ap.add_argument("--crease-fixtures", metavar="DIR",
                    help="write the creased-subdivision fixtures (CREASE_CASES) to DIR and stop")
    ap.add_argument("cases", nargs="*", help="case names (default: all in cases.json)")
    args = ap.parse_args(argv)
    if not available():
        print("bpy is not importable: pip install bpy==5.0.1 (Python 3.11)", file=sys.stderr)
        return 2
    import bpy

    if args.crease_fixtures:
        files = crease_fixtures(args.crease_fixtures)
        total = sum(f.stat().st_size for f in files)
        print(f"Blender {bpy.app.version_string}: {len(files)} crease fixtures, {total / 1024:.0f} KB, "
              f"in {args.crease_fixtures}")
        return 0

    fixtures = _find_fixtures()
    if fixtures is None:
        print("shared/fixtures/blender not found (set SHAPEFLOW_SHARED)", file=sys.stderr)
        return 2
    meta = json.loads((fixtures / "cases.json").read_text())
    print(f"Blender {bpy.app.version_string} (fixtures from {meta.get('blender_version')}), {fixtures}")
    names = args.cases or sorted(meta["cases"])
    worst: dict[str, float] = {}
    ratios = []
    print(f"{'case':58s} {'dev/diag':>10s} {'ours s':>9s} {'fixture s':>9s}")
    for name in names:
        r = run_case(fixtures, name, repeat=args.repeat)
        ref = meta["cases"][name].get("blender_seconds")
        extra = ""
        if r["kind"] == "subdivision":
            extra = f"  ordered={r['dev_ordered']:.1e} faces_equal={r['faces_equal']}"
            if "weight_dev" in r:
                extra += f" weights={r['weight_dev']:.1e}"
        print(f"{name:58s} {r['dev']:10.2e} {r['seconds']:9.4f} {ref if ref is not None else float('nan'):9.4f}{extra}")
        worst[r["kind"]] = max(worst.get(r["kind"], 0.0), r["dev"])
        if ref:
            ratios.append(r["seconds"] / ref)
    for kind, dev in sorted(worst.items()):
        print(f"max deviation / bbox diagonal, {kind}: {dev:.3e}")
    if ratios:
        print(f"timing ours/fixture: median {statistics.median(ratios):.2f}x")
    if args.suzanne:
        secs, n, samples = time_suzanne(3)
        print(f"Suzanne-sub4 ({n} vertices) Laplacian Smooth, normalized, 1 iteration, lambda 1.0: "
              f"median {secs:.2f} s of {[round(s, 2) for s in samples]} "
              f"(baseline {last_timing['baseline'] * 1e3:.2f} ms)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
