"""A bounded, derandomized mutation fuzzer over a valid glTF document and a valid GLB.

The seed documents use most of what the reader supports (two meshes, shared and quantized
accessors, interleaving, a sparse accessor, normals, UVs, colours, a node tree, an embedded image,
two buffers).  .gltf: JSON values replaced structurally (negative, huge, fractional, strings, null,
lists, objects, indices out of range, keys removed).  .glb: bytes overwritten, chunk lengths
replaced, the file cut short.  Each case may end only in a mesh with finite vertices (which must
then be written back, and the written file read again) or a MeshError: no other exception, no
crash, no hang.
"""

from __future__ import annotations

import copy
import io
import json
import struct
import warnings

import numpy as np
import pytest
from test_gltf_files import Doc, cube
from test_gltf_hostile import quantized_doc

import shapeflow as sf
from shapeflow.io.gltf import read_gltf, write_gltf

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, event, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

FUZZ = settings(derandomize=True, max_examples=500, deadline=None, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])


def seed_doc() -> Doc:
    d, *_ = quantized_doc()                                     # mesh 0: quantized, interleaved
    V, T = cube()
    d.j["buffers"].append({})
    d.blobs.append(bytearray())
    pos = d.accessor(V.astype("<f4"), "VEC3", buffer=1, minmax=True)
    col = d.accessor(np.full((8, 4), 200, np.uint8), "VEC4", normalized=True, buffer=1)
    half = d.accessor(T[:6].reshape(-1).astype("<u1"), "SCALAR", buffer=1)
    rest = d.accessor(T[6:].reshape(-1).astype("<u4"), "SCALAR", buffer=1)
    d.j["accessors"][pos]["sparse"] = {
        "count": 1, "indices": {"bufferView": d.view(np.array([3], "<u2").tobytes(), 1), "componentType": 5123},
        "values": {"bufferView": d.view(np.array([1, 1, 1.5], "<f4").tobytes(), 1)}}
    mesh = d.mesh({"attributes": {"POSITION": pos, "COLOR_0": col}, "indices": half},
                  {"attributes": {"POSITION": pos, "COLOR_0": col}, "indices": rest, "mode": 4})
    child = d.node(root=False, mesh=mesh, translation=[3.0, 0.0, 0.0], rotation=[0.0, 0.0, 0.6, 0.8])
    d.j["nodes"][0]["children"] = [child]
    d.j["images"] = [{"uri": "data:image/png;base64,iVBORw0KGgo=", "mimeType": "image/png"}]
    return d


def paths(obj, at=()):
    yield at
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from paths(v, at + (k,))
    elif isinstance(obj, list):
        for k, v in enumerate(obj):
            yield from paths(v, at + (k,))


SEED = seed_doc()
SEED.finish_buffers()
SEED_JSON = SEED.j
SEED_PATHS = [p for p in paths(SEED_JSON) if p]
SEED_GLB = seed_doc().glb()
KINDS = ["negative", "huge", "fraction", "string", "null", "list", "object", "beyond", "zero", "bool", "delete"]


def _has(parent, key) -> bool:
    if isinstance(parent, dict):
        return key in parent
    return isinstance(parent, list) and isinstance(key, int) and key < len(parent)


def mutate(doc: dict, path: tuple, kind: str, k: int) -> None:
    parent = doc
    for key in path[:-1]:
        if not _has(parent, key):
            return                                              # an earlier mutation removed it
        parent = parent[key]
    key = path[-1]
    if not _has(parent, key):
        return
    old = parent[key]
    if kind == "delete":
        del parent[key]
        return
    number = old if isinstance(old, (int, float)) and not isinstance(old, bool) else k
    parent[key] = {
        "negative": -abs(number) - 1, "huge": [2 ** 31, 2 ** 32 - 1, 2 ** 63, 10 ** 30, 1e308][k % 5],
        "fraction": number + 0.5, "string": str(number), "null": None, "list": [number], "object": {"x": number},
        "beyond": number + [1, 7, 1000, 2 ** 20][k % 4], "zero": 0, "bool": True}[kind]


def outcome(data: bytes, name: str) -> str:
    """A finite mesh that writes back and reads again, or a MeshError; nothing else (returns which)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.DataLossWarning)
        try:
            m = read_gltf(data, name, external_files=False)
        except sf.MeshError as exc:
            return "refused: " + str(exc).split(": ")[1][:30]
        assert np.isfinite(m.vertices).all()
        for binary in (True, False):
            f = io.BytesIO()
            try:
                write_gltf(f, m.with_vertices(m.vertices * 0.5), binary=binary)
            except sf.MeshError:
                continue
            back = read_gltf(f.getvalue(), name, external_files=False)
            assert back.n_vertices == m.n_vertices and back.n_faces == m.n_faces
    return "read"


def test_the_seeds_are_read_and_written_back():
    for data in (json.dumps(SEED_JSON).encode(), SEED_GLB):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sf.DataLossWarning)
            m = read_gltf(data, "seed.gltf", external_files=False)
        assert m.n_vertices == 16 and m.n_faces == 24 and "primitive" in m.face_attributes
        assert outcome(data, "seed.gltf") == "read"


@FUZZ
@given(st.lists(st.tuples(st.integers(0, len(SEED_PATHS) - 1), st.sampled_from(KINDS), st.integers(0, 99)),
                min_size=1, max_size=3))
def test_mutated_gltf_json(mutations):
    doc = copy.deepcopy(SEED_JSON)
    for p, kind, k in mutations:
        mutate(doc, SEED_PATHS[p], kind, k)
    event(outcome(json.dumps(doc).encode(), "fuzz.gltf"))


JSON_LENGTH = struct.unpack_from("<I", SEED_GLB, 12)[0]
BIN_AT = 20 + JSON_LENGTH                   # the binary chunk's header; its bytes follow
JSONISH = b'0123456789-.e,:"{}[] ntf'


@FUZZ
@given(st.lists(st.one_of(
    st.tuples(st.just("bin"), st.integers(BIN_AT + 8, len(SEED_GLB) - 1), st.integers(0, 255)),
    st.tuples(st.just("json"), st.integers(20, BIN_AT - 1), st.sampled_from(list(JSONISH))),
    st.tuples(st.just("length"), st.sampled_from([8, 12, BIN_AT]), st.sampled_from(
        [0, 1, 3, 4, JSON_LENGTH - 1, JSON_LENGTH + 1, 2 ** 31, 2 ** 32 - 1, len(SEED_GLB)])),
    st.tuples(st.just("cut"), st.integers(0, len(SEED_GLB) - 1), st.booleans())), min_size=1, max_size=4))
def test_mutated_glb_bytes(mutations):
    data = bytearray(SEED_GLB)
    for kind, at, value in mutations:
        if kind in ("bin", "json") and at < len(data):
            data[at] = value
        elif kind == "length" and at + 4 <= len(data):
            data[at:at + 4] = struct.pack("<I", value)
        elif kind == "cut":
            del data[at:]
            if value and len(data) >= 12:                        # the header says so too
                data[8:12] = struct.pack("<I", len(data))
    event(outcome(bytes(data), "fuzz.glb"))
