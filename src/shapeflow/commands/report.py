"""How a command tells what it does: messages, warnings, progress and facts, to whoever runs it.

A command never prints.  It tells a :class:`Reporter`: the command line's prints every line on
stderr and draws a progress bar on a terminal (:class:`shapeflow.cli.common.Terminal`);
:class:`Collector` keeps what was said (``shapeflow batch`` stores it in each file's manifest
record).  The base class keeps nothing: a silent run.
"""

from __future__ import annotations

import contextlib
from typing import Any, Callable, ContextManager

__all__ = ["Reporter", "Collector", "ProgressCallback"]

#: ``progress(done, total)``, called as the work advances
ProgressCallback = Callable[[int, int], None]


class Reporter:
    """Where a command's words go.  Lines come whole, as the user reads them
    (``shapeflow enhance: λ=-5, 1 iteration(s), ...``); this class drops them."""

    def message(self, text: str) -> None:
        """A line about the work: a summary, a stage, what was written where."""

    def warning(self, text: str) -> None:
        """A line about a result that says less than was asked (a collapsed model, a stroke that
        moved nothing)."""

    def progress(self, total: int, desc: str) -> ContextManager[ProgressCallback | None]:
        """For the block: a ``progress(done, total)`` callback over ``total`` units of work, or None
        when nothing shows progress."""
        return contextlib.nullcontext(None)

    def fact(self, key: str, value: Any) -> None:
        """Something the command found, for a record: ``vertices``, ``faces``, the flow's ``report``
        or the family's ``reports``."""


class Collector(Reporter):
    """Keeps what a command said: ``messages`` (warnings among them, in order) and ``facts`` (the
    first value of each key).  Shows no progress."""

    def __init__(self) -> None:
        self.messages: list[str] = []
        self.facts: dict[str, Any] = {}

    def message(self, text: str) -> None:
        self.messages.append(text)

    def warning(self, text: str) -> None:
        self.messages.append(text)

    def fact(self, key: str, value: Any) -> None:
        self.facts.setdefault(key, value)
