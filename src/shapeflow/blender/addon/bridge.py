"""Blender mesh <-> shapeflow arrays, in bulk.

Positions, faces, selection, UVs, material indices, smooth flags and edge data
(vertex pairs, ``sharp_edge`` flags, ``crease_edge`` values) go through
``foreach_get``/``foreach_set`` on whole arrays: no Python loop over vertices,
corners or faces.  Where Blender 4.x stores the data as a generic attribute
(``position``, ``.corner_vert``, ``.select_vert``, ``.hide_vert``) the
attribute's ``foreach_get`` is used: it copies the array in one go (0.1 ms for
126K positions, against 4 ms through ``vertices.foreach_get("co")`` and 33 ms
for 500K corners through ``loops.foreach_get("vertex_index")``), with the
classic ``MeshVertex``/``MeshLoop`` accessors as the fallback.  Face sizes
follow from ``loop_start`` (faces are stored as offsets since Blender 4.0).

Vertex-group weights have no bulk accessor in Blender's Python API (they are
not exposed as attributes, and ``foreach_get`` cannot reach ``vertex.groups``).
They are read by evaluating a throw-away object that shares the mesh and
carries a tiny Geometry Nodes modifier (*Named Attribute* → *Store Named
Attribute*), which copies each group into a float point attribute of the
evaluated mesh; that attribute is then read with ``foreach_get``.  On the
126,290-vertex Suzanne this takes ~16 ms where the per-vertex loop takes
~570 ms.  Should the node setup fail (an API change), the per-vertex loop is
used instead.  Weights are written with one ``VertexGroup.add`` call per
distinct value.

Caches (one entry each, cleared on unregister and when a file is loaded):
the shapeflow :class:`~shapeflow.Mesh` of the last face layout seen (its
topology and cotangent structure are what an *Adjust Last Operation* re-run
can reuse), and the last :class:`~shapeflow.FlowSolver` together with the
positions and weights it was built for.
"""

import bpy
import numpy as np

GROUP_ATTR_PREFIX = "__shapeflow_group_"

_mesh_cache: dict = {}
_solver_cache: dict = {}


def clear_caches() -> None:
    _mesh_cache.clear()
    _solver_cache.clear()


# --------------------------------------------------------------------------
# positions, faces, selection
# --------------------------------------------------------------------------

def _attribute(me, name, domain, data_type):
    """The generic attribute ``name`` if it exists with that domain and type (bulk access), else None."""
    a = me.attributes.get(name)
    if a is not None and a.domain == domain and a.data_type == data_type:
        return a
    return None


def read_positions(me) -> np.ndarray:
    """(n, 3) float64 vertex positions (object space)."""
    co = np.empty(3 * len(me.vertices), dtype=np.float32)
    a = _attribute(me, "position", "POINT", "FLOAT_VECTOR")
    if a is not None:  # one memcpy-like copy (~0.1 ms for 126K vertices)
        a.data.foreach_get("vector", co)
    else:  # per-element RNA access (~4 ms for 126K vertices)
        me.vertices.foreach_get("co", co)
    return co.reshape(-1, 3).astype(np.float64)


def write_positions(me, V) -> None:
    """Set every vertex position from an (n, 3) array and tag the mesh for update."""
    co = np.ascontiguousarray(np.asarray(V, dtype=np.float32).reshape(-1))
    if co.size != 3 * len(me.vertices):
        raise ValueError(f"expected {len(me.vertices)} positions, got {co.size // 3}")
    a = _attribute(me, "position", "POINT", "FLOAT_VECTOR")
    if a is not None:
        a.data.foreach_set("vector", co)
    else:
        me.vertices.foreach_set("co", co)
    me.update()  # normals and the evaluated mesh follow the new positions


def _edit_key(ob):
    """The shape key edits go to (the active one), or None for a mesh without shape keys."""
    if ob.data.shape_keys is None:
        return None
    return ob.active_shape_key or ob.data.shape_keys.reference_key


