"""glTF files built by hand for the glTF tests (hostile ones too), and an independent reader.

:class:`Doc` writes the JSON and the buffers itself (no shapeflow code), so each test can break
exactly one field.  :func:`decode` reads an accessor the way the glTF spec describes it, with
NumPy and explicit byte arithmetic, from a file pygltflib loaded.  The tests in this module check
that the builder's files are what other readers (pygltflib, trimesh) see.
"""

from __future__ import annotations

import base64
import json
import struct

import numpy as np
import pytest

pygltflib = pytest.importorskip("pygltflib", reason="pygltflib (the 'gltf' extra) is not installed")

CT = {"f4": 5126, "i1": 5120, "u1": 5121, "i2": 5122, "u2": 5123, "u4": 5125}
DT = {v: k for k, v in CT.items()}
WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}


def cube():
    """A closed cube of 8 vertices and 12 triangles (outward), its corner UVs per vertex."""
    V = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    T = np.array([[q[0], q[1], q[2]] for q in quads] + [[q[0], q[2], q[3]] for q in quads])
    return V, T


class Doc:
    """A glTF document under construction: ``j`` is its JSON, ``blobs`` its buffers."""

    def __init__(self, n_buffers: int = 1):
        self.j = {"asset": {"version": "2.0"}, "buffers": [{} for _ in range(n_buffers)], "bufferViews": [],
                  "accessors": [], "meshes": [], "nodes": [], "scenes": [{"nodes": []}], "scene": 0}
        self.blobs = [bytearray() for _ in range(n_buffers)]

    def view(self, data: bytes, buffer: int = 0, stride: int | None = None) -> int:
        blob = self.blobs[buffer]
        blob += b"\0" * (-len(blob) % 4)
        v = {"buffer": buffer, "byteOffset": len(blob), "byteLength": len(data)}
        if stride:
            v["byteStride"] = stride
        blob += data
        self.j["bufferViews"].append(v)
        return len(self.j["bufferViews"]) - 1

    def accessor(self, arr, kind: str, *, view: int | None = None, offset: int = 0, normalized: bool = False,
                 buffer: int = 0, minmax: bool = False, count: int | None = None) -> int:
        arr = np.asarray(arr)
        a = {"componentType": CT[arr.dtype.str[1:]], "type": kind, "count": count or arr.shape[0]}
        if view is None:
            view = self.view(np.ascontiguousarray(arr).astype(arr.dtype.newbyteorder("<")).tobytes(), buffer)
        a["bufferView"] = view
        if offset:
            a["byteOffset"] = offset
        if normalized:
            a["normalized"] = True
        if minmax:
            flat = arr.reshape(arr.shape[0], -1)
            cast = float if arr.dtype.kind == "f" else int
            a["min"], a["max"] = [cast(x) for x in flat.min(0)], [cast(x) for x in flat.max(0)]
        self.j["accessors"].append(a)
        return len(self.j["accessors"]) - 1

    def mesh(self, *primitives: dict) -> int:
        self.j["meshes"].append({"primitives": [dict(p) for p in primitives]})
        return len(self.j["meshes"]) - 1

    def node(self, root: bool = True, **fields) -> int:
        self.j["nodes"].append(fields)
        if root:
            self.j["scenes"][0]["nodes"].append(len(self.j["nodes"]) - 1)
        return len(self.j["nodes"]) - 1

    def finish_buffers(self, uris: dict | None = None, glb: bool = False) -> None:
        """byteLength of every buffer; uris: buffer -> uri (else data: URIs, or GLB's chunk for 0)."""
        for i, (b, blob) in enumerate(zip(self.j["buffers"], self.blobs)):
            b["byteLength"] = len(blob)
            if uris and i in uris:
                b["uri"] = uris[i]
            elif not (glb and i == 0):
                b["uri"] = "data:application/octet-stream;base64," + base64.b64encode(bytes(blob)).decode()

    def gltf(self, uris: dict | None = None) -> bytes:
        self.finish_buffers(uris)
        return json.dumps(self.j).encode()

    def glb(self, uris: dict | None = None) -> bytes:
        self.finish_buffers(uris, glb=True)
        return glb_bytes(json.dumps(self.j).encode(), bytes(self.blobs[0]))


def glb_bytes(text: bytes, binary: bytes | None, version: int = 2) -> bytes:
    text += b" " * (-len(text) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text
    if binary is not None:
        binary += b"\0" * (-len(binary) % 4)
        body += struct.pack("<II", len(binary), 0x004E4942) + binary
    return b"glTF" + struct.pack("<II", version, 12 + len(body)) + body


def cube_doc(n_buffers: int = 1) -> Doc:
    """The cube as one float32 triangle primitive, shown by one node."""
    V, T = cube()
    d = Doc(n_buffers)
    pos = d.accessor(V.astype("<f4"), "VEC3", minmax=True)
    idx = d.accessor(T.reshape(-1).astype("<u2"), "SCALAR")
    d.node(mesh=d.mesh({"attributes": {"POSITION": pos}, "indices": idx}))
    return d


# ---------------------------------------------------------------- the independent reader

def load(path):
    """pygltflib's document and its buffers' bytes (GLB chunk or data: URIs; never a file)."""
    g = pygltflib.GLTF2.load(str(path))
    blobs = []
    for b in g.buffers:
        if b.uri is None:
            blobs.append(g.binary_blob())
        else:
            assert b.uri.startswith("data:"), b.uri[:40]
            blobs.append(base64.b64decode(b.uri.split(",", 1)[1]))
    return g, blobs


def element_bytes(g, blobs, i) -> np.ndarray:
    """(count, element size) bytes of accessor i, by the spec's offset arithmetic."""
    a = g.accessors[i]
    v = g.bufferViews[a.bufferView]
    size = np.dtype(DT[a.componentType]).itemsize * WIDTH[a.type]
    stride = v.byteStride or size
    start = (v.byteOffset or 0) + (a.byteOffset or 0)
    at = start + stride * np.arange(a.count)[:, None] + np.arange(size)
    assert at.max() < (v.byteOffset or 0) + v.byteLength
    return np.frombuffer(blobs[v.buffer], np.uint8)[at]


def decode(g, blobs, i) -> np.ndarray:
    """Accessor i's values in its component type, (count, width)."""
    a = g.accessors[i]
    raw = element_bytes(g, blobs, i)
    return np.ascontiguousarray(raw).view("<" + DT[a.componentType]).reshape(a.count, WIDTH[a.type])


# ---------------------------------------------------------------- the builder is sound

def test_the_built_files_are_what_pygltflib_and_trimesh_read(tmp_path):
    V, T = cube()
    for ext in ("gltf", "glb"):
        d = cube_doc()
        p = tmp_path / f"c.{ext}"
        p.write_bytes(d.gltf() if ext == "gltf" else d.glb())
        g, blobs = load(p)
        np.testing.assert_array_equal(decode(g, blobs, 0), V.astype("<f4"))
        np.testing.assert_array_equal(decode(g, blobs, 1).reshape(-1, 3), T)
        trimesh = pytest.importorskip("trimesh")
        t = trimesh.load(str(p), force="mesh", process=False)
        np.testing.assert_array_equal(np.asarray(t.vertices), V)
        np.testing.assert_array_equal(np.asarray(t.faces), T)
