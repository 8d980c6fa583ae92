"""What a batch did: :class:`BatchReport`."""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["BatchReport"]


@dataclass
class BatchReport:
    """The outcome of :func:`shapeflow.batch.run`.

    ``records`` are the manifest records of the files this run processed (done or
    failed), in the order they finished; ``skipped`` the inputs already done by an
    earlier run with the same parameters.
    """

    records: list = field(default_factory=list)
    skipped: list = field(default_factory=list)
    seconds: float = 0.0
    workers: int = 0
    manifest: str = ""
    dashboard: str | None = None
    interrupted: bool = False
    notices: list = field(default_factory=list)   #: what the run said before processing (see ``run``)

    @property
    def done(self) -> list:
        return [r for r in self.records if r["status"] == "done"]

    @property
    def failed(self) -> list:
        return [r for r in self.records if r["status"] != "done"]

    @property
    def ok(self) -> bool:
        """No file failed and the run was not interrupted."""
        return not self.failed and not self.interrupted

    @property
    def files_per_second(self) -> float:
        return len(self.records) / self.seconds if self.seconds > 0 else 0.0

    def slowest(self, k: int = 3) -> list:
        return sorted(self.done, key=lambda r: -r["seconds"])[:k]

    def summary(self, *, failures: int = 10) -> str:
        """A few lines: counts, throughput, slowest files, the first failures with their errors."""
        head = (f"{len(self.done)} done, {len(self.skipped)} skipped (done before), {len(self.failed)} failed "
                f"in {self.seconds:.1f} s ({self.files_per_second:.2f} files/s on {self.workers} workers)")
        if self.interrupted:
            head += "; interrupted (run the same command again to resume)"
        lines = [head]
        slow = self.slowest()
        if slow:
            lines.append("slowest: " + ", ".join(f"{r['input']} {r['seconds']:.2f} s" for r in slow))
        for r in self.failed[:failures]:
            err = str(r["error"])
            lines.append(f"failed: {err}" if r["input"] in err else f"failed: {r['input']}: {err}")
        if len(self.failed) > failures:
            lines.append(f"... and {len(self.failed) - failures} more failures (see the manifest)")
        lines.append(f"manifest: {self.manifest}")
        return "\n".join(lines)
