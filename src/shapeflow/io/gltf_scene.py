"""The node graph of a glTF file, walked once: where the default scene shows each mesh.

glTF nodes form disjoint strict trees: a node with two parents (a shared child), a node that is
its own ancestor (a cycle) or a scene root that is some node's child is refused by name.  Each
node's ``children`` are read once and each node is visited once, so the walk is linear in the
number of nodes whatever the file declares.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import MeshError
from .gltf_source import entry, field_int, is_int, items

__all__ = ["node_matrix", "mesh_placements"]


def _numbers(node: dict, key: str, n: int, i: int, name: str):
    v = node.get(key)
    if v is None:
        return None
    try:
        ok = (isinstance(v, list) and len(v) == n
              and all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v))
    except OverflowError:          # an integer beyond double precision
        ok = False
    if not ok:
        raise MeshError(f"{name}: node {i}: {key} is not {n} finite numbers")
    return np.asarray(v, np.float64)


def node_matrix(node: dict, i: int, name: str) -> np.ndarray:
    """A node's local transform (its ``matrix``, column-major, or T·R·S)."""
    m = _numbers(node, "matrix", 16, i, name)
    if m is not None:
        return m.reshape(4, 4).T
    M = np.eye(4)
    s, r, t = (_numbers(node, k, n, i, name) for k, n in (("scale", 3), ("rotation", 4), ("translation", 3)))
    if s is not None:
        M = np.diag([*s, 1.0])
    if r is not None:
        norm = np.linalg.norm(r)
        x, y, z, w = r / norm if norm > 0 and np.isfinite(norm) else (0.0, 0.0, 0.0, 1.0)
        R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                      [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                      [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
        M = np.block([[R, np.zeros((3, 1))], [np.zeros((1, 3)), np.ones((1, 1))]]) @ M
    if t is not None:
        T = np.eye(4)
        T[:3, 3] = t
        M = T @ M
    return M


def _children(nodes: list, name: str) -> tuple[list, list]:
    """Each node's children (read once) and parent (-1: a root); two parents or a cycle is refused."""
    n = len(nodes)
    kids, parent = [], [-1] * n
    for p, node in enumerate(nodes):       # over the nodes and their child lists: linear
        if not isinstance(node, dict):
            raise MeshError(f"{name}: node {p} is not an object")
        ch = node.get("children")
        ch = [] if ch is None else ch
        if not isinstance(ch, list) or not all(is_int(c) and 0 <= c < n for c in ch):
            raise MeshError(f"{name}: node {p}: children is not a list of node indices below {n}")
        for c in ch:
            if c == p:
                raise MeshError(f"{name}: node {p} is its own child (a cycle); glTF nodes form trees")
            if parent[c] >= 0:
                raise MeshError(f"{name}: node {c} has two parents (nodes {parent[c]} and {p}); "
                                "glTF nodes form trees, a node may not be shared")
            parent[c] = p
        kids.append(ch)
    reached = [False] * n
    stack = [i for i in range(n) if parent[i] < 0]
    while stack:
        i = stack.pop()
        reached[i] = True
        stack.extend(kids[i])
    if not all(reached):
        k = reached.index(False)
        raise MeshError(f"{name}: node {k} lies on or below a cycle of children (it has no root); "
                        "glTF nodes form trees")
    return kids, parent


def _roots(doc: dict, parent: list, name: str) -> list:
    scenes = items(doc, "scenes", name)
    if not scenes:
        return [i for i, p in enumerate(parent) if p < 0]
    s = field_int(doc, "scene", "the file", name, hi=len(scenes) - 1, default=0)
    scene = entry(doc, "scenes", s, name, "the default scene")
    roots = scene.get("nodes")
    roots = [] if roots is None else roots
    if not isinstance(roots, list) or not all(is_int(r) and 0 <= r < len(parent) for r in roots):
        raise MeshError(f"{name}: scene {s}: nodes is not a list of node indices below {len(parent)}")
    seen = set()
    for r in roots:
        if parent[r] >= 0:
            raise MeshError(f"{name}: scene {s} lists node {r} as a root, but it is the child of node {parent[r]}")
        if r in seen:
            raise MeshError(f"{name}: scene {s} lists node {r} twice")
        seen.add(r)
    return roots


def mesh_placements(doc: dict, name: str = "glTF document") -> tuple[dict, dict]:
    """World transform of the first node that shows each mesh in the default scene (depth first,
    parents before children), and how many nodes show it.  Meshes no node shows are absent."""
    nodes = items(doc, "nodes", name)
    n_meshes = len(items(doc, "meshes", name))
    kids, parent = _children(nodes, name)
    first: dict = {}
    count: dict = {}
    stack = [(r, np.eye(4)) for r in reversed(_roots(doc, parent, name))]
    while stack:                       # each node once: the graph is a forest (checked above)
        i, above = stack.pop()
        M = above @ node_matrix(nodes[i], i, name)
        if not np.isfinite(M).all():
            raise MeshError(f"{name}: node {i}: its world transform overflows double precision")
        m = field_int(nodes[i], "mesh", f"node {i}", name, hi=n_meshes - 1)
        if m is not None:
            first.setdefault(m, M)
            count[m] = count.get(m, 0) + 1
        stack.extend((c, M) for c in reversed(kids[i]))
    return first, count
