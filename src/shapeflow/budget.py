"""Work and memory estimates checked before long work starts.

A request that cannot fit in this machine's memory is refused up front with a
:class:`~shapeflow.errors.ParameterError` that gives the estimate, instead of
failing with ``MemoryError`` after minutes of work.
"""

from __future__ import annotations

import os

from .errors import ParameterError

__all__ = ["available_bytes", "check_memory"]


def _cgroup_room() -> int | None:
    """Bytes left under this process's cgroup (v2) memory limit, or None without one."""
    try:
        with open("/proc/self/cgroup") as f:
            path = next((ln.split(":", 2)[2].strip() for ln in f if ln.startswith("0::")), None)
        if path is None:
            return None
        base = os.path.join("/sys/fs/cgroup", path.lstrip("/"))
        with open(os.path.join(base, "memory.max")) as f:
            limit = f.read().strip()
        if limit == "max":
            return None
        with open(os.path.join(base, "memory.current")) as f:
            return max(int(limit) - int(f.read().strip()), 0)
    except (OSError, ValueError, IndexError):
        return None


def available_bytes() -> int | None:
    """Memory this process can still get: MemAvailable (Linux), bounded by a cgroup limit; None if unknown."""
    room = None
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    room = int(line.split()[1]) * 1024
                    break
    except (OSError, ValueError, IndexError):
        pass
    if room is None:
        try:
            room = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        except (ValueError, OSError, AttributeError):
            room = None
    cg = _cgroup_room()
    if cg is not None:
        room = cg if room is None else min(room, cg)
    return room


def _size(n: float) -> str:
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if n >= scale:
            return f"{n / scale:.3g} {unit}"
    return f"{n:.3g} bytes"


def check_memory(what: str, need: float, *, parameter: str) -> None:
    """Refuse (ParameterError naming ``parameter``) work estimated to need more than the memory available."""
    room = available_bytes()
    if room is not None and need > room:
        raise ParameterError(f"{parameter}: {what} needs about {_size(need)} of memory; "
                             f"this machine has {_size(room)} available")
