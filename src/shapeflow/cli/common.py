"""Helpers shared by the subcommands."""

from __future__ import annotations

import contextlib
import contextvars
import sys
from dataclasses import dataclass, field

#: files from this size on get a line on stderr as each stage starts (reading, solving, writing)
STAGE_NOTES_FROM = 64 * 2**20


def load_mesh_arg(arg: str, *, faces: bool = True, quiet: bool = True, command: str = ""):
    """Load a mesh given on the command line: a path or ``example:NAME``.

    A mesh without faces (a point cloud) is refused unless ``faces=False``: no command
    that smooths, subdivides or sculpts has anything to work on.  With ``quiet=False``, a file of
    :data:`STAGE_NOTES_FROM` bytes or more is announced and its load time said."""
    if arg.startswith("example:"):
        from ..examples import load_example

        mesh = load_example(arg.split(":", 1)[1])
    else:
        import os
        import time

        from ..io import load

        size = os.path.getsize(arg) if os.path.isfile(arg) else 0
        big = not quiet and size >= STAGE_NOTES_FROM
        if big:
            eprint(f"shapeflow {command}: reading {arg} ({size / 2**30:.2f} GiB)")
        t0 = time.perf_counter()
        mesh = load(arg)
        if big:
            eprint(f"shapeflow {command}: {mesh.n_vertices:,} vertices, {mesh.n_faces:,} faces read in "
                   f"{time.perf_counter() - t0:.1f} s")
    note_fact("vertices", mesh.n_vertices)
    note_fact("faces", mesh.n_faces)
    if faces and mesh.n_faces == 0:
        from ..errors import MeshError

        raise MeshError(f"{arg}: no faces ({mesh.n_vertices} vertices only: a point cloud?); "
                        "shapeflow works on polygon meshes")
    return mesh


def option_number(option: str, value: float, *, lo: float | None = None) -> float:
    """A number given with ``option``, checked in the user's terms before it becomes a library
    parameter: ``--strength must be finite, got inf`` (not the library's ``lam`` with its sign)."""
    from .. import params
    from ..errors import ParameterError

    v = params.number(option, value, lo=lo)
    if abs(v) > params.LAMBDA_MAX:
        name = option if lo is not None and lo >= 0 else f"|{option}|"
        raise ParameterError(f"{name} must be <= {params.LAMBDA_MAX:g} (beyond it the flow's system is singular in "
                             f"double precision, and one step is its limit already), got {v:g}")
    return v


@contextlib.contextmanager
def option_names(names: dict):
    """Within the block, a library ParameterError that starts with a parameter's name (``iterations
    must be >= 0``, ``|lam_border| must be ...``) is told with the option's name instead
    (``names``: parameter -> option, e.g. ``{"iterations": "--iterations"}``)."""
    import re

    from ..errors import ParameterError

    try:
        yield
    except ParameterError as exc:
        text = str(exc)
        m = re.match(r"^(\|?)([A-Za-z_][A-Za-z_0-9]*)(\|?)(\b.*)$", text, re.S)
        if m and m.group(2) in names:
            raise type(exc)(f"{m.group(1)}{names[m.group(2)]}{m.group(3)}{m.group(4)}") from None
        raise


@dataclass
class Collected:
    """What a command said and did while :func:`collecting` was active."""

    messages: list = field(default_factory=list)   #: the lines it would have printed on stderr
    facts: dict = field(default_factory=dict)      #: first value of each fact (vertices, faces, report...)


_SINK: contextvars.ContextVar[Collected | None] = contextvars.ContextVar("shapeflow_cli_sink", default=None)


@contextlib.contextmanager
def collecting():
    """Within the block, the commands' stderr lines and facts go to the yielded :class:`Collected`.

    ``shapeflow batch`` runs the commands this way, so each file's messages and flow report
    land in its manifest record.  Per context (thread or task), like :mod:`contextvars`.
    """
    sink = Collected()
    token = _SINK.set(sink)
    try:
        yield sink
    finally:
        _SINK.reset(token)


def note_fact(key: str, value) -> None:
    """Record a fact for :func:`collecting` (the first value of a key stays); nothing outside it."""
    sink = _SINK.get()
    if sink is not None:
        sink.facts.setdefault(key, value)


def eprint(*a, **kw) -> None:
    sink = _SINK.get()
    if sink is not None:
        sink.messages.append(kw.get("sep", " ").join(str(x) for x in a))
        return
    print(*a, file=sys.stderr, **kw)


def resolve_output(input_arg: str, output: str, force: bool, *others: str | None) -> str:
    """Check every output path before any work; refuse to overwrite the input unless forced.

    ``others`` are further outputs of the command (``--image``, ``--weights-out``).  Each must be
    writable (:func:`shapeflow.io.output_target`): its folder exists, it is not bundled data, and
    it is not read-only unless ``--force``.  Returns ``output``.
    """
    import os

    from ..errors import ParameterError
    from ..io import output_target

    if not input_arg.startswith("example:") and os.path.exists(output) and os.path.exists(input_arg) \
            and os.path.samefile(input_arg, output) and not force:
        raise ParameterError(f"output {output!r} is the input file; pass --force to overwrite it")
    from ..io.registry import format_for

    for path in (output, *others):
        if path:
            output_target(path, force=force)
    from ..io.weights import WEIGHT_EXTENSIONS

    if os.path.splitext(output)[1].lower() not in WEIGHT_EXTENSIONS:   # values files (curvature) aside,
        format_for(output, None)                                       # an unknown format fails now
    return output