def read_object_positions(ob) -> np.ndarray:
    """Positions of the shape being edited: the active shape key if the mesh has keys, else the mesh."""
    key = _edit_key(ob)
    if key is None:
        return read_positions(ob.data)
    co = np.empty(3 * len(key.data), dtype=np.float32)
    key.data.foreach_get("co", co)
    return co.reshape(-1, 3).astype(np.float64)


def write_object_positions(ob, V) -> None:
    """Write the shape being edited: the active shape key (and the mesh if it is the Basis), else the mesh.

    Writing only the mesh positions of a mesh with shape keys would be undone
    the next time Edit Mode loads the key.
    """
    key = _edit_key(ob)
    if key is None:
        write_positions(ob.data, V)
        return
    co = np.ascontiguousarray(np.asarray(V, dtype=np.float32).reshape(-1))
    key.data.foreach_set("co", co)
    if key == ob.data.shape_keys.reference_key:
        write_positions(ob.data, V)
    else:
        ob.data.update()


def read_faces(me) -> tuple[np.ndarray, np.ndarray]:
    """Face sizes (m,) and corner vertices in face order (Σ sizes,), int64."""
    m, nl = len(me.polygons), len(me.loops)
    starts = np.empty(m, dtype=np.int32)
    me.polygons.foreach_get("loop_start", starts)
    a = _attribute(me, ".corner_vert", "CORNER", "INT")
    corners = np.empty(nl, dtype=np.int32)
    if a is not None:
        a.data.foreach_get("value", corners)
    else:
        me.loops.foreach_get("vertex_index", corners)
    # Blender 4.x stores faces as offsets into the corners: sizes follow from the starts
    bounds = np.append(starts.astype(np.int64), nl)
    sizes = np.diff(bounds)
    if m and (starts[0] != 0 or (sizes <= 0).any()):  # not face after face: ask for sizes, gather
        sz = np.empty(m, dtype=np.int32)
        me.polygons.foreach_get("loop_total", sz)
        sizes = sz.astype(np.int64)
        corners = corners[corner_order(starts, sizes)]
    return sizes, corners.astype(np.int64)


def corner_order(starts, sizes) -> np.ndarray:
    """Loop indices of every face's corners, face after face."""
    sizes = np.asarray(sizes, dtype=np.int64)
    first = np.zeros(sizes.size, dtype=np.int64)
    if sizes.size:
        np.cumsum(sizes[:-1], out=first[1:])
    return np.repeat(np.asarray(starts, dtype=np.int64) - first, sizes) + np.arange(int(sizes.sum()))


def _read_flag(me, attr_name, prop):
    n = len(me.vertices)
    out = np.zeros(n, dtype=bool)
    a = _attribute(me, attr_name, "POINT", "BOOLEAN")
    if a is not None:
        a.data.foreach_get("value", out)
    elif attr_name not in me.attributes:  # Blender creates the flag layers only once used
        return out
    else:
        me.vertices.foreach_get(prop, out)
    return out


def read_selection(me) -> np.ndarray:
    """Selected and visible vertices (bool mask) of an object-mode mesh."""
    return _read_flag(me, ".select_vert", "select") & ~_read_flag(me, ".hide_vert", "hide")


def bounding_diagonal(V) -> float:
    V = np.asarray(V)
    if V.size == 0:
        return 0.0
    return float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))


# --------------------------------------------------------------------------
# edges: vertex pairs, sharp flags and creases
# --------------------------------------------------------------------------

def read_edges(me) -> np.ndarray:
    """(E, 2) int64 vertex pairs of the mesh's edges, in Blender's edge order."""
    ev = np.empty(2 * len(me.edges), dtype=np.int32)
    a = _attribute(me, ".edge_verts", "EDGE", "INT32_2D")
    if a is not None:
        a.data.foreach_get("value", ev)
    else:
        me.edges.foreach_get("vertices", ev)
    return ev.reshape(-1, 2).astype(np.int64)


