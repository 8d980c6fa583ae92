"""``family IN OUTDIR --from 0 --to -240 --step -5``: one mesh per λ (figure 1).

The members come from :func:`shapeflow.family` (one shared multi-shift solve
where the flow options allow it).  File names carry the member's position and
its λ with a fixed width, e.g. ``spot_00_lam+000.0.ply`` …
``spot_48_lam-240.0.ply``, so a plain sort lists them in family order.  ``--to`` is included when it
lies on the grid ``--from + k·--step``.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import params
from ..errors import ParameterError
from .common import load_mesh, option_names, option_number, progress, save_mesh, welded_for_operator
from .flow import OPTION_NAMES, FlowSettings, add_flow_options
from .report import Reporter

__all__ = ["FamilyOptions", "member_lambdas", "member_names", "in_words", "add_parser", "run"]

#: members solved in one batch are held in memory together; above this many
#: bytes of positions the family is solved in batches (in order of |λ|)
BATCH_BYTES = 512 * 2 ** 20
MAX_MEMBERS = 100_000
FORMATS = ("ply", "obj", "off", "stl", "glb", "gltf")


@dataclass(frozen=True)
class FamilyOptions(FlowSettings):
    """Options of ``family``: the flow's, the members' λ (``lambdas``, a comma-separated list, or
    ``lam_from``/``lam_to``/``lam_step``), and the members' file names.  ``lams`` is the checked
    list of λ, made with the object."""

    lambdas: str | None = None
    lam_from: float | None = None
    lam_to: float | None = None
    lam_step: float | None = None
    name: str | None = None
    format: str | None = None
    strategy: str = "auto"
    lams: tuple[float, ...] = field(init=False, repr=False)

    def __post_init__(self):
        object.__setattr__(self, "lams", tuple(member_lambdas(self)))
        option_number("--lambda-border", self.lambda_border)
        if self.name and (os.sep in self.name or (os.altsep and os.altsep in self.name)):
            raise ParameterError(f"--name must be a plain file name prefix, got {self.name!r}")
        self.check_run_settings()


def add_parser(sub) -> None:
    """The grammar of ``family``."""
    p = sub.add_parser(
        "family", help="a family of shapes, one mesh per λ, from one shared solve (figure 1)",
        description="Run the flow for a range of λ (--from, --from + --step, ... up to --to, included when it "
                    "lies on that grid) and write "
                    "one mesh per λ into OUTDIR.  With one iteration all members share a single "
                    "multi-shift CG solve (about the cost of the largest |λ| alone); otherwise each λ "
                    "is solved on one shared operator.  Flow options as for 'shapeflow flow'.",
        epilog="Figure 1 of the paper: shapeflow family IN OUTDIR --from 0 --to -240 --step -5 "
               "(49 members, λ = 0, -5, ..., -240).")
    add_flow_options(p)
    _retitle(p, "output", metavar="OUTDIR",
             help="directory for the members (created if missing); files NAME_INDEX_lamVALUE.EXT")
    _retitle(p, "force", help="overwrite member files that already exist in OUTDIR")
    _retitle(p, "image", help="also draw a strip of up to 12 members (first and last included), blue to red "
                              "by λ (needs shapeflow[render])")
    g = p.add_argument_group("the λ of the members")
    g.add_argument("--from", dest="lam_from", type=float, default=None, metavar="A",
                   help="first λ (default 0 with --to/--step)")
    g.add_argument("--to", dest="lam_to", type=float, default=None, metavar="B",
                   help="end of the range, included when it lies on the grid A + k·S")
    g.add_argument("--step", dest="lam_step", type=float, default=None, metavar="S",
                   help="increment, non-zero, pointing from A to B (e.g. -5)")
    g.add_argument("--lambdas", default=None, metavar="L1,L2,...",
                   help="explicit comma-separated list of λ instead of --from/--to/--step")
    p.add_argument("--name", default=None, help="file name prefix (default: the input's name)")
    p.add_argument("--format", choices=FORMATS, default=None,
                   help="output format (default: the input's, else ply)")
    p.add_argument("--strategy", choices=["auto", "multishift", "separate"], default="auto",
                   help="auto: shared solve where the shift structure holds (default); multishift: "
                        "insist on it; separate: one solve per λ")
    p.set_defaults(options=FamilyOptions)


#: the shared solve of a one-iteration family, said without the solver's notation (the report keeps it)
SHARED_SOLVE = ("a single flow step: the members' systems are one matrix plus 1/|λ| on its diagonal, with one "
                "right-hand side, so one solve serves them all")


def in_words(report, *, alone: bool = True) -> str:
    """A family report's summary for the command line: the shared solve said in words (the report's
    ``reason`` keeps the notation ``(σI + M) Y = b``), without the member count the line already
    says when ``alone`` (one batch)."""
    text = report.summary()
    if report.path == "multishift":
        text = text.replace(f"({report.reason})", f"({SHARED_SOLVE})")
    return text.removeprefix(f"{len(report.lams)} members: ") if alone else text


def _retitle(parser, dest: str, **kw) -> None:
    """Change the help (or metavar) of an option that ``add_flow_options`` defined."""
    for action in parser._actions:
        if action.dest == dest:
            for key, value in kw.items():
                setattr(action, key, value)
            return


def _number(name: str, text: str) -> float:
    """A finite number written on the command line."""
    try:
        v = float(text)
    except ValueError:
        raise ParameterError(f"{name}: {text!r} is not a number") from None
    return params.number(name, v)


def member_lambdas(o) -> list[float]:
    """The members' λ from ``o.lambdas`` or ``o.lam_from``/``o.lam_to``/``o.lam_step`` (``--lambdas`` or
    ``--from/--to/--step``): A, A + S, ... up to B, B included when it lies on the grid (within a
    billionth of a step: 0 to -240 step -5 gives 49 members)."""
    ranged = any(x is not None for x in (o.lam_from, o.lam_to, o.lam_step))
    if o.lambdas is not None:
        if ranged:
            raise ParameterError("give either --lambdas or --from/--to/--step, not both")
        parts = [s.strip() for s in o.lambdas.split(",")]
        if not any(parts):
            raise ParameterError("--lambdas is empty")
        lams = [_number("--lambdas", s) for s in parts if s]
    else:
        if o.lam_to is None or o.lam_step is None:
            raise ParameterError("give the λ of the members: --to and --step (with --from, default 0), "
                                 "or --lambdas")
        a = 0.0 if o.lam_from is None else _number("--from", str(o.lam_from))
        b = _number("--to", str(o.lam_to))
        s = _number("--step", str(o.lam_step))
        if s == 0.0:
            raise ParameterError("--step must not be 0")
        steps = (b - a) / s
        if steps < -1e-9:
            raise ParameterError(f"--from {a:g} --to {b:g} --step {s:g} gives no λ "
                                 "(the step must point from --from towards --to)")
        count = math.floor(steps + 1e-9) + 1 if math.isfinite(steps) else math.inf
        if count > MAX_MEMBERS:
            raise ParameterError(f"--from/--to/--step give {count} members; at most {MAX_MEMBERS}")
        lams = [a + i * s for i in range(count)]
        lams = [float(f"{x:.12g}") for x in lams]          # 0.1 + 2*0.1 -> 0.3, not 0.30000000000000004
    if len(lams) > MAX_MEMBERS:
        raise ParameterError(f"{len(lams)} members; at most {MAX_MEMBERS}")
    return [0.0 if x == 0 else x for x in lams]            # no "-0"


def _decimals(lams) -> int:
    for d in range(1, 7):
        if all(abs(round(x, d) - x) <= 1e-9 * max(1.0, abs(x)) for x in lams):
            return d
    return 6


def member_names(stem: str, lams, ext: str) -> list[str]:
    """``STEM_INDEX_lam±VALUE.EXT`` with fixed widths (a plain sort gives the family order)."""
    d = _decimals(lams)
    width_i = len(str(len(lams) - 1))
    int_digits = max(3, len(str(int(max(abs(x) for x in lams)))))
    width_v = 1 + int_digits + 1 + d                         # sign, digits, point, decimals
    return [f"{stem}_{i:0{width_i}d}_lam{x:+0{width_v}.{d}f}.{ext}" for i, x in enumerate(lams)]


def _output_format(o: FamilyOptions, source: str) -> str:
    if o.format:
        return o.format
    if not source.startswith("example:"):
        ext = Path(source).suffix.lower().lstrip(".")
        if ext in FORMATS:
            return ext
    return "ply"


def _stem(o: FamilyOptions, source: str) -> str:
    if o.name:
        return o.name
    if source.startswith("example:"):
        return source.split(":", 1)[1] or "example"
    return Path(source).stem


def _member_paths(o: FamilyOptions, source: str, outdir: Path) -> tuple[list[str], list[Path]]:
    """The members' file names and paths, checked before any work: OUTDIR is a folder or can be
    made, and no member file exists unless ``--force``."""
    if outdir.exists() and not outdir.is_dir():
        raise ParameterError(f"OUTDIR {str(outdir)!r} exists and is not a directory")
    names = member_names(_stem(o, source), o.lams, _output_format(o, source))
    paths = [outdir / nm for nm in names]
    if not o.force:
        exist = [p for p in paths if p.exists()]
        if exist:
            raise ParameterError(f"{len(exist)} member file(s) already exist in {str(outdir)!r} "
                                 f"(first: {exist[0].name}); pass --force to overwrite them")
    parent = outdir.resolve().parent
    if not outdir.exists() and not parent.is_dir():
        raise ParameterError(f"OUTDIR {str(outdir)!r}: its folder {str(parent)!r} does not exist")
    return names, paths


def run(o: FamilyOptions, source: str, target: str, report: Reporter) -> None:
    """Write the family of ``source`` into the folder ``target`` (and the strip ``o.image``)."""
    from ..flow.family import family
    from ..geometry import refresh_normals
    from ..io import output_target

    t0 = time.perf_counter()
    lams = list(o.lams)
    if o.image:
        from .images import check_picture_path

        check_picture_path(o.image)  # a bad picture path fails before any work
    # members drawn in the --image strip: at most 12, evenly spaced, first and last included
    panels = sorted(set(np.linspace(0, len(lams) - 1, min(12, len(lams))).round().astype(int).tolist()))
    kept = {}
    outdir = Path(target)
    names, paths = _member_paths(o, source, outdir)
    mesh = load_mesh(source, report)
    with option_names(OPTION_NAMES):
        operand, kw, restore = welded_for_operator(mesh, o.flow_kwargs(mesh, source, "family", report), "family",
                                                   o.quiet, report)
    outdir.mkdir(exist_ok=True)
    for p in (paths[0], o.image):   # every output writable before any work (the folder exists now)
        if p:
            output_target(p, force=o.force)
    # batches bound the memory of the positions held at once (one batch for any usual family)
    per_member = 2 * 24 * max(1, mesh.n_vertices)
    batch = max(1, BATCH_BYTES // per_member)
    order = sorted(range(len(lams)), key=lambda i: abs(lams[i]))
    batches = [order[i:i + batch] for i in range(0, len(order), batch)]
    reports = []
    # one bar over both phases: every member is counted once solved and once written
    with progress(report, 2 * len(lams), "family (solve+write)", o.quiet) as cb:
        done = 0
        for idx in batches:
            def solved(d, total, _base=done):
                if cb is not None:
                    cb(_base + d, 2 * len(lams))

            with option_names(OPTION_NAMES):
                shapes, rep = family(operand, [lams[i] for i in idx], strategy=o.strategy,
                                     progress=solved, return_report=True, **kw)
            reports.append(rep)
            done += len(idx)
            for i, V in zip(idx, shapes):
                save_mesh(str(paths[i]), restore(refresh_normals(operand.with_vertices(V))), o.force, report)
                if o.image and i in panels:
                    kept[i] = V
                done += 1
                if cb is not None:
                    cb(done, 2 * len(lams))
    report.fact("reports", reports)
    if o.image:
        from .images import family_image

        family_image(o.image, [operand.with_vertices(kept[i]) for i in panels], [lams[i] for i in panels],
                     up=o.image_up, quiet=o.quiet, report=report)
    if not o.quiet:
        summary = "; ".join(in_words(r, alone=len(reports) == 1) for r in reports)
        report.message(f"shapeflow family: {len(lams)} members, λ {lams[0]:g} .. {lams[-1]:g}, "
                       f"{mesh.n_vertices} vertices: {summary}; total {time.perf_counter() - t0:.3f} s "
                       f"-> {outdir}{os.sep}{names[0]} .. {names[-1]}")
