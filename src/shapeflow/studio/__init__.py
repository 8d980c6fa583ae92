"""ShapeFlow Studio: interactive shape enhancement, weight painting and the brush.

This package holds the studio's model, :class:`StudioSession`; the browser front end and
its server build on it.
"""

from .session import FamilyStatus, StudioSession, smooth_falloff

__all__ = ["StudioSession", "FamilyStatus", "smooth_falloff"]