def read_edge_values(me, name, data_type) -> np.ndarray | None:
    """The EDGE attribute ``name`` of that type ((E,) float64 or bool), or None where the mesh has none."""
    a = _attribute(me, name, "EDGE", data_type)
    if a is None:
        return None
    out = np.empty(len(me.edges), dtype=bool if data_type == "BOOLEAN" else np.float32)
    a.data.foreach_get("value", out)
    return out if data_type == "BOOLEAN" else out.astype(np.float64)


def read_sharp_flags(me) -> np.ndarray:
    """Edges marked Sharp (the boolean ``sharp_edge`` attribute), as an (E,) mask."""
    v = read_edge_values(me, "sharp_edge", "BOOLEAN")
    return np.zeros(len(me.edges), dtype=bool) if v is None else v


def read_creases(me) -> np.ndarray:
    """Edge creases in [0, 1] (the float ``crease_edge`` attribute), (E,); zeros where the mesh has none."""
    v = read_edge_values(me, "crease_edge", "FLOAT")
    return np.zeros(len(me.edges)) if v is None else np.clip(np.nan_to_num(v), 0.0, 1.0)


def edge_rows(me, pairs) -> np.ndarray:
    """Blender's edge index of each vertex pair (k, 2), either order; -1 where the mesh has no such edge."""
    E = read_edges(me)
    n = np.int64(max(len(me.vertices), 1))
    key = np.minimum(E[:, 0], E[:, 1]) * n + np.maximum(E[:, 0], E[:, 1])
    order = np.argsort(key, kind="stable")
    p = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    want = np.minimum(p[:, 0], p[:, 1]) * n + np.maximum(p[:, 0], p[:, 1])
    pos = np.minimum(np.searchsorted(key[order], want), max(key.size - 1, 0))
    found = key[order][pos] == want if key.size else np.zeros(want.size, dtype=bool)
    return np.where(found, order[pos] if key.size else -1, -1)


def write_edge_values(me, name, data_type, pairs, values) -> None:
    """Set the EDGE attribute ``name`` to ``values`` on the edges ``pairs`` (0 / False on every other
    edge), creating it; nothing is created when no pair is given."""
    rows = edge_rows(me, pairs) if len(pairs) else np.zeros(0, dtype=np.int64)
    if rows.size == 0 and me.attributes.get(name) is None:
        return
    if (rows < 0).any():
        raise ValueError(f"{int((rows < 0).sum())} of the {name} pairs are not edges of mesh '{me.name}'")
    a = _attribute(me, name, "EDGE", data_type)
    if a is None:
        if me.attributes.get(name) is not None:
            me.attributes.remove(me.attributes[name])
        a = me.attributes.new(name, data_type, "EDGE")
    out = np.zeros(len(me.edges), dtype=bool if data_type == "BOOLEAN" else np.float32)
    out[rows] = values
    a.data.foreach_set("value", out)


# --------------------------------------------------------------------------
# vertex groups
# --------------------------------------------------------------------------

def _socket(sockets, name):
    """The float-capable socket called ``name`` (several share a name in some versions)."""
    cands = [s for s in sockets if s.name == name]
    for s in cands:
        if getattr(s, "type", "") in ("VALUE", "FLOAT") and getattr(s, "enabled", True):
            return s
    for s in cands:
        if getattr(s, "enabled", True):
            return s
    if cands:
        return cands[0]
    raise KeyError(name)


