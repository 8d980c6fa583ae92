"""The studio's undo history: steps that keep only the vertices they changed, strokes as one step,
bounded in bytes.

A step keeps the indices it touched and their positions and weights before and after (a step
that changed no position keeps no positions, one that changed no weight no weights).  A *group*
(a stroke: pointer down to pointer up) gathers every edit made while it is open into one step:
the union of the vertices touched, each with its first "before" and its last "after".  Merging
is vectorised: a boolean mask of the vertices already in the group picks the new ones of each
edit (O(size of the edit)), whose "before" values are taken before the edit applies; the
"after" values are read once, when the group closes.

The history holds at most ``limit`` bytes (:func:`default_limit`): the oldest steps are dropped
first, the newest is always kept.  :attr:`History.modified` says whether the state differs from
the one marked saved (the state as opened, or at the last :meth:`History.mark_saved`): the
history remembers which step was on top then, so undoing back to a saved state counts as
unmodified.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import params

__all__ = ["History", "Step", "default_limit", "DEFAULT_LIMIT"]

#: the history's bound when memory is plentiful, bytes
DEFAULT_LIMIT = 256 << 20
_LOST = object()       # the saved state fell off the bottom of the history: every reachable state differs


def default_limit() -> int:
    """256 MiB, or a quarter of the memory available when that is less (at least 16 MiB)."""
    from ..budget import available_bytes

    room = available_bytes()
    return DEFAULT_LIMIT if room is None else int(max(16 << 20, min(DEFAULT_LIMIT, room // 4)))


@dataclass
class Step:
    """One undo step: the vertices it touched, before and after (None: not changed by the step)."""

    what: str
    idx: np.ndarray
    v_before: np.ndarray | None
    v_after: np.ndarray | None
    w_before: np.ndarray | None
    w_after: np.ndarray | None

    @classmethod
    def of(cls, what, idx, vb, va, wb, wa) -> "Step":
        if np.array_equal(vb, va):
            vb = va = None
        if np.array_equal(wb, wa):
            wb = wa = None
        return cls(what, idx, vb, va, wb, wa)

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in (self.idx, self.v_before, self.v_after, self.w_before, self.w_after)
                   if a is not None)


class _Group:
    """An open group: the vertices touched so far (a mask and chunks of indices) and their first 'before'."""

    def __init__(self, what: str, n: int):
        self.what = what
        self.seen = np.zeros(n, dtype=bool)
        self.idx: list = []
        self.vb: list = []
        self.wb: list = []

    def add(self, idx: np.ndarray, V: np.ndarray, w: np.ndarray) -> None:
        new = np.unique(idx[~self.seen[idx]])
        if new.size:
            self.seen[new] = True
            self.idx.append(new)
            self.vb.append(V[new])
            self.wb.append(w[new])

    def step(self, V: np.ndarray, w: np.ndarray) -> Step | None:
        if not self.idx:
            return None
        idx = np.concatenate(self.idx)
        return Step.of(self.what, idx, np.concatenate(self.vb), V[idx], np.concatenate(self.wb), w[idx])


class History:
    """Undo and redo stacks of :class:`Step` bounded by ``limit`` bytes, with groups (see the module
    docstring).  The session owns the arrays; the history reads them and tells it what to write."""

    def __init__(self, limit: int | None = None):
        self.limit = default_limit() if limit is None else params.integer("history_bytes", limit, lo=1)
        self.undo: list[Step] = []
        self.redo: list[Step] = []
        self.bytes = 0
        self._group: _Group | None = None
        self._saved = None          # the step on top of the undo stack in the saved state (None: empty)

    # --- recording ---------------------------------------------------------
    @property
    def grouping(self) -> bool:
        return self._group is not None

    def open(self, what: str, n: int) -> None:
        """Gather the following edits into one step (an open group is closed first)."""
        self._group = _Group(what, n)

    def close(self, V, w) -> bool:
        """Close the open group: its edits become one step.  False when no group was open."""
        g, self._group = self._group, None
        if g is None:
            return False
        step = g.step(V, w)
        if step is not None:
            self._push(step)
        return True

    def record(self, what: str, idx: np.ndarray, V, w, apply, *, alone: bool = False) -> None:
        """``apply()`` writes new positions or weights of the vertices ``idx`` into ``V``/``w``; the
        history keeps what it needs to take that back: part of the open group, or (``alone``, or
        no group open) a step of its own."""
        if self._group is not None and not alone:
            self._group.add(idx, V, w)
            self.redo.clear()
            apply()
            return
        if self._group is not None:              # the group so far becomes a step; it stays open
            what_g, n = self._group.what, self._group.seen.size
            self.close(V, w)
            self._group = _Group(what_g, n)
        vb, wb = V[idx], w[idx]
        apply()
        self._push(Step.of(what, idx, vb, V[idx], wb, w[idx]))

    def _push(self, step: Step) -> None:
        self.undo.append(step)
        self.bytes += step.nbytes
        for s in self.redo:
            self.bytes -= s.nbytes
        self.redo.clear()
        while self.bytes > self.limit and len(self.undo) > 1:     # the oldest go first; the newest stays
            old = self.undo.pop(0)
            self.bytes -= old.nbytes
            if self._saved is None:
                self._saved = _LOST            # the saved state (before `old`) can no longer be reached
            elif self._saved is old:
                self._saved = None             # the state after `old` is now the bottom of the history

    # --- moving through it ---------------------------------------------------
    def back(self, V, w) -> Step | None:
        """The step to take back (moved to the redo stack), after closing an open group; None when
        there is none.  The caller writes ``v_before``/``w_before``."""
        self.close(V, w)
        if not self.undo:
            return None
        step = self.undo.pop()
        self.redo.append(step)
        return step

    def forward(self, V, w) -> Step | None:
        """The step to do again (moved back to the undo stack); the caller writes ``v_after``/``w_after``."""
        self.close(V, w)
        if not self.redo:
            return None
        step = self.redo.pop()
        self.undo.append(step)
        return step

    # --- saved or not --------------------------------------------------------
    def mark(self):
        """A token for the current state (the step on top of the undo stack)."""
        return self.undo[-1] if self.undo else None

    def mark_saved(self, mark) -> None:
        """The state ``mark`` (from :meth:`mark`) was saved."""
        self._saved = mark

    @property
    def pending(self) -> bool:
        """Whether an open group holds edits (a step once it closes)."""
        return self._group is not None and bool(self._group.idx)

    @property
    def modified(self) -> bool:
        """Whether the state differs from the one last saved (or opened)."""
        return self.mark() is not self._saved or self.pending
