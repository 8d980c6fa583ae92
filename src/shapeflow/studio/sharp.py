"""Sharp features in the studio: the "Keep sharp edges" setting of a session, and what follows from it.

:class:`SharpFeatures` is a part of :class:`~shapeflow.studio.session.StudioSession`: with the setting
on, the family is solved with ``feature_angle`` (and, when asked, the edges the opened file marks:
:func:`shapeflow.commands.features.marked_edges`, on the session's welded numbering) — flat faces
stay flat, straight edges straight, corners stay (:mod:`shapeflow.flow.features`) — and the
enhancement brush is built with the same sharp edges; the inflate brush, which moves vertices along
their normals, holds the vertices on a sharp edge where they are.  The sharp edges are those of the
current shape (the dihedral angle at the positions the family is solved from).  Changing the setting
is not an edit: the history, the version and the positions stay as they are.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .. import params
from ..errors import ParameterError

__all__ = ["SharpFeatures", "FeatureSetting", "DEFAULT_ANGLE"]

#: the angle the setting starts with (degrees between two faces' normals)
DEFAULT_ANGLE = 30.0


@dataclass(frozen=True)
class FeatureSetting:
    """Whether sharp edges are kept, from which dihedral angle (degrees, 0..180), and whether the
    edges the opened file marks are kept too."""

    on: bool = False
    angle: float = DEFAULT_ANGLE
    marked: bool = False


class SharpFeatures:
    """The sharp-feature half of a studio session (it uses the session's ``_lock``, ``_base``,
    ``_input``, ``_V`` and ``_sculpt``)."""

    _feature_setting = FeatureSetting()
    _marked_pairs: np.ndarray | None = None
    _held: np.ndarray | None = None          # vertices on a sharp edge when the brush was built

    @property
    def features(self) -> dict:
        """``{"on": …, "angle": …, "marked": …}``: the current setting."""
        with self._lock:
            return asdict(self._feature_setting)

    def set_features(self, on: bool, angle: float = DEFAULT_ANGLE, marked: bool = False) -> bool:
        """Keep sharp edges (``on``) whose faces bend by more than ``angle`` degrees, and with ``marked``
        the edges the opened file marks; True when this changes what the family and the brushes use
        (solve the family again then).  Not an edit: nothing enters the history."""
        new = FeatureSetting(params.flag("on", on), params.number("angle", angle, lo=0.0, hi=180.0),
                             params.flag("marked", marked))
        if new.marked and self.marked_count == 0:
            raise ParameterError("marked: the file marks no sharp edge (no smoothing-group border, "
                                 "no 't crease' tag, no split normal)")
        with self._lock:
            old, self._feature_setting = self._feature_setting, new
            changed = self._feature_options(old) != self._feature_options(new)
            if changed:
                self._sculpt.forget()             # rebuilt with the new sharp edges at the next dab
            return changed

    @property
    def marked_count(self) -> int:
        """How many edges the opened file marks sharp (0 when its marks cannot be read)."""
        return int(len(self.marked_pairs))

    @property
    def marked_pairs(self) -> np.ndarray:
        """(k, 2) the edges the opened file marks sharp, as vertex pairs of the session's (welded) mesh."""
        with self._lock:
            if self._marked_pairs is None:
                self._marked_pairs = _marked_pairs(self._input, self._base)
            return self._marked_pairs

    @staticmethod
    def _feature_options(setting: FeatureSetting) -> tuple:
        return (setting.angle, setting.marked) if setting.on else None

    def feature_options(self) -> dict:
        """``feature_angle`` and ``sharp_edges`` for :func:`shapeflow.family` and
        :class:`~shapeflow.sculpt.Brush` under the current setting (empty when it is off)."""
        with self._lock:
            f = self._feature_setting
            if not f.on:
                return {}
            return {"feature_angle": f.angle, "sharp_edges": self.marked_pairs if f.marked else None}

    def sharp_edges(self, vertices=None) -> np.ndarray:
        """(k, 2) the sharp edges the setting keeps, as vertex pairs, at ``vertices`` (default: the
        current positions); none when the setting is off."""
        from ..flow.features import resolve_sharp_edges

        with self._lock:
            kw = self.feature_options()
            V = self._V if vertices is None else np.asarray(vertices, np.float64)
            if not kw:
                return np.zeros((0, 2), np.int64)
            sharp = resolve_sharp_edges(self._base.with_vertices(V), kw["feature_angle"], kw["sharp_edges"])
            return self._base.topology.edges[sharp].astype(np.int64)

    def _brush_features(self, inflate: bool) -> dict:
        """What a brush built now at the current positions takes: the enhancement brush the sharp edges
        (keyword arguments), the inflate brush none — it keeps the vertices on them (:meth:`_dab_weights`)."""
        with self._lock:
            self._held = None
            kw = self.feature_options()
            if not kw:
                return {}
            if not inflate:
                return kw
            held = np.zeros(self._V.shape[0], bool)
            held[self.sharp_edges().reshape(-1)] = True
            self._held = held
            return {}

    def _dab_weights(self, w: np.ndarray) -> np.ndarray:
        """The weights a dab of the current brush uses: 0 on the vertices it holds."""
        if self._held is not None:
            w = np.where(self._held, 0.0, w)
        return w


def _marked_pairs(mesh, base) -> np.ndarray:
    """The file's marked edges of ``mesh`` (as opened) as vertex pairs of ``base`` (as welded); none when
    the marks cannot be read (a malformed 't crease' tag matters only to those who keep the marks)."""
    from ..commands.features import marked_edges

    try:
        marks = marked_edges(mesh, str(mesh.metadata.get("name") or "the file"))
    except ParameterError:
        return np.zeros((0, 2), np.int64)
    pairs = mesh.topology.edges[marks.sharp].astype(np.int64)
    if base is not mesh:
        pairs = base.weld_map[pairs]
        pairs = pairs[pairs[:, 0] != pairs[:, 1]]
        pairs = np.unique(np.sort(pairs, axis=1), axis=0)
    return pairs
