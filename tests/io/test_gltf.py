"""glTF / GLB: a seamed, textured cube with a material and a node, built with pygltflib in the
test, smooths as one surface and is written back with only positions and normals changed."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import need

import shapeflow as sf

pygltflib = need("pygltflib", "pygltflib (the 'gltf' extra)")


def cube_with_seams():
    """24 vertices (4 per side: split at every edge, as exporters write cubes), UVs, normals, one
    material, one node with a name."""
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    sides = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    pos, nrm, uv, idx = [], [], [], []
    for s in sides:
        p = corners[s]
        n = np.cross(p[1] - p[0], p[2] - p[0])
        base = len(pos)
        pos += list(p)
        nrm += [n / np.linalg.norm(n)] * 4
        uv += [[0, 0], [1, 0], [1, 1], [0, 1]]
        idx += [base, base + 1, base + 2, base, base + 2, base + 3]
    pos, nrm, uv = (np.array(a, "<f4") for a in (pos, nrm, uv))
    idx = np.array(idx, "<u2")
    blob = pos.tobytes() + nrm.tobytes() + uv.tobytes() + idx.tobytes()
    views, off = [], 0
    for a in (pos, nrm, uv, idx):
        views.append(pygltflib.BufferView(buffer=0, byteOffset=off, byteLength=a.nbytes))
        off += a.nbytes
    g = pygltflib.GLTF2(
        scene=0, scenes=[pygltflib.Scene(nodes=[0])], nodes=[pygltflib.Node(mesh=0, name="Crate")],
        materials=[pygltflib.Material(name="wood")],
        meshes=[pygltflib.Mesh(primitives=[pygltflib.Primitive(
            attributes=pygltflib.Attributes(POSITION=0, NORMAL=1, TEXCOORD_0=2), indices=3, material=0)])],
        accessors=[pygltflib.Accessor(bufferView=0, componentType=5126, count=24, type="VEC3",
                                      min=[-1, -1, -1], max=[1, 1, 1]),
                   pygltflib.Accessor(bufferView=1, componentType=5126, count=24, type="VEC3"),
                   pygltflib.Accessor(bufferView=2, componentType=5126, count=24, type="VEC2"),
                   pygltflib.Accessor(bufferView=3, componentType=5123, count=36, type="SCALAR")],
        bufferViews=views, buffers=[pygltflib.Buffer(byteLength=len(blob))])
    g.set_binary_blob(blob)
    return g, pos, uv, idx


def _read(path):
    g = pygltflib.GLTF2.load(str(path))
    blob = g.binary_blob() if g.buffers[0].uri is None else g.get_data_from_buffer_uri(g.buffers[0].uri)

    def acc(i, dt, w):
        a, v = g.accessors[i], g.bufferViews[g.accessors[i].bufferView]
        return np.frombuffer(blob, dt, a.count * w, v.byteOffset or 0).reshape(a.count, w)

    return g, acc


@pytest.mark.parametrize("ext", [".glb", ".gltf"])
def test_a_seamed_cube_smooths_as_one_surface_and_keeps_its_scene(tmp_path, capsys, ext):
    from shapeflow.cli import main

    g, pos, uv, idx = cube_with_seams()
    src = tmp_path / f"cube{ext}"
    if ext == ".glb":
        g.save_binary(str(src))
    else:
        g.convert_buffers(pygltflib.BufferFormat.DATAURI)
        g.save_json(str(src))
    m = sf.load(src)
    assert m.n_vertices == 24 and m.n_faces == 12 and sf.weld(m).n_vertices == 8
    out = tmp_path / f"out{ext}"
    assert main(["smooth", str(src), str(out), "--strength", "0.5"]) == 0
    assert "welded to 8" in capsys.readouterr().err
    g2, acc = _read(out)
    assert g2.materials[0].name == "wood" and g2.nodes[0].name == "Crate"
    assert g2.meshes[0].primitives[0].material == 0
    new = acc(0, "<f4", 3).astype(np.float64)
    np.testing.assert_array_equal(acc(2, "<f4", 2), uv)                   # UVs unchanged
    np.testing.assert_array_equal(acc(3, "<u2", 1).reshape(-1), idx)      # triangles unchanged
    # the seam copies of each cube corner moved together, as the welded cube's corner did
    w = sf.weld(m)
    ref = sf.flow(w, 0.5).vertices[w.weld_map]
    np.testing.assert_allclose(new, ref, atol=1e-6)
    for c in range(8):
        copies = np.flatnonzero(w.weld_map == c)
        assert np.abs(new[copies] - new[copies[0]]).max() == 0.0
    assert np.abs(new).max() < 1.0                                         # it shrank (smoothing a cube)
    # normals: unit, from the new surface (the welded cube is symmetric: they point outwards)
    n = acc(1, "<f4", 3)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-6)
    assert (np.einsum("ij,ij->i", n, new) > 0).all()


def test_a_new_document_for_changed_faces(tmp_path):
    g, *_ = cube_with_seams()
    src = tmp_path / "cube.glb"
    g.save_binary(str(src))
    m = sf.load(src)
    with pytest.warns(sf.DataLossWarning, match="faces changed"):
        sf.save(tmp_path / "sub.glb", sf.subdivide(sf.weld(m), 1))
    back = sf.load(tmp_path / "sub.glb")
    assert back.n_faces == 2 * sf.weld(m).n_corners     # a quad per parent corner, written as two triangles


def test_not_a_gltf_file_is_a_mesh_error(tmp_path):
    p = tmp_path / "x.glb"
    p.write_bytes(b"glTF\x02\x00\x00\x00garbage")
    with pytest.raises(sf.MeshError, match="x.glb"):
        sf.load(p)


def test_a_textured_obj_becomes_a_gltf_with_its_uvs_and_seams(tmp_path):
    """bob (quads, vt and vn with seams) as a new glTF: one glTF vertex per distinct
    (vertex, vt, vn) of the corners, each corner's UV and position where the OBJ had them."""
    from conftest import MESHES

    if MESHES is None:
        pytest.skip("shared meshes not found")
    import warnings

    m = sf.load(MESHES / "bob_quad.obj")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.DataLossWarning)       # quads as fans, face labels
        sf.save(tmp_path / "bob.glb", m)
    g, acc = _read(tmp_path / "bob.glb")
    prim = g.meshes[0].primitives[0]
    pos = acc(prim.attributes.POSITION, "<f4", 3)
    uvs = acc(prim.attributes.TEXCOORD_0, "<f4", 2)
    triples = {(v, t, n) for v, t, n in zip(m.face_indices, m.corner_attributes["uv"].index,
                                            m.corner_attributes["normal"].index)}
    assert pos.shape[0] == len(triples)
    back = sf.load(tmp_path / "bob.glb")
    # the fans of each OBJ face, corner by corner: the glTF corners carry the OBJ corners' values
    corners = []
    for f in range(m.n_faces):
        o, k = m.face_offsets[f], m.face_sizes[f]
        corners += [c for j in range(1, k - 1) for c in (o, o + j, o + j + 1)]
    corners = np.array(corners)
    np.testing.assert_allclose(back.vertices[back.face_indices], m.vertices[m.face_indices[corners]], atol=1e-6)
    np.testing.assert_allclose(back.corner_attributes["uv"], m.corner_attributes["uv"].expand()[corners], atol=1e-7)
    assert uvs.shape[0] == pos.shape[0]


