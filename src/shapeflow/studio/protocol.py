"""The messages a studio page may send: one table, message type → fields → handler.

A page sends JSON objects ``{"op": NAME, ...}``.  :func:`parse` turns the text of one message into
``(op, fields)`` or raises :class:`~shapeflow.errors.ParameterError` naming what is wrong — before
anything changes: the text must be one JSON object (no ``NaN``/``Infinity`` literals, nesting at
most :data:`MAX_DEPTH` deep), its ``op`` one of :data:`MESSAGES`, every other key one of that
message's fields, and every value of its field's kind (finite numbers within their bounds, booleans
that are booleans, names from their list, at most :data:`MAX_LAMS` λ values).  Any message may
carry an ``id`` (an integer the page numbers its requests with), echoed to that page alone in
the ``done`` message that follows the answer (or in the ``error`` message).  A message's handler
(in :mod:`~shapeflow.studio.hub`) receives only checked values; the bounds that depend on the
mesh (a brush centre near the model, a radius below ten diagonals) are checked there.

======== ================================================ =========================================
op       fields                                           effect
======== ================================================ =========================================
lam      value (λ), field ("curvature", "displacement",   preview the family's shape at λ
         "weights" or null)
field    name ("weights", "curvature", "displacement"),   the colour field of the current shape or
         lam (λ or null)                                  of the preview at λ
options  lam_border, iterations (1..100), normalized,     solve the family again with these options
         preserve_volume, compat ("paper", "blender")
solve    lams (1..MAX_LAMS values of λ), or from, to,     solve the family over these λ (and 0)
         step (the command line's family range)
begin    —                                                a stroke begins: its edits are one step
end      —                                                the stroke ends
paint    center (3 numbers), radius (> 0), value (0..1),  paint weights (one undo step, or part of
         strength (0..1), mirror (flag)                   the stroke)
dab      center, radius, lam (λ of the brush), inflate,   one dab of the enhancement or inflate
         strength (inflate: −1..1), mirror (flag)         brush (at λ ≠ 0: the preview applied first)
apply    value (λ)                                        the preview at λ becomes the shape
front    axis ("+x", "-x", "+y", "-y", "+z", "-z", or     the axis the model faces (views, mirror
         null: the file's own)                            plane, downloads)
undo     —                                                take back the last step
redo     —                                                do it again
features on (flag), angle (0..180°, default 30),          keep sharp edges in the family and the
         marked (flag: the file's marked edges too)       brushes (not an edit), drawn as lines
======== ================================================ =========================================
"""

from __future__ import annotations

import json
from dataclasses import dataclass

from .. import params
from ..errors import ParameterError

__all__ = ["MESSAGES", "MAX_DEPTH", "MAX_LAMS", "ID", "parse", "Field"]

#: how deeply a message may nest (a real one nests two levels: an object holding a list)
MAX_DEPTH = 8
#: the most λ values one family solve may ask for (the memory estimate may allow fewer)
MAX_LAMS = 1000
_REQUIRED = object()


@dataclass(frozen=True)
class Field:
    """One field of a message: its kind ("number", "integer", "flag", "choice", "point", "lams"),
    bounds or choices, and its default (required when absent)."""

    kind: str
    lo: float | None = None
    hi: float | None = None
    choices: tuple = ()
    default: object = _REQUIRED
    nullable: bool = False

    def check(self, name: str, x):
        if x is None and self.nullable:
            return None
        if self.kind == "number":
            return params.number(name, x, lo=self.lo, hi=self.hi)
        if self.kind == "integer":
            return params.integer(name, x, lo=int(self.lo), hi=int(self.hi))
        if self.kind == "flag":
            if not isinstance(x, bool):
                raise ParameterError(f"{name} must be true or false, got {_show(x)}")
            return x
        if self.kind == "choice":
            if not isinstance(x, str) or x not in self.choices:
                raise ParameterError(f"{name} must be one of {', '.join(map(str, self.choices))}, got {_show(x)}")
            return x
        if self.kind == "point":
            if not isinstance(x, list) or len(x) != 3:
                raise ParameterError(f"{name} must be a list of 3 numbers, got {_show(x)}")
            return [params.number(f"{name}[{i}]", v) for i, v in enumerate(x)]
        if self.kind == "lams":
            if not isinstance(x, list) or not 1 <= len(x) <= MAX_LAMS:
                raise ParameterError(f"{name} must be a list of 1 to {MAX_LAMS} numbers, got {_show(x)}")
            return [params.number(f"{name}[{i}]", v, lo=self.lo, hi=self.hi) for i, v in enumerate(x)]
        raise AssertionError(self.kind)


LAM = Field("number", -params.LAMBDA_MAX, params.LAMBDA_MAX)
POINT = Field("point")
RADIUS = Field("number", 0.0, None)
UNIT = Field("number", 0.0, 1.0)

