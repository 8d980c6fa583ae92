"""Small analytic meshes for tests (independent of shapeflow's own code), and the grid Laplacian that
the linear-algebra tests solve with."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

import shapeflow as sf


def grid_laplacian(m: int) -> sp.csr_matrix:
    """The 5-point Laplacian of an m × m grid with Dirichlet rows (int32 CSR, as the flow's systems): SPD,
    eigenvalues 4 − 2cos(πi/(m+1)) − 2cos(πj/(m+1)), the smallest 4 − 4cos(π/(m+1)), condition ~m²."""
    T = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(m, m))
    eye = sp.eye(m)
    A = (sp.kron(T, eye) + sp.kron(eye, T)).tocsr()
    A.indices = A.indices.astype(np.int32)
    A.indptr = A.indptr.astype(np.int32)
    return A


def grid(nx: int, ny: int | None = None, *, jitter: float = 0.0, seed: int = 0, mix: float = 0.0,
         z=None) -> sf.Mesh:
    """An nx × ny vertex planar grid of unit quads; ``mix`` = chance to split a quad into 2 triangles."""
    ny = ny or nx
    rng = np.random.default_rng(seed)
    xs, ys = np.meshgrid(np.arange(nx, dtype=float), np.arange(ny, dtype=float), indexing="ij")
    V = np.c_[xs.ravel(), ys.ravel(), np.zeros(nx * ny)]
    if jitter:
        V[:, :2] += jitter * rng.uniform(-1, 1, (nx * ny, 2))
    if z is not None:
        V[:, 2] = z(V[:, 0], V[:, 1])
    faces = []
    for i in range(nx - 1):
        for j in range(ny - 1):
            a, b, c, d = i * ny + j, (i + 1) * ny + j, (i + 1) * ny + j + 1, i * ny + j + 1
            if mix and rng.random() < mix:
                faces += [[a, b, c], [a, c, d]] if rng.random() < 0.5 else [[a, b, d], [b, c, d]]
            else:
                faces.append([a, b, c, d])
    return sf.Mesh(V, faces)


def cube_sphere(k: int, r: float = 1.0, *, mix: float = 0.0, seed: int = 0) -> sf.Mesh:
    """A quad sphere: each cube face cut into k × k quads, projected to radius r.

    ``mix`` > 0 splits that fraction of quads into two triangles at random.
    """
    rng = np.random.default_rng(seed)
    verts: dict = {}
    V = []

    def vid(p):
        key = tuple(np.round(p * 2 * k).astype(int))
        if key not in verts:
            verts[key] = len(V)
            V.append(p)
        return verts[key]

    faces = []
    t = np.linspace(-1, 1, k + 1)
    for axis in range(3):
        for sgn in (-1.0, 1.0):
            u_ax, v_ax = [a for a in range(3) if a != axis]
            for i in range(k):
                for j in range(k):
                    corners = []
                    for di, dj in ((0, 0), (1, 0), (1, 1), (0, 1)):
                        p = np.zeros(3)
                        p[axis] = sgn
                        p[u_ax] = t[i + di]
                        p[v_ax] = t[j + dj]
                        corners.append(vid(p))
                    # orient outward
                    if (sgn > 0) != ((axis == 1)):
                        corners = corners[::-1]
                    if mix and rng.random() < mix:
                        a, b, c, d = corners
                        faces += [[a, b, c], [a, c, d]]
                    else:
                        faces.append(corners)
    V = np.array(V)
    V = r * V / np.linalg.norm(V, axis=1)[:, None]
    m = sf.Mesh(V, faces)
    # make orientation outward consistently (check with the first face normal)
    return _orient_outward(m)


def icosphere(level: int, r: float = 1.0) -> sf.Mesh:
    """A subdivided icosahedron projected to radius r (triangles)."""
    p = (1 + 5 ** 0.5) / 2
    V = [[-1, p, 0], [1, p, 0], [-1, -p, 0], [1, -p, 0], [0, -1, p], [0, 1, p], [0, -1, -p], [0, 1, -p],
         [p, 0, -1], [p, 0, 1], [-p, 0, -1], [-p, 0, 1]]
    F = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
         [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5],
         [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    V = [np.array(v, float) / np.linalg.norm(v) for v in V]
    for _ in range(level):
        mid = {}

        def midpoint(a, b):
            key = (min(a, b), max(a, b))
            if key not in mid:
                m = V[a] + V[b]
                V.append(m / np.linalg.norm(m))
                mid[key] = len(V) - 1
            return mid[key]

        F2 = []
        for a, b, c in F:
            ab, bc, ca = midpoint(a, b), midpoint(b, c), midpoint(c, a)
            F2 += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        F = F2
    return _orient_outward(sf.Mesh(r * np.array(V), F))


def _orient_outward(m: sf.Mesh) -> sf.Mesh:
    from shapeflow.geometry import face_vector_areas

    fa = face_vector_areas(m)
    cent = np.add.reduceat(m.vertices[m.face_indices], m.face_offsets[:-1], axis=0) / m.face_sizes[:, None]
    flip = np.einsum("ij,ij->i", fa, cent) < 0
    faces = m.faces_as_lists()
    faces = [f[::-1] if fl else f for f, fl in zip(faces, flip)]
    return sf.Mesh(m.vertices, faces)


def random_rotation(seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    q, r = np.linalg.qr(rng.standard_normal((3, 3)))
    q *= np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] *= -1
    return q


def ngon_disk(n_sides: int = 7, rings: int = 3) -> sf.Mesh:
    """A planar mesh with an n-gon in the middle, a ring of quads, then triangles (irregular)."""
    rng = np.random.default_rng(n_sides)
    ang = np.linspace(0, 2 * np.pi, n_sides, endpoint=False)
    V = [np.c_[np.cos(ang), np.sin(ang), np.zeros(n_sides)] * (1 + 0.1 * rng.uniform(-1, 1, (n_sides, 1)))]
    faces = [list(range(n_sides))]
    prev = list(range(n_sides))
    count = n_sides
    for r in range(1, rings + 1):
        rad = 1 + r
        ring = np.c_[np.cos(ang + 0.05 * r), np.sin(ang + 0.05 * r), np.zeros(n_sides)] * rad
        ring[:, :2] += 0.1 * rng.uniform(-1, 1, (n_sides, 2))
        V.append(ring)
        cur = list(range(count, count + n_sides))
        count += n_sides
        for i in range(n_sides):
            a, b = prev[i], prev[(i + 1) % n_sides]
            c, d = cur[(i + 1) % n_sides], cur[i]
            if r % 2:  # counter-clockwise seen from +z, like the central n-gon
                faces.append([a, d, c, b])
            else:
                faces += [[a, d, c], [a, c, b]]
        prev = cur
    m = sf.Mesh(np.vstack(V), faces)
    from shapeflow.geometry import face_vector_areas

    assert (face_vector_areas(m)[:, 2] > 0).all(), "test mesh folded over"
    return m