def placed_cubes():
    """The seamed cube as two meshes (sharing accessors), shown by a parent node (translation,
    rotation, scale) and its child (a column-major matrix): where they sit, from scipy's rotation."""
    from scipy.spatial.transform import Rotation

    g, pos, uv, idx = cube_with_seams()
    g.meshes.append(pygltflib.Mesh(primitives=[pygltflib.Primitive(
        attributes=pygltflib.Attributes(POSITION=0, NORMAL=1, TEXCOORD_0=2), indices=3)]))
    q = [0.0, 0.0, np.sin(np.pi / 6), np.cos(np.pi / 6)]                  # 60° about z, (x, y, z, w)
    child = np.eye(4)
    child[:3, 3] = [0.0, 3.0, 0.5]
    g.nodes = [pygltflib.Node(mesh=0, translation=[5.0, 0.0, -1.0], rotation=q, scale=[2.0, 2.0, 0.5],
                              children=[1], name="parent"),
               pygltflib.Node(mesh=1, matrix=child.T.reshape(-1).tolist(), name="child")]
    parent = np.eye(4)
    parent[:3, :3] = Rotation.from_quat(q).as_matrix() @ np.diag([2.0, 2.0, 0.5])
    parent[:3, 3] = [5.0, 0.0, -1.0]
    world = [parent, parent @ child]
    expected = np.concatenate([pos @ M[:3, :3].T + M[:3, 3] for M in world])
    return g, expected


def test_node_transforms_place_the_meshes_as_the_scene_shows_them(tmp_path):
    g, expected = placed_cubes()
    src = tmp_path / "placed.glb"
    g.save_binary(str(src))
    m = sf.load(src)
    np.testing.assert_allclose(m.vertices, expected, atol=1e-5)
    trimesh = need("trimesh", "trimesh (a test dependency)")
    scene = trimesh.load(str(src), force="scene", process=False)
    theirs = np.unique(np.round(scene.to_geometry().vertices, 4), axis=0)
    assert np.array_equal(np.unique(np.round(m.vertices, 4), axis=0), theirs)   # trimesh's scene graph agrees
    # the two cubes coincide in their own coordinates, not in the scene: each welds to its 8 corners
    assert sf.weld(m).n_vertices == 16
    # normals follow the inverse transpose: still perpendicular to the placed faces
    nrm = sf.mesh.attributes.expand(m.corner_attributes["normal"])
    V, fi = m.vertices, m.face_indices.reshape(-1, 3)
    face_n = np.cross(V[fi[:, 1]] - V[fi[:, 0]], V[fi[:, 2]] - V[fi[:, 0]])
    assert np.allclose(np.einsum("ij,ij->i", nrm.reshape(-1, 3, 3)[:, 0], face_n), np.linalg.norm(face_n, axis=1),
                       rtol=1e-5)


def test_a_placed_scene_is_written_back_in_its_own_coordinates(tmp_path):
    g, expected = placed_cubes()
    src, out = tmp_path / "placed.glb", tmp_path / "out.glb"
    g.save_binary(str(src))
    m = sf.load(src)
    smoothed = sf.flow(sf.weld(m), 0.5)
    result = sf.unweld(smoothed, m, sf.weld(m))
    sf.save(out, result)
    back = pygltflib.GLTF2.load(str(out))
    assert back.nodes[0].translation == [5.0, 0.0, -1.0] and back.nodes[1].matrix == g.nodes[1].matrix
    np.testing.assert_allclose(sf.load(out).vertices, result.vertices, atol=1e-5)
    assert not np.allclose(result.vertices, expected, atol=1e-3)     # the flow did move them