def save_mesh(path: str, mesh, force: bool = False, *, quiet: bool = True, command: str = "") -> None:
    """Write atomically (the I/O layer writes a temporary file, then renames it); with ``quiet=False``
    a mesh of a million vertices or more is announced."""
    from ..io import save

    if not quiet and mesh.n_vertices >= 1_000_000:
        eprint(f"shapeflow {command}: writing {path}")
    save(path, mesh, force=force)


def write_values(path: str, values, force: bool = False) -> None:
    """Per-vertex values to ``.npy`` (exact) or text (one value a line, ``%.17g``), atomically."""
    import numpy as np

    from ..io import atomic_write

    if path.lower().endswith(".npy"):
        atomic_write(path, lambda f: np.save(f, values, allow_pickle=False), force=force)
    else:
        atomic_write(path, lambda f: np.savetxt(f, values, fmt="%.17g"), force=force)


class progress_callback:
    """Context manager giving a ``progress(done, total)`` callback: a tqdm bar on a
    terminal when tqdm is installed (extra ``progress``), else nothing."""

    def __init__(self, total: int, desc: str, quiet: bool = False):
        self.total = total
        self.desc = desc
        self.quiet = quiet
        self.bar = None

    def __enter__(self):
        if self.quiet or self.total < 2 or not sys.stderr.isatty():
            return None
        try:
            from tqdm import tqdm
        except Exception:   # noqa: BLE001 - no bars without a working tqdm
            return None
        self.bar = tqdm(total=self.total, desc=self.desc, unit="it", file=sys.stderr, leave=False)

        def cb(done, total):
            self.bar.update(done - self.bar.n)

        return cb

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.close()
        return False


def may_need_weld(mesh) -> bool:
    """False for a mesh whose faces leave no boundary edge: a vertex split at a seam (or a soup) always
    leaves boundary edges along it, so a closed mesh has nothing to weld and skips the neighbour search
    (2.6 s for a 2M-vertex scan, 2026-11-24)."""
    return bool(mesh.n_faces) and bool(mesh.topology.boundary_edge_mask.any())


def welded_for_operator(mesh, kw: dict, command: str, quiet: bool):
    """The mesh the operator works on, and how to put a result back on the input's layout.

    A mesh whose vertices are split at seams (or a triangle soup) is welded for the operator
    (:func:`shapeflow.weld`) and the result scattered back, so every copy of a vertex moves alike
    and the file keeps its layout and attributes; the command says so.  Weights given as an array
    follow the weld.  Returns ``(mesh, kw, restore)``.
    """
    import numpy as np

    from ..geometry.weld import unweld, weld

    welded = weld(mesh) if may_need_weld(mesh) else mesh     # one neighbour search decides and welds
    if welded.n_vertices == mesh.n_vertices:
        return mesh, kw, (lambda result: result)
    first = np.unique(welded.weld_map, return_index=True)[1]
    if isinstance(kw.get("weights"), np.ndarray):
        kw = {**kw, "weights": kw["weights"][first]}
    if not quiet:
        eprint(f"shapeflow {command}: {mesh.n_vertices - welded.n_vertices} vertices coincide with others "
               f"(seams or a triangle soup): welded to {welded.n_vertices} for the operator, "
               "the result written on the input's layout")
    return welded, kw, (lambda result: unweld(result, mesh, welded))


#: from this |λ| on, the result is checked for the limits of the flow (collapse, rescaling)
STRONG_LAMBDA = 1e3


def warn_degenerate_result(command: str, lam: float, before, after) -> None:
    """A one-line warning when a very large λ gave a result that says little: smoothing that
    collapsed the model towards a point, or enhancement that only rescaled it."""
    import numpy as np

    V, X = before.vertices, after.vertices
    moved = float(np.linalg.norm(X - V))
    if moved == 0.0 or V.shape[0] < 4 or abs(lam) < STRONG_LAMBDA:
        return
    c = V.mean(axis=0)
    if lam > 0 and after.diagonal < 0.05 * before.diagonal:
        eprint(f"shapeflow {command}: warning: λ={lam:g} collapsed the model to {after.diagonal / before.diagonal:.1%} "
               "of its size (the limit of strong smoothing is the mean position); try a smaller λ")
        return
    D = V - c
    s = float(np.einsum("ij,ij->", X - c, D) / max(np.einsum("ij,ij->", D, D), np.finfo(float).tiny))
    rest = float(np.linalg.norm(X - c - s * D))
    if lam < 0 and rest < 0.05 * moved:
        eprint(f"shapeflow {command}: warning: λ={lam:g} mostly rescaled the model (by {s:.3g}; "
               f"{rest / moved:.1%} of the motion is a change of shape); try a smaller |λ|")


def note_compiling(consumers: tuple, size: int, *, min_size: int | None = None, quiet: bool = False) -> bool:
    """Say once that the compiled kernels are being compiled (the first run on this machine takes
    tens of seconds; later runs load them from numba's cache).  Returns whether it said so."""
    from pathlib import Path

    from .. import accel

    if quiet or not accel.current().uses_compiled(size, min_size=min_size):
        return False
    import importlib

    missing = []
    for name in consumers:
        mod = importlib.import_module(f"shapeflow.{name}.compiled")
        cache = Path(mod.__file__).parent / "__pycache__"
        if not any(cache.glob("compiled.*.nbi")):
            missing.append(name)
    if missing:
        eprint("shapeflow: compiling the fast kernels (first run on this machine only; later runs load them "
               "from numba's cache)")
    return bool(missing)
