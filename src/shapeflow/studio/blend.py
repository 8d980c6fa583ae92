"""The studio's sculpt brushes, and a stroke of its enhancement brush: every dab solved on the shape the
stroke began on, the dabs blended.

The paper's brush (:class:`~shapeflow.sculpt.Brush`: one implicit step of the flow inside a sphere,
its rim fixed) compounds when its dabs are applied one after the other: at the λ of the studio's
brush a dab nearly doubles the surface's deviation from the membrane its rim spans, so a vertex
that k dabs of a stroke cover moves by up to 2^k times what one dab moves it, and k depends on how
densely the dabs lie.  On Spot (2,930 vertices) at the page's default brush (radius 0.2 of the
bounding sphere, λ −102.3) a stroke of 47 dabs across the horns moved a vertex by 3.2 radii and
changed a dihedral angle by 168°.

Here a stroke enhances each point it passes over once.  Each dab is solved on the positions the
stroke began on (the brush previews it and never commits it, so the brush keeps those positions),
and each vertex takes the average of the positions the stroke's dabs gave it, each weighted by the
smooth falloff (1 − t²)² of its distance t·r from that dab's centre (on the same positions); a
vertex one dab moved takes that dab's position exactly.  Every vertex therefore stays within the
convex hull of where the dabs alone would put it: a stroke moves no vertex further than its
farthest-reaching dab alone does, however many dabs it has, and more dabs refine the average
instead of compounding it (a stroke of one dab is that dab; many dabs at one place are one dab).
A dab position that is not finite is never taken (the vertex stays).  Work per dab is the dab's
own: nothing proportional to the mesh but the stroke's sums, allocated once per stroke; the brush
is built again on the new shape once per stroke (:meth:`Sculptor.build`).
"""

from __future__ import annotations

import numpy as np

from ..sculpt.stroke import smooth_falloff

__all__ = ["StrokeBlend", "Sculptor", "finite_preview"]


def finite_preview(brush, center):
    """``brush.preview(center)`` with every vertex it would move to a non-finite position left where it
    is (an overflowing solve never reaches the session)."""
    d = brush.preview(center)
    bad = ~np.isfinite(d.positions).all(axis=1)
    if bad.any():
        d.positions[bad] = d.previous[bad]
    return d


class StrokeBlend:
    """The running blend of one stroke's dabs over ``brush`` (a :class:`~shapeflow.sculpt.Brush` on the
    positions the stroke began on, with ``n`` vertices).  ``version``: the session's shape version its
    last dab left (anything else moving the shape ends the blend: the next dab begins a new one)."""

    def __init__(self, brush, n: int, version: int):
        self.brush, self.version = brush, version
        self._num = np.zeros((n, 3))
        self._den = np.zeros(n)
        self._count = np.zeros(n, np.int32)

    def dab(self, center) -> tuple[np.ndarray, np.ndarray]:
        """Solve a dab at ``center`` on the stroke's first positions and blend it in: the vertices it
        solved for and their blended positions."""
        d = finite_preview(self.brush, center)
        self.brush.discard()
        idx = np.asarray(d.indices, np.int64)
        if idx.size == 0:
            return idx, np.zeros((0, 3))
        P = np.asarray(d.positions, np.float64)
        t = np.linalg.norm(np.asarray(d.previous, np.float64) - np.asarray(center, np.float64), axis=1) / d.radius
        f = smooth_falloff(np.minimum(t, 1.0))
        self._num[idx] += f[:, None] * P
        self._den[idx] += f
        self._count[idx] += 1
        den = self._den[idx][:, None]
        mean = np.divide(self._num[idx], den, out=P.copy(), where=den > 0)
        return idx, np.where((self._count[idx] == 1)[:, None], P, mean)


class Sculptor:
    """The sculpt brushes of a :class:`~shapeflow.studio.session.StudioSession`: one brush at a time (the
    enhancement brush or the inflate brush), kept while it holds the session's positions (``key``: the
    shape version it holds, and whether it inflates), and the open stroke's :class:`StrokeBlend`."""

    def __init__(self):
        self.brush = self.key = self.blend = None
        self.last = (0.1, -50.0)          # the enhancement brush's last radius and λ

    def end(self) -> None:
        """A stroke begins or ends: the next enhancement dab starts a new blend."""
        self.blend = None

    def forget(self) -> None:
        """Drop the brush and the blend (the sharp edges they keep changed): built anew at the next dab."""
        self.brush = self.key = self.blend = None

    def brush_for(self, at, version: int, n: int, weights, features, *, inflate: bool, blend: bool,
                  radius: float, lam: float, strength: float):
        """The brush of the next dabs, set to ``radius`` and ``lam`` (inflate: ``strength``) and the
        weights ``weights()`` gives; for an enhancement stroke (``blend``) :attr:`blend` is the open
        blend if nothing else moved the shape since its last dab, else a new one.  A brush built anew
        is built on ``at()`` (the current positions as a mesh) with ``features(inflate)`` (the sharp
        edges it keeps, as keyword arguments; called before ``weights()``)."""
        from ..sculpt import InflateBrush

        if not (blend and not inflate and self.blend is not None and self.blend.version == version):
            self.blend = None
            if not inflate:
                self.last = (radius, lam)
                if self.brush is None or self.key != (version, False):
                    self.brush, self.key = self.build(at(), weights(), features(False)), (version, False)
            elif self.brush is None or self.key != (version, True):
                kw = features(True)
                self.brush = InflateBrush(at(), radius=radius, strength=strength, weights=weights(), undo_limit=0,
                                          **kw)
                self.key = (version, True)
            if blend and not inflate:
                self.blend = StrokeBlend(self.brush, n, version)
        b = self.brush
        b.set_weights(weights())      # painted since the brush was built: no rebuild for that
        b.radius = radius
        if inflate:
            b.strength = strength
        else:
            b.lam = lam
        return b

    def dab(self, center) -> tuple[np.ndarray, np.ndarray]:
        """One dab of the brush :meth:`brush_for` made ready: into the blend, or (no blend) committed to
        the brush; the vertices it moved and their new positions."""
        if self.blend is not None:
            return self.blend.dab(center)
        d = finite_preview(self.brush, center)
        idx = np.asarray(self.brush.commit(), np.int64)
        return idx, np.array(d.positions, np.float64)

    def settled(self, version: int) -> None:
        """The dabs are recorded and the session's shape is at ``version``: what the blend's last dab
        left, or (dabs committed) what the brush holds."""
        if self.blend is not None:
            self.blend.version = version
        elif self.key is not None:
            self.key = (version, self.key[1])

    def build(self, mesh, weights, features):
        """The enhancement brush on ``mesh`` at the last radius and λ with the sharp edges ``features``
        (keyword arguments; undo_limit=0: the session keeps the history, the brush none of its own)."""
        from ..sculpt import Brush

        return Brush(mesh, radius=self.last[0], lam=self.last[1], falloff="smooth", weights=weights, undo_limit=0,
                     **features)
