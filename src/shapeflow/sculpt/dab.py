"""The region and the small SPD system of one enhancement-brush dab."""

from __future__ import annotations

import numpy as np

from .. import accel
from ..flow.features import resolve_sharp_edges
from .base import Dab, serialised
from .numbering import csr_by, csr_ranges
from .stroke import apply_falloff, as_point

__all__ = ["DabSystem"]


class DabSystem:
    """The region and the linear system of one dab (a mixin of :class:`~shapeflow.sculpt.brush.Brush`).

    :meth:`_classify` finds the rim, locks, weights and degrees of the
    vertices inside the sphere; :meth:`_solve_region` assembles the rows of
    the free vertices (exactly the flow's rows, with the rim and the fixed
    vertices as Dirichlet values) and solves them with the brush's
    :class:`~shapeflow.linalg.local.LocalSolver`, the boundary block first,
    then the feature curves (:mod:`shapeflow.flow.features`), then the rest.
    """

    def _build_features(self, mesh, feature_angle, sharp_edges) -> None:
        """The sharp edges' classification in the internal numbering (None: no sharp edges)."""
        self._feature = self._curve = None
        sharp = resolve_sharp_edges(mesh, feature_angle, sharp_edges)
        if sharp is None:
            return
        n = self._n
        pairs = self._inv[mesh.topology.edges[sharp]]            # internal numbering
        count = np.bincount(pairs.reshape(-1), minlength=n)
        self._feature = (count > 0) & ~self._bmask
        self._curve = (count == 2) & ~self._bmask
        self.sharp_edge_count = int(sharp.sum())
        pairs = pairs[self._curve[pairs[:, 0]] | self._curve[pairs[:, 1]]]
        a = np.concatenate([pairs[:, 0], pairs[:, 1]])
        self._vc_ptr, order = csr_by(a, n)
        self._vc_nb = np.concatenate([pairs[:, 1], pairs[:, 0]])[order]

    @serialised
    def region(self, center) -> dict:
        """Inside, rim and free vertices of a dab at ``center`` (nothing is solved).

        Returns sorted index arrays ``inside``, ``rim``, ``free`` (the vertices
        a dab would solve for) and ``fixed`` (inside, not rim, yet kept in
        place: weight 0, locked, a boundary vertex with λ_b = 0, or a curve
        end or corner of the sharp edges).
        """
        c = as_point(center)
        S, d = self._query(c, self._radius)
        try:
            info = self._classify(S, d)
            free = info["free_i"] | info["free_b"] | info["free_c"]
            P = self._perm
            return {"inside": np.sort(P[S]), "rim": np.sort(P[S[info["rim"]]]), "free": np.sort(P[S[free]]),
                    "fixed": np.sort(P[S[~info["rim"] & ~free]])}
        finally:
            self._slot[S] = -1

    def _classify(self, S: np.ndarray, d: np.ndarray) -> dict:
        """Rim, locks, weights and degrees of the region ``S`` (fills ``self._slot``)."""
        ns = S.size
        slot = self._slot
        slot[S] = np.arange(ns)
        kern = accel.kernels("sculpt", self._n)     # one implementation for the region and its system
        rim, deg, neighbours = kern.classify(S, slot, self._vn_ptr, self._vn_nb, self._vn_pair, self._pw)
        w = self._w[S]
        if self._falloff_fn is not None:
            w = w * apply_falloff(self._falloff_fn, d / self._radius)
        mass = deg if self.normalized else 2.0 * self._ring_areas(S)
        bnd = self._bmask[S]
        cand = ~rim & (self._lock_count[S] == 0) & (w > 0)
        if self._lam != 0.0:
            free_i = cand & ~bnd & (mass > 0) & (deg > 0)
        else:
            free_i = np.zeros(ns, dtype=bool)
        free_b = cand & bnd if self._lam_b != 0.0 else np.zeros(ns, dtype=bool)
        free_c = np.zeros(ns, dtype=bool)
        if self._feature is not None:      # feature vertices: their curve's own step, or fixed
            free_i &= ~self._feature[S]
            if self._lam != 0.0:
                free_c = cand & self._curve[S]
        return dict(kernels=kern, neighbours=neighbours, rim=rim, deg=deg, w=w, mass=mass,
                    free_i=free_i, free_b=free_b, free_c=free_c)

    def _compute(self, c: np.ndarray) -> Dab:
        self._notes = []   # fallbacks taken by this dab (calls are serialised: one dab at a time)
        S, d = self._query(c, self._radius)
        if S.size == 0:
            return Dab(c, self._radius, np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 3)))
        order = np.argsort(S)
        S, d = S[order], d[order]
        try:
            info = self._classify(S, d)
            return self._solve_region(c, S, info)
        finally:
            self._slot[S] = -1

    def _solve_region(self, c: np.ndarray, S: np.ndarray, info: dict) -> Dab:
        V = self._V
        ns = S.size
        rim = S[info["rim"]]
        lam, lam_b = self._lam, self._lam_b
        # --- boundary vertices first (umbrella operator, as flow's paper mode) -------
        Rb = np.zeros(0, np.int64)
        Xb = np.zeros((0, 3))
        if info["free_b"].any():
            Rb, Xb = self._solve_umbrella(S, info, "free_b", lam_b, self._vb_ptr, self._vb_nb, Rb, Xb)
        # --- feature curves (their ends, corners and the solved boundary as boundary values) ----
        Rc = np.zeros(0, np.int64)
        Xc = np.zeros((0, 3))
        if info["free_c"].any():
            Rc, Xc = self._solve_umbrella(S, info, "free_c", lam, self._vc_ptr, self._vc_nb, Rb, Xb)
        Rd, Xd = (np.concatenate([Rb, Rc]), np.concatenate([Xb, Xc])) if Rc.size else (Rb, Xb)
        # --- interior ----------------------------------------------------------------
        R = np.flatnonzero(info["free_i"])
        k = R.size
        solver_used, bw = "none", 0
        if k:
            loc = np.full(ns, -1, dtype=np.int64)
            loc[R] = np.arange(k)
            cdiag = info["mass"][R] / (abs(lam) * info["w"][R])
            U = S[R]
            ri, ci, vi, rhs, VU = info["kernels"].assemble(S, R, loc, self._slot, self._vn_ptr, self._vn_nb,
                                                           self._vn_pair, self._pw, V, cdiag, Rd, Xd,
                                                           info["neighbours"])
            Xi, solver_used, bw = self._local_solver.solve(k, ri, ci, vi, cdiag + info["deg"][R], rhs,
                                                           notes=self._notes)
            bad = ~np.isfinite(Xi).all(axis=1)
            if bad.any():
                Xi[bad] = VU[bad]
        # --- result: V + sign(λ)(X − V) --------------------------------------------------
        idx_parts, new_parts, old_parts = [], [], []
        for Rs, Xs, sign in ((Rb, Xb, lam_b >= 0), (Rc, Xc, lam >= 0)):    # the boundary, the curves
            if Rs.size:
                Us = S[Rs]
                Vs = V.take(Us, axis=0, mode="clip")
                idx_parts.append(Us)
                old_parts.append(Vs)
                new_parts.append(Xs if sign else Vs - (Xs - Vs))
        if k:
            idx_parts.append(U)
            old_parts.append(VU)
            new_parts.append(Xi if lam >= 0 else VU - (Xi - VU))
        if not idx_parts:
            z = np.zeros((0, 3))
            return Dab(c, self._radius, np.zeros(0, np.int64), z, z, rim=self._perm[rim], n_inside=ns,
                       _internal=np.zeros(0, np.int64))
        if len(idx_parts) == 1:
            idx, new, old = idx_parts[0], new_parts[0], old_parts[0]
        else:
            idx, new, old = (np.concatenate(p) for p in (idx_parts, new_parts, old_parts))
        return Dab(c, self._radius, self._perm[idx], new, old, rim=self._perm[rim], n_inside=ns,
                   solver=solver_used, bandwidth=bw, notes=self._notes, _internal=idx)

    def _solve_umbrella(self, S: np.ndarray, info: dict, which: str, lam: float, ptr: np.ndarray, nbs: np.ndarray,
                        Rd: np.ndarray, Xd: np.ndarray):
        """flow's umbrella step (weights 1/|e_ij| over the neighbours ``ptr``/``nbs``) on the region's
        vertices ``info[which]``: the boundary block (``"free_b"``, λ_b) or the feature curves
        (``"free_c"``, λ; fixed neighbours solved before, ``Rd``/``Xd``, enter at their new position)."""
        V = self._V
        ns = S.size
        curve = which == "free_c"
        Rb = np.flatnonzero(info[which])
        Ub = S[Rb]
        ent, lens = csr_ranges(ptr, Ub)
        row = np.repeat(np.arange(Rb.size), lens)
        nb = nbs[ent]
        if not curve:
            keep = self._lock_count[nb] == 0             # flow drops umbrella edges with a locked end
            row, nb = row[keep], nb[keep]
        snb = self._slot[nb]                    # face neighbours of non-rim vertices: inside
        diff = V.take(Ub[row], axis=0, mode="clip") - V.take(nb, axis=0, mode="clip")
        length = np.sqrt(np.einsum("ij,ij->i", diff, diff))
        e = 1.0 / length
        Esum = np.bincount(row, e, minlength=Rb.size)
        # no usable umbrella edge (a curve vertex: a zero-length curve edge): the vertex stays
        ok = Esum > 0 if not curve else np.bincount(row, length > 0, minlength=Rb.size) == 2
        if not ok.all():
            sub = np.flatnonzero(ok)
            remap = np.full(ok.size, -1, dtype=np.int64)
            remap[sub] = np.arange(sub.size)
            row = remap[row]
            m = row >= 0
            row, nb, snb, e, length = row[m], nb[m], snb[m], e[m], length[m]
            Rb, Ub, Esum = Rb[sub], Ub[sub], Esum[sub]
            if Rb.size == 0:
                return Rb, np.zeros((0, 3))
        kb = Rb.size
        bloc = np.full(ns, -1, dtype=np.int64)
        bloc[Rb] = np.arange(kb)
        col = bloc[snb]
        mass = Esum if self.normalized or not curve else 0.5 * np.bincount(row, length, minlength=kb)
        cb = mass / (abs(lam) * info["w"][Rb])
        rhs = cb[:, None] * V.take(Ub, axis=0, mode="clip")
        cp = col < 0
        if cp.any():
            Xn = V[nb[cp]]
            if Rd.size:                          # neighbours solved before: their new (pre-sign) value
                dl = np.full(ns, -1, dtype=np.int64)
                dl[Rd] = np.arange(Rd.size)
                j = dl[snb[cp]]
                Xn[j >= 0] = Xd[j[j >= 0]]
            for q in range(3):
                rhs[:, q] += np.bincount(row[cp], e[cp] * Xn[:, q], minlength=kb)
        m = ~cp
        # rows come grouped by vertex, but in the order of Rb, so sort the entries by row
        X, _, _ = self._local_solver.solve(kb, row[m], col[m], -e[m], cb + Esum, rhs, grouped=False, notes=self._notes)
        bad = ~np.isfinite(X).all(axis=1)
        if bad.any():
            X[bad] = V[Ub[bad]]
        return Rb, X
