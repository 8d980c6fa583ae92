"""The inflate brush: each vertex in the sphere moves along its normal (the baseline of figure 9)."""

from __future__ import annotations

import numpy as np

from .. import params
from ..mesh import Mesh
from ..types import Falloff, Weights
from .base import BrushBase, Dab, serialised
from .numbering import csr_by, csr_ranges, unique_stamp
from .stroke import apply_falloff

__all__ = ["InflateBrush"]


class InflateBrush(BrushBase):
    """Move the vertices inside the sphere along their normals (the baseline of figure 9).

    Each dab moves vertex i by ``strength · radius · f(d_i/r) · w_i · n_i``
    (``n_i``: unit area-weighted vertex normal at the current positions, as
    :func:`shapeflow.geometry.vertex_normals`); negative strength deflates.
    Same API and thread model (calls serialised by a lock) as :class:`Brush`.
    """

    def __init__(self, mesh: Mesh, *, strength: float = 0.05, radius: float, falloff: Falloff = None,
                 weights: Weights = None, undo_limit: int = 64, rebuild_fraction: float = 0.15):
        super().__init__(mesh, radius=radius, falloff=falloff, weights=weights,
                         undo_limit=undo_limit, rebuild_fraction=rebuild_fraction)
        self.strength = strength
        t = self._imesh.topology
        self._vf_ptr, order = csr_by(t.face_indices, self._n)
        self._vf_face = t.corner_face[order]
        self._fstamp = np.zeros(t.n_faces, dtype=np.int64)
        self._tri_buf = None               # compiled cache update: the moved triangles

    @property
    @serialised
    def strength(self) -> float:
        """Displacement per dab as a fraction of the radius (< 0 deflates)."""
        return self._strength

    @strength.setter
    @serialised
    def strength(self, v) -> None:
        self._strength = params.number("strength", v)

    def _normals(self, S: np.ndarray) -> np.ndarray:
        """Unit area-weighted normals of vertices ``S`` (zero where undefined)."""
        t = self._imesh.topology
        ent, lens = csr_ranges(self._vf_ptr, S)
        fv = self._vf_face[ent]
        faces = unique_stamp(fv, self._fstamp)
        # vector area of each face: ½ Σ (v_k − v_0) × (v_{k+1} − v_0), as geometry.face_vector_areas
        off = t.face_offsets
        fsz = off[faces + 1] - off[faces]
        cent, clen = csr_ranges(off, faces)
        corners = cent
        first = np.repeat(off[faces], fsz)
        V = self._V
        fi = t.face_indices
        base = V[fi[first]]
        a = V[fi[corners]] - base
        b = V[fi[t.corner_next[corners]]] - base
        cr = np.cross(a, b)
        starts = np.cumsum(fsz) - fsz
        fa = 0.5 * np.add.reduceat(cr, starts, axis=0)
        floc = self._fstamp  # reuse as face -> local index
        floc[faces] = np.arange(faces.size)
        nrm = np.zeros((S.size, 3))
        rows = np.repeat(np.arange(S.size), lens)
        loc = floc[fv]
        for q in range(3):
            nrm[:, q] = np.bincount(rows, fa[loc, q], minlength=S.size)
        ln = np.sqrt(np.einsum("ij,ij->i", nrm, nrm))
        ok = ln > 0
        nrm[ok] /= ln[ok, None]
        return nrm

    def _compute(self, c: np.ndarray) -> Dab:
        S, d = self._query(c, self._radius)
        if S.size == 0:
            return Dab(c, self._radius, np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 3)))
        S_order = np.argsort(S)
        S, d = S[S_order], d[S_order]
        f = self._w[S].copy()
        if self._falloff_fn is not None:
            f *= apply_falloff(self._falloff_fn, d / self._radius)
        nrm = self._normals(S)
        move = (f != 0) & (np.abs(nrm).sum(axis=1) > 0)
        if self._strength == 0.0:
            move[:] = False
        idx = S[move]
        old = self._V[idx]
        new = old + (self._strength * self._radius * f[move])[:, None] * nrm[move]
        return Dab(c, self._radius, self._perm[idx], new, old, n_inside=S.size, solver="inflate", _internal=idx)
