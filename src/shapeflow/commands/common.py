"""What the operations share: meshes in and out, checks of option values in the user's terms, the weld
for the operator, and the warnings about results that say little."""

from __future__ import annotations

import contextlib

from .report import Reporter

#: files from this size on get a line as each stage starts (reading, solving, writing)
STAGE_NOTES_FROM = 64 * 2**20


def load_mesh(arg: str, report: Reporter, *, faces: bool = True, quiet: bool = True, command: str = ""):
    """Load a mesh named as on the command line: a path or ``example:NAME``.

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
            report.message(f"shapeflow {command}: reading {arg} ({size / 2**30:.2f} GiB)")
        t0 = time.perf_counter()
        mesh = load(arg)
        if big:
            report.message(f"shapeflow {command}: {mesh.n_vertices:,} vertices, {mesh.n_faces:,} faces read in "
                           f"{time.perf_counter() - t0:.1f} s")
    report.fact("vertices", mesh.n_vertices)
    report.fact("faces", mesh.n_faces)
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


def progress(report: Reporter, total: int, desc: str, quiet: bool = False):
    """``report``'s progress for the block, or none when ``quiet``."""
    return contextlib.nullcontext(None) if quiet else report.progress(total, desc)


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


def save_mesh(path: str, mesh, force: bool, report: Reporter, *, quiet: bool = True, command: str = "") -> None:
    """Write atomically (the I/O layer writes a temporary file, then renames it); with ``quiet=False``
    a mesh of a million vertices or more is announced."""
    from ..io import save

    if not quiet and mesh.n_vertices >= 1_000_000:
        report.message(f"shapeflow {command}: writing {path}")
    save(path, mesh, force=force)


def write_values(path: str, values, force: bool = False) -> None:
    """Per-vertex values to ``.npy`` (exact) or text (one value a line, ``%.17g``), atomically."""
    import numpy as np

    from ..io import atomic_write

    if path.lower().endswith(".npy"):
        atomic_write(path, lambda f: np.save(f, values, allow_pickle=False), force=force)
    else:
        atomic_write(path, lambda f: np.savetxt(f, values, fmt="%.17g"), force=force)


def welded_for_operator(mesh, kw: dict, command: str, quiet: bool, report: Reporter):
    """The mesh the operator works on, and how to put a result back on the input's layout.

    A mesh whose vertices are split at seams (or a triangle soup) is welded for the operator
    (:func:`shapeflow.weld`) and the result scattered back, so every copy of a vertex moves alike
    and the file keeps its layout and attributes; the command says so.  Weights given as an array
    and sharp edges given as vertex pairs follow the weld (a pair whose two vertices become one is
    dropped).  Returns ``(mesh, kw, restore)``.
    """
    import numpy as np

    from ..geometry.weld import unweld, weld_if_split

    welded = weld_if_split(mesh)     # a closed mesh skips the neighbour search; one search decides and welds
    if welded is mesh:
        return mesh, kw, (lambda result: result)
    first = np.unique(welded.weld_map, return_index=True)[1]
    if isinstance(kw.get("weights"), np.ndarray):
        kw = {**kw, "weights": kw["weights"][first]}
    if isinstance(kw.get("sharp_edges"), np.ndarray):
        pairs = welded.weld_map[kw["sharp_edges"]]
        kw = {**kw, "sharp_edges": pairs[pairs[:, 0] != pairs[:, 1]]}
    if not quiet:
        report.message(f"shapeflow {command}: {mesh.n_vertices - welded.n_vertices} vertices coincide with others "
                       f"(seams or a triangle soup): welded to {welded.n_vertices} for the operator, "
                       "the result written on the input's layout")
    return welded, kw, (lambda result: unweld(result, mesh, welded))


#: from this |λ| on, the result is checked for the limits of the flow (collapse, rescaling)
STRONG_LAMBDA = 1e3


def warn_degenerate_result(report: Reporter, command: str, lam: float, before, after) -> None:
    """A one-line warning when a very large λ gave a result that says little: smoothing that
    collapsed the model towards a point, or enhancement that only rescaled it."""
    import numpy as np

    V, X = before.vertices, after.vertices
    moved = float(np.linalg.norm(X - V))
    if moved == 0.0 or V.shape[0] < 4 or abs(lam) < STRONG_LAMBDA:
        return
    c = V.mean(axis=0)
    if lam > 0 and after.diagonal < 0.05 * before.diagonal:
        report.warning(f"shapeflow {command}: warning: λ={lam:g} collapsed the model to "
                       f"{after.diagonal / before.diagonal:.1%} of its size (the limit of strong smoothing is the "
                       "mean position); try a smaller λ")
        return
    D = V - c
    s = float(np.einsum("ij,ij->", X - c, D) / max(np.einsum("ij,ij->", D, D), np.finfo(float).tiny))
    rest = float(np.linalg.norm(X - c - s * D))
    if lam < 0 and rest < 0.05 * moved:
        report.warning(f"shapeflow {command}: warning: λ={lam:g} mostly rescaled the model (by {s:.3g}; "
                       f"{rest / moved:.1%} of the motion is a change of shape); try a smaller |λ|")


def note_compiling(report: Reporter, consumers: tuple, size: int, *, min_size: int | None = None,
                   quiet: bool = False, command: str = "") -> bool:
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
        report.message(f"shapeflow{' ' + command if command else ''}: compiling the fast kernels (first run on this "
                       "machine only; later runs load them from numba's cache)")
    return bool(missing)