def _reader_tree(names):
    ng = bpy.data.node_groups.new(".shapeflow_read_groups", "GeometryNodeTree")
    iface = ng.interface
    iface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    iface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    gin = ng.nodes.new("NodeGroupInput")
    gout = ng.nodes.new("NodeGroupOutput")
    geo = gin.outputs[0]
    for i, name in enumerate(names):
        named = ng.nodes.new("GeometryNodeInputNamedAttribute")
        named.data_type = "FLOAT"
        named.inputs["Name"].default_value = name
        store = ng.nodes.new("GeometryNodeStoreNamedAttribute")
        store.data_type = "FLOAT"
        store.domain = "POINT"
        store.inputs["Name"].default_value = f"{GROUP_ATTR_PREFIX}{i}"
        ng.links.new(geo, store.inputs["Geometry"])
        ng.links.new(_socket(named.outputs, "Attribute"), _socket(store.inputs, "Value"))
        geo = store.outputs["Geometry"] if "Geometry" in store.outputs else store.outputs[0]
    ng.links.new(geo, gout.inputs[0])
    return ng


def _read_groups_nodes(context, ob, names) -> list[np.ndarray]:
    me = ob.data
    n = len(me.vertices)
    ng = tmp = None
    try:
        ng = _reader_tree(names)
        tmp = bpy.data.objects.new(".shapeflow_read_groups", me)  # shares the mesh: same groups
        context.scene.collection.objects.link(tmp)
        mod = tmp.modifiers.new("shapeflow", "NODES")
        mod.node_group = ng
        dg = context.evaluated_depsgraph_get()
        dg.update()
        me_eval = tmp.evaluated_get(dg).data
        if len(me_eval.vertices) != n:
            raise RuntimeError("evaluated mesh has a different vertex count")
        out = []
        for i in range(len(names)):
            attr = me_eval.attributes.get(f"{GROUP_ATTR_PREFIX}{i}")
            if attr is None or attr.domain != "POINT" or len(attr.data) != n:
                raise RuntimeError("the weights attribute is missing on the evaluated mesh")
            w = np.empty(n, dtype=np.float32)
            attr.data.foreach_get("value", w)
            out.append(w.astype(np.float64))
        return out
    finally:
        if tmp is not None:
            bpy.data.objects.remove(tmp, do_unlink=True)
        if ng is not None:
            bpy.data.node_groups.remove(ng)


def _read_groups_loop(ob, names) -> list[np.ndarray]:
    me = ob.data
    n = len(me.vertices)
    index = {ob.vertex_groups[name].index: k for k, name in enumerate(names)}
    out = [np.zeros(n) for _ in names]
    for v in me.vertices:  # fallback only: ~4.5 µs per vertex
        for g in v.groups:
            k = index.get(g.group)
            if k is not None:
                out[k][v.index] = g.weight
    return out


def read_vertex_groups(context, ob, names) -> list[np.ndarray]:
    """Weights (n,) of the named vertex groups (0 where a vertex is not in a group).

    The object must be in Object mode (the mesh arrays are read, not the edit BMesh).
    """
    names = list(names)
    missing = [nm for nm in names if ob.vertex_groups.get(nm) is None]
    if missing:
        raise KeyError(f"object '{ob.name}' has no vertex group {missing[0]!r}")
    if not names:
        return []
    if len(ob.data.vertices) == 0:
        return [np.zeros(0) for _ in names]
    try:
        return _read_groups_nodes(context, ob, names)
    except Exception:  # node API differences: fall back to the exact, slower loop
        return _read_groups_loop(ob, names)


def read_vertex_group(context, ob, name) -> np.ndarray:
    return read_vertex_groups(context, ob, [name])[0]


def write_vertex_group(ob, name, weights) -> None:
    """Create (or fill) the vertex group ``name`` with per-vertex weights; 0 = not assigned."""
    vg = ob.vertex_groups.get(name) or ob.vertex_groups.new(name=name)
    w = np.asarray(weights, dtype=np.float32).ravel()
    nz = np.flatnonzero(w > 0)
    if nz.size == 0:
        return
    vals, inv = np.unique(w[nz], return_inverse=True)
    order = np.argsort(inv, kind="stable")
    bounds = np.searchsorted(inv[order], np.arange(vals.size + 1))
    members = nz[order]
    for k, val in enumerate(vals):  # one call per distinct weight, not per vertex
        vg.add(members[bounds[k]:bounds[k + 1]].tolist(), float(val), "REPLACE")


