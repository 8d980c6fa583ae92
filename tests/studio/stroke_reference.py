"""What a stroke of the studio's enhancement brush must give, computed from the library's brush alone
(a slow, independent implementation of docs/studio.md's "Strokes": nothing of shapeflow.studio)."""

from __future__ import annotations

import numpy as np

import shapeflow as sf


def dabs_alone(mesh, centres, radius, lam, weights=None):
    """Each dab applied alone to the mesh as given (a fresh sf.Brush with the smooth falloff): a list of
    (the vertices it moved, their new positions)."""
    out = []
    for c in centres:
        b = sf.Brush(mesh, radius=radius, lam=lam, falloff="smooth", weights=weights)
        idx = np.asarray(b.dab(c))
        out.append((idx, b.vertices[idx]))
    return out


def blend(mesh, centres, radius, alone):
    """The stroke from its dabs alone: each vertex the (1 − t²)²-weighted mean of the positions the dabs
    gave it, t its distance from the dab's centre over the radius (where one dab moved it: that dab's
    position; where none did: where it was)."""
    V = mesh.vertices
    num, den, count, one = np.zeros_like(V), np.zeros(len(V)), np.zeros(len(V), int), V.copy()
    for c, (idx, P) in zip(centres, alone):
        f = (1.0 - np.minimum(np.linalg.norm(V[idx] - c, axis=1) / radius, 1.0) ** 2) ** 2
        num[idx] += f[:, None] * P
        den[idx] += f
        count[idx] += 1
        one[idx] = P
    out = np.where((count == 1)[:, None], one, V)
    many = count > 1
    out[many] = num[many] / den[many][:, None]
    return out


def blended(mesh, centres, radius, lam, weights=None):
    """A stroke of the studio's enhancement brush through ``centres``."""
    return blend(mesh, centres, radius, dabs_alone(mesh, centres, radius, lam, weights))


def farthest_alone(mesh, alone):
    """How far the farthest-reaching of the dabs alone moves each vertex (0 where none moves it)."""
    far = np.zeros(mesh.n_vertices)
    for idx, P in alone:
        far[idx] = np.maximum(far[idx], np.linalg.norm(P - mesh.vertices[idx], axis=1))
    return far