#: message type → its fields (the handlers: :data:`shapeflow.studio.hub.HANDLERS`)
MESSAGES: dict[str, dict[str, Field]] = {
    "lam": {"value": LAM, "field": Field("choice", choices=("curvature", "displacement", "weights"),
                                         default=None, nullable=True)},
    "field": {"name": Field("choice", choices=("weights", "curvature", "displacement")),
              "lam": Field("number", LAM.lo, LAM.hi, default=None, nullable=True)},
    "options": {"lam_border": Field("number", LAM.lo, LAM.hi, default=0.0),
                "iterations": Field("integer", 1, 100, default=1),
                "normalized": Field("flag", default=True),
                "preserve_volume": Field("flag", default=False),
                "compat": Field("choice", choices=("paper", "blender"), default="paper")},
    "solve": {"lams": Field("lams", LAM.lo, LAM.hi, default=None, nullable=True),
              "from": Field("number", -1e6, 1e6, default=None, nullable=True),
              "to": Field("number", -1e6, 1e6, default=None, nullable=True),
              "step": Field("number", -1e6, 1e6, default=None, nullable=True)},
    "begin": {},
    "end": {},
    "paint": {"center": POINT, "radius": RADIUS, "value": Field("number", 0.0, 1.0, default=1.0),
              "strength": Field("number", 0.0, 1.0, default=1.0), "mirror": Field("flag", default=False)},
    "dab": {"center": POINT, "radius": RADIUS, "lam": Field("number", -1e6, 1e6, default=-50.0),
            "inflate": Field("flag", default=False), "strength": Field("number", -1.0, 1.0, default=0.05),
            "mirror": Field("flag", default=False)},
    "apply": {"value": LAM},
    "front": {"axis": Field("choice", choices=("+x", "-x", "+y", "-y", "+z", "-z"), nullable=True)},
    "undo": {},
    "redo": {},
    "features": {"on": Field("flag"), "angle": Field("number", 0.0, 180.0, default=30.0),
                 "marked": Field("flag", default=False)},
}


def _show(x) -> str:
    s = json.dumps(x) if isinstance(x, (list, dict, str, int, float, bool, type(None))) else repr(x)
    return s if len(s) <= 60 else s[:57] + "..."


def _refuse_constant(name: str):
    raise ParameterError(f"the message holds {name}: numbers must be finite")


def _depth(x, limit: int) -> int:
    """Nesting depth of a parsed JSON value, stopping past ``limit`` (iterative: no recursion)."""
    deepest, stack = 0, [(x, 1)]
    while stack:
        v, d = stack.pop()
        if isinstance(v, (list, dict)):
            deepest = max(deepest, d)
            if deepest > limit:
                return deepest
            stack.extend((c, d + 1) for c in (v.values() if isinstance(v, dict) else v))
    return deepest


#: a field every message may carry: the tab's number for the request, echoed in the ``done`` (or
#: ``error``) message that answers it, to that tab only
ID = Field("integer", 0, 2**53, default=None, nullable=True)


def parse(text) -> tuple[str, dict]:
    """``(op, fields)`` of one message's text, every field checked and defaults filled in (``id``
    among them: None when the message has none).  A refused message's error carries its ``id``
    (when that was valid) as the attribute ``request_id``, for the answer."""
    if not isinstance(text, str):
        raise ParameterError("a message must be JSON text")
    try:
        msg = json.loads(text, parse_constant=_refuse_constant)
    except ParameterError:
        raise
    except (ValueError, RecursionError) as exc:       # bad JSON, integers of over 4,300 digits
        raise ParameterError(f"the message is not valid JSON ({str(exc)[:80]})") from None
    if not isinstance(msg, dict):
        raise ParameterError(f"a message must be a JSON object, got {type(msg).__name__}")
    if _depth(msg, MAX_DEPTH) > MAX_DEPTH:
        raise ParameterError(f"the message nests deeper than {MAX_DEPTH} levels")
    rid = ID.check("id", msg.get("id"))
    try:
        return _fields(msg, rid)
    except ParameterError as exc:
        exc.request_id = rid
        raise


def _fields(msg: dict, rid) -> tuple[str, dict]:
    op = msg.get("op")
    if not isinstance(op, str) or op not in MESSAGES:
        raise ParameterError(f"unknown operation {_show(op)}; the studio knows {', '.join(MESSAGES)}")
    fields = MESSAGES[op]
    extra = sorted(k for k in msg if k not in ("op", "id") and k not in fields)
    if extra:
        raise ParameterError(f"{op}: unknown field{'s' if len(extra) > 1 else ''} {', '.join(map(_show, extra))}")
    out = {"id": rid}
    for name, f in fields.items():
        if name in msg:
            out[name] = f.check(name, msg[name])
        elif f.default is _REQUIRED:
            raise ParameterError(f"{op}: the field {name!r} is missing")
        else:
            out[name] = f.default
    if "radius" in out and not out["radius"] > 0:
        raise ParameterError(f"{op}: radius must be > 0, got {out['radius']}")
    return op, out