# --------------------------------------------------------------------------
# building meshes
# --------------------------------------------------------------------------

def new_mesh(name, V, sizes, corners):
    """A new Blender mesh from CSR arrays (edges derived from the faces)."""
    V = np.asarray(V, dtype=np.float64).reshape(-1, 3)
    sizes = np.asarray(sizes, dtype=np.int64)
    corners = np.asarray(corners, dtype=np.int64)
    me = bpy.data.meshes.new(name)
    me.vertices.add(len(V))
    me.loops.add(len(corners))
    me.polygons.add(len(sizes))
    co = np.ascontiguousarray(V.astype(np.float32).ravel())
    a = _attribute(me, "position", "POINT", "FLOAT_VECTOR")
    (a.data.foreach_set("vector", co) if a is not None else me.vertices.foreach_set("co", co))
    me.loops.foreach_set("vertex_index", corners.astype(np.int32))
    starts = np.zeros(len(sizes), dtype=np.int32)
    if len(sizes):
        np.cumsum(sizes[:-1], out=starts[1:])
    me.polygons.foreach_set("loop_start", starts)  # face sizes follow from the offsets (Blender 4.0+)
    me.update(calc_edges=True)
    drop_bad_edge_selection(me)
    return me


def drop_bad_edge_selection(me) -> None:
    """Remove an edge-selection layer of the wrong type.

    Blender 5.0.1's ``update(calc_edges=True)`` (and ``from_pydata``) on a mesh without edges leaves
    ``.select_edge`` typed like the edges' vertex pairs (INT32_2D); writing edge selection through
    ``foreach_set`` then crashes Blender.  Without the layer Blender makes a proper one when needed.
    """
    a = me.attributes.get(".select_edge")
    if a is not None and a.data_type != "BOOLEAN":
        me.attributes.remove(a)


# --------------------------------------------------------------------------
# shapeflow objects, cached across re-runs
# --------------------------------------------------------------------------

def shapeflow_mesh(V, sizes, corners):
    """A :class:`shapeflow.Mesh`, reusing the topology of the last call when the faces are equal."""
    import shapeflow as sf

    c = _mesh_cache
    if (c and c["n"] == len(V) and np.array_equal(c["sizes"], sizes)
            and np.array_equal(c["corners"], corners)):
        return c["mesh"].with_vertices(V)
    mesh = sf.Mesh.from_csr(V, sizes, corners)
    _mesh_cache.clear()
    _mesh_cache.update(n=len(V), sizes=np.array(sizes), corners=np.array(corners), mesh=mesh)
    return mesh


def flow_solver(mesh, weights, **options):
    """A :class:`shapeflow.FlowSolver`, reused when the mesh, positions, weights and options repeat.

    Scrubbing λ in *Adjust Last Operation* undoes the last run and re-executes
    the operator on the very same positions: the operator at those positions
    (cotangent weights, degrees, boundary umbrella) is then built only once.
    """
    import shapeflow as sf

    c = _solver_cache
    key = (id(mesh.topology), tuple((k, _hashable(v)) for k, v in sorted(options.items())))
    w = None if weights is None else np.asarray(weights, dtype=np.float64)
    same_w = (w is None and c.get("w") is None) or (w is not None and c.get("w") is not None
                                                    and np.array_equal(c["w"], w))
    if c and c["key"] == key and c["topology"] is mesh.topology and same_w and np.array_equal(c["V"], mesh.vertices):
        return c["solver"]
    solver = sf.FlowSolver(mesh, weights=w, **options)
    _solver_cache.clear()
    _solver_cache.update(key=key, topology=mesh.topology, V=np.array(mesh.vertices), w=None if w is None else w.copy(),
                         solver=solver)
    return solver


def _hashable(value):
    """An option as a comparable key (arrays, e.g. sharp edges, by their shape and bytes)."""
    if isinstance(value, np.ndarray):
        return (value.dtype.str, value.shape, value.tobytes())
    return value
