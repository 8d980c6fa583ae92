"""Re-measure every figure of README.md and docs/performance.md in one run, into one dated folder.

    python benchmarks/measure_all.py                 # the whole set (~25 min on the 2-core reference machine)
    python benchmarks/measure_all.py --dry-run       # the plan: steps, commands, estimated durations
    python benchmarks/measure_all.py --only flow,brush
    python benchmarks/measure_all.py --quick --only brush-sizes,contention   # a smoke test of this driver

Runs the benchmark invocations that print the docs' figures (``figures.py``) one after the other,
each in a process of its own (never two at once: the machine has 2 shared cores), and writes
``benchmarks/results/<date>-all/`` (``<date>-quick/`` with ``--quick``; ``-2``, ``-3`` ... when it
exists): ``logs/<step>.log`` with each invocation's full output (stdout and stderr), and
``summary.md`` / ``summary.json``: for every invocation its command, start and end, duration, load
average before and after, memory available and exit code; for every doc figure the doc's line, the
figure as the doc gives it and the output lines that give it now; and the figures no benchmark
prints.  The summary is rewritten after every step, so an interrupted run keeps what it measured.

Steps that need Blender run under a Python with ``bpy`` (``--blender-python``, else
``$SHAPEFLOW_BPY_PYTHON``, this Python if it imports bpy, or ``bpyvenv/`` beside the checkout); the
others under this Python; all with ``PYTHONPATH=<checkout>/src``, so the checkout's code is
measured, except the add-on's, which run the extension built from it (its bundled copy).  The
first step fills numba's on-disk cache, so no timed call compiles; the Blender steps come early,
since the first caches Blender's Suzanne ×4 (``benchmarks/.cache``) for the flow and add-on steps.
Meshes come from ``--shared`` (else ``$SHAPEFLOW_SHARED``, else ``shared/`` beside the checkout).
A step whose needs are missing (bpy, Chromium, free memory for the big scans) is skipped and the
summary says why.  ``--quick`` runs each step with few repeats: only to test this driver, never
for the docs.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

from figures import FIGURES, UNMEASURED, Pick  # noqa: E402


@dataclass(frozen=True)
class Step:
    """One invocation.  ``args``: a script in benchmarks/ (or ``-m module``) and its options;
    ``quick``: the options of the smoke version (None: not run with --quick); ``seconds``: its
    measured duration per run at ``args`` on the reference machine (2026-11-26, load average 1–3);
    ``fewer``: how it falls short of the protocol the docs' figures came from."""

    name: str
    args: tuple[str, ...]
    quick: tuple[str, ...] | None
    seconds: float
    quick_seconds: float
    python: str = "venv"              # "venv": this Python; "bpy": the Python with Blender's bpy
    runs: int = 1
    needs: tuple[str, ...] = ()       # "bpy", "chromium", "zip" (the extension built by blender-zip)
    mem_gb: float = 0.0               # memory that must be available when the step starts
    src_path: bool = True             # PYTHONPATH=<checkout>/src (off: the extension's bundled copy runs)
    fewer: str = ""
    what: str = ""


STEPS: tuple[Step, ...] = (
    Step("warm-up", ("measure_all.py", "--_warm-up"), ("measure_all.py", "--_warm-up"), 15, 15,
         what="numba's on-disk cache filled (compiled kernels forced), so no timed call compiles"),
    Step("flow-blender", ("bench_flow.py", "--blender-only"), ("bench_flow.py", "--blender-only"), 17, 17,
         python="bpy", runs=2, needs=("bpy",), what="Blender's Laplacian Smooth on Suzanne ×4; caches Blender's "
         "Suzanne ×4 (benchmarks/.cache) for flow and the add-on", fewer="the docs' 8.7–9.9 s range does not say "
         "how many runs it spans: two here, each a median of 3"),
    Step("flow", ("bench_flow.py", "--repeat", "11"), ("bench_flow.py", "--quick", "--repeat", "2"), 55, 12, runs=4,
         what="the flow rows, solvers, kernels off, the 937,730-vertex case"),
    Step("scan-2M", ("bench_flow.py", "--scan", "2M"), ("bench_flow.py", "--scan", "200K"), 6, 3, mem_gb=2),
    Step("scan-20M", ("bench_flow.py", "--scan", "20M"), None, 54, 0, mem_gb=10),
    Step("scan-50M", ("bench_flow.py", "--scan", "50M"), None, 110, 0, mem_gb=21,
         what="duration estimated from the docs' 20 + 43 + 11 s and the generation time of the 2M scan"),
    Step("operators", ("bench_operators.py",), ("bench_operators.py", "--repeat", "1"), 13, 8),
    Step("io", ("bench_io.py", "--shared", "{shared}/meshes"),
         ("bench_io.py", "--shared", "{shared}/meshes", "--reps", "1", "--no-big"), 175, 6,
         what="also docs/io.md's table (7 rounds, 5 for the large files)"),
    Step("subdivision", ("bench_subdivision.py", "--no-blender"),
         ("bench_subdivision.py", "--no-blender", "--repeat", "1", "--size", "60"), 15, 4),
    Step("subdivision-blender", ("bench_subdivision.py", "--blender-only"),
         ("bench_subdivision.py", "--blender-only", "--repeat", "1", "--size", "60"), 5, 4,
         python="bpy", needs=("bpy",)),
    Step("family", ("bench_family.py", "--no-blender"), ("bench_family.py", "--quick", "--repeat", "1"), 75, 8),
    Step("family-blender", ("bench_family.py", "--blender-only"),
         ("bench_family.py", "--blender-only", "--blender-samples", "1"), 12, 8, python="bpy", needs=("bpy",)),
    Step("family-ratio", ("bench_family.py", "--ratio", "--rounds", "15"),
         ("bench_family.py", "--ratio", "--rounds", "1"), 44, 9),
    Step("family-ratio-126k", ("bench_family.py", "--ratio", "--rounds", "5", "--suzanne-levels", "4"), None, 70, 0,
         what="the same ratio on Suzanne ×4 (126,290 vertices), where the default kernels are the compiled ones"),
    Step("family-check-cost", ("bench_family.py", "--check-cost", "--rounds", "15"),
         ("bench_family.py", "--check-cost", "--rounds", "1"), 25, 4),
    Step("brush", ("bench_brush.py",), ("bench_brush.py", "--quick"), 20, 8, runs=3),
    Step("brush-sizes", ("bench_brush.py", "--sizes"), ("bench_brush.py", "--sizes", "--quick"), 4, 3),
    Step("render", ("bench_render.py", "--repeat", "3"), ("bench_render.py", "--repeat", "1"), 28, 12),
    Step("peers", ("bench_peers.py", "--reps", "9"), ("bench_peers.py", "--reps", "1"), 28, 7),
    Step("peers-1-thread", ("bench_peers.py", "--reps", "9", "--threads", "1"),
         ("bench_peers.py", "--reps", "1", "--threads", "1"), 28, 7, runs=3,
         what="three runs, as performance.md's one-thread comparison with trimesh"),
    Step("contention", ("bench_contention.py", "--reps", "7"), ("bench_contention.py", "--reps", "1"), 14, 6),
    Step("batch", ("bench_batch.py",), ("bench_batch.py", "--files", "8", "--reps", "1"), 38, 12),
    Step("blender-zip", ("-m", "shapeflow.blender", "build", "--output", "{tmp}", "--platform", "linux-x64"),
         ("-m", "shapeflow.blender", "build", "--output", "{tmp}", "--platform", "linux-x64"), 4, 4,
         needs=("bpy",), what="the extension zip for the add-on steps (not a figure)"),
    Step("addon", ("bench_blender_addon.py", "--zip", "{zip}", "--repeat", "3"),
         ("bench_blender_addon.py", "--zip", "{zip}", "--repeat", "1", "--skip-modifier"), 23, 12,
         python="bpy", runs=2, needs=("bpy", "zip"), src_path=False, fewer="the docs' 0.30–0.34 s range does not "
         "say how many runs it spans: two here, each a median of 3"),
    Step("addon-busy", ("bench_blender_addon.py", "--zip", "{zip}", "--busy", "--repeat", "5"),
         ("bench_blender_addon.py", "--zip", "{zip}", "--busy", "--repeat", "1"), 79, 40,
         python="bpy", needs=("bpy", "zip"), src_path=False),
    Step("features", ("bench_features.py", "--rounds", "21"), ("bench_features.py", "--rounds", "1"), 35, 10,
         what="docs/method.md's sharp-feature costs"),
    Step("studio", ("bench_studio.py",), ("bench_studio.py", "--dabs", "5", "--rounds", "1"), 120, 40, runs=2,
         needs=("chromium",), what="docs/studio.md's responsiveness table (two runs, as there)"),
)
BY_NAME = {s.name: s for s in STEPS}
ENV_NOTED = re.compile(r"^(SHAPEFLOW_|NUMBA_|OMP_|OPENBLAS_|MKL_|MALLOC_)")


def mem_available_gb() -> float:
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) / 2**20
    except OSError:
        pass
    return float("nan")


def loadavg() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]


def find_blender_python(given: str | None) -> str | None:
    import importlib.util

    if given:
        return given
    if os.environ.get("SHAPEFLOW_BPY_PYTHON"):
        return os.environ["SHAPEFLOW_BPY_PYTHON"]
    if importlib.util.find_spec("bpy") is not None:
        return sys.executable
    beside = ROOT.parent / "bpyvenv" / "bin" / "python"
    return str(beside) if beside.exists() else None


def missing(step: Step, ctx: dict, at_run: bool = False) -> str:
    """Why ``step`` cannot run here ('' when it can)."""
    if "bpy" in step.needs and not ctx["bpy"]:
        return "no Python with bpy (--blender-python or $SHAPEFLOW_BPY_PYTHON)"
    if "chromium" in step.needs and not (shutil.which("chromium") and shutil.which("chromedriver")):
        return "needs chromium and chromedriver"
    if "zip" in step.needs and at_run and not ctx.get("zip"):
        return "no extension zip (blender-zip failed or did not run)"
    free = mem_available_gb()
    if step.mem_gb and free < step.mem_gb:
        return f"needs {step.mem_gb:g} GB of available memory, {free:.1f} GB {'now' if at_run else 'at planning'}"
    return ""


def command(step: Step, ctx: dict, quick: bool) -> list[str]:
    args = step.quick if quick else step.args
    py = (ctx["bpy"] or "<python with bpy>") if step.python == "bpy" else sys.executable
    out = [py, *args] if args[0] == "-m" else [py, str(HERE / args[0]), *args[1:]]
    for key, value in (("{shared}", ctx["shared"]), ("{zip}", ctx.get("zip", "")), ("{tmp}", ctx["tmp"])):
        out = [a.replace(key, str(value)) for a in out]
    return out


def child_env(step: Step, ctx: dict) -> dict:
    env = dict(os.environ, SHAPEFLOW_SHARED=str(ctx["shared"]), PYTHONUNBUFFERED="1")
    if step.src_path:
        env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src")] + [p for p in [env.get("PYTHONPATH")] if p])
    else:
        env.pop("PYTHONPATH", None)
    return env


def fmt_s(s: float) -> str:
    return f"{s:.0f} s" if s < 120 else f"{s / 60:.1f} min"


def plan(steps: list[Step], ctx: dict, quick: bool) -> float:
    """Print the plan; return the estimated seconds of the steps that will run."""
    total = 0.0
    print(f"{'step':20s} {'python':6s} {'runs':>4s} {'estimate':>9s}  command")
    for s in steps:
        why = missing(s, ctx)
        runs = 1 if quick else s.runs
        est = (s.quick_seconds if quick else s.seconds) * runs
        if quick and s.quick is None:
            why = "not part of --quick"
        if not why:
            total += est
        cmd = " ".join(Path(a).name if i < 2 and "/" in a else a for i, a in enumerate(command(s, ctx, quick)))
        print(f"{s.name:20s} {s.python:6s} {runs:4d} {fmt_s(est) if not why else 'skipped':>9s}  "
              f"{cmd if not why else why}")
        if s.what:
            print(f"{'':44s}({s.what})")
    print(f"\nestimated total: {fmt_s(total)} (durations measured 2026-11-26 on the 2-core reference machine at "
          f"load average 1–3; a busier machine takes longer)")
    if not quick:
        fewer = [s for s in steps if s.fewer]
        print("runs and rounds as in the docs' originals (four runs of bench_flow.py, three of bench_brush.py, "
              "the docs' --reps/--rounds/--repeat)" + (", except:" if fewer else ""))
        for s in fewer:
            print(f"  {s.name}: {s.fewer}")
    return total


def run_step(step: Step, run: int, ctx: dict, logs: Path, quick: bool) -> dict:
    cmd = command(step, ctx, quick)
    name = step.name if (1 if quick else step.runs) == 1 else f"{step.name}-{run}"
    log = logs / f"{name}.log"
    rec = dict(step=step.name, run=run, command=cmd, log=str(log.relative_to(logs.parent)),
               python=step.python, src_path=step.src_path)
    why = missing(step, ctx, at_run=True)
    if why:
        rec.update(exit=None, skipped=why)
        return rec
    rec.update(start=time.strftime("%Y-%m-%d %H:%M:%S"), load_before=loadavg(),
               mem_available_gb_before=round(mem_available_gb(), 1))
    timeout = max(300.0, 5 * step.seconds)
    t0 = time.perf_counter()
    with open(log, "w") as f:
        f.write(f"## {' '.join(cmd)}\n## started {rec['start']}, load average {rec['load_before']}\n")
        f.flush()
        proc = subprocess.Popen(cmd, cwd=ROOT, env=child_env(step, ctx), stdout=f, stderr=subprocess.STDOUT,
                                start_new_session=True)
        try:
            code = proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            code = proc.wait()
            rec["timeout"] = f"killed after {timeout:.0f} s"
        except KeyboardInterrupt:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
            code = "interrupted"
        rec.update(end=time.strftime("%Y-%m-%d %H:%M:%S"), seconds=round(time.perf_counter() - t0, 1),
                   load_after=loadavg(), exit=code)
        f.write(f"## exit {code}, {rec['seconds']} s, load average {rec['load_after']}\n")
    return rec


def output_lines(lines: list[str], pick: Pick) -> set[int]:
    """Indices of the lines of an output that ``pick`` selects."""
    start, end = 0, len(lines)
    if pick.section:
        start = next((i for i, x in enumerate(lines) if re.search(pick.section, x)), end)
        end = next((j for j in range(start + 1, end) if not lines[j].strip()), end)
    rx = re.compile(pick.match)
    return {j for i in range(start, end) if rx.search(lines[i]) for j in range(i, min(end, i + 1 + pick.after))}


def doc_line(doc: str, anchor: str) -> int | None:
    try:
        text = (ROOT / doc).read_text().splitlines()
    except OSError:
        return None
    return next((i + 1 for i, x in enumerate(text) if anchor in x), None)


def figure_lines(records: list[dict], out: Path) -> list[dict]:
    runs = {r["step"]: r["run"] for r in records}             # the last run of each step
    rows = []
    for fig in FIGURES:
        got = []
        steps = list(dict.fromkeys(p.step for p in fig.picks))
        for rec in (r for s in steps for r in records if r["step"] == s and r.get("exit") is not None):
            text = (out / rec["log"]).read_text(errors="replace").splitlines()
            lines = [x for x in text if not x.startswith("## ")]        # the log's own header and footer
            chosen = set().union(*(output_lines(lines, p) for p in fig.picks if p.step == rec["step"]))
            tag = rec["step"] + (f" {rec['run']}" if runs[rec["step"]] > 1 else "")
            got += [dict(step=tag, text=lines[i]) for i in sorted(chosen)]
        problems = {}
        for r in records:
            if r["step"] in steps and r.get("exit") != 0:
                problems[r["step"]] = (f"skipped: {r['skipped']}" if r.get("skipped")
                                       else r.get("timeout") or f"exit {r['exit']}")
        rows.append(dict(doc=fig.doc, line=doc_line(fig.doc, fig.anchor), anchor=fig.anchor, says=fig.says,
                         note=fig.note, steps=steps, problems=problems,
                         not_run=[s for s in steps if s not in runs], lines=got))
    return rows


def write_summary(out: Path, meta: dict, records: list[dict]) -> None:
    figs = figure_lines(records, out)
    unmeasured = [dict(doc=u.doc, line=doc_line(u.doc, u.anchor), anchor=u.anchor, why=u.why) for u in UNMEASURED]
    (out / "summary.json").write_text(json.dumps(dict(meta=meta, steps=records, figures=figs,
                                                      unmeasured=unmeasured), indent=1, ensure_ascii=False) + "\n")
    md = [f"# Benchmarks of {meta['date']}{' (--quick: not for the docs)' if meta['quick'] else ''}", "",
          f"`{' '.join(meta['argv'])}`; commit {meta['commit']}; {meta['cores']} cores, "
          f"{meta['mem_total_gb']} GB; started {meta['started']}" + (f", finished {meta['finished']} "
                                                                       f"({fmt_s(meta['seconds'])})"
                                                                       if meta.get("finished") else " (running)"),
          "", "Interpreters: " + "; ".join(f"{k}: {v}" for k, v in meta["interpreters"].items()),
          "", "Environment: " + (", ".join(f"{k}={v}" for k, v in meta["env"].items()) or "none of note"), "",
          "## Invocations", "", "| step | command | start | end | seconds | load average before → after | exit | log |",
          "|---|---|---|---|---|---|---|---|"]
    for r in records:
        cmd = " ".join(Path(a).name if "/" in a and i < 2 else a for i, a in enumerate(r["command"]))
        ex = r.get("skipped") and f"skipped: {r['skipped']}" or r.get("timeout") or r.get("exit")
        load = " → ".join(" ".join(map(str, r[k])) for k in ("load_before", "load_after") if k in r)
        name = r["step"] + ("" if r["run"] == 1 else f" {r['run']}")
        md.append(f"| {name} | `{cmd}` | {r.get('start', '')} | {r.get('end', '')} | {r.get('seconds', '')} | "
                  f"{load} | {ex} | [{Path(r['log']).name}]({r['log']}) |")
    md += ["", "## Figures of the docs and the output lines that give them", ""]
    for f in figs:
        if len(f["not_run"]) == len(f["steps"]):
            continue
        where = f"{f['doc']}:{f['line']}" if f["line"] else f"{f['doc']} (anchor not found: the doc changed)"
        md += [f"### {where}", "", f"> {f['anchor']}", "", f"the doc: {f['says']}" + (f" — {f['note']}" if f["note"]
                                                                                   else "")]
        for s, why in f["problems"].items():
            md.append(f"\n**{s}: {why}**")
        if f["not_run"]:
            md.append(f"\nnot run in this pass: {', '.join(f['not_run'])}")
        if f["lines"]:
            width = max(len(x["step"]) for x in f["lines"])
            md += ["", "```text"] + [f"[{x['step']:{width}s}] {x['text']}" for x in f["lines"]] + ["```"]
        md.append("")
    idle = [f"{f['doc']}:{f['line']} ({', '.join(f['steps'])})" for f in figs if len(f["not_run"]) == len(f["steps"])]
    if idle:
        md += ["## Figures whose steps did not run in this pass", "", ", ".join(idle), ""]
    md += ["## Figures no benchmark prints (not renewed by this run)", "",
           "| doc line | text on the line | why |", "|---|---|---|"]
    md += [f"| {u['doc']}:{u['line']} | {u['anchor'].replace('|', '∣')} | {u['why']} |" for u in unmeasured]
    (out / "summary.md").write_text("\n".join(md) + "\n")


def versions(py: str, src_path: bool) -> str:
    code = ("import sys, importlib.metadata as m\nv=[]\nfor p in ('numpy','scipy','numba','bpy'):\n try: "
            "v.append(p+' '+m.version(p))\n except Exception: pass\nprint('Python '+sys.version.split()[0]+', '+"
            "', '.join(v))")
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src")) if src_path else os.environ
    r = subprocess.run([py, "-c", code], capture_output=True, text=True, env=env)
    return r.stdout.strip() or r.stderr.strip()[-200:]


def git(*args: str) -> str:
    r = subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, text=True)
    return r.stdout.strip()


def out_dir(given: str | None, quick: bool) -> Path:
    if given:
        return Path(given)
    base = HERE / "results" / f"{time.strftime('%Y-%m-%d')}-{'quick' if quick else 'all'}"
    out, k = base, 1
    while out.exists():
        k += 1
        out = base.with_name(f"{base.name}-{k}")
    return out


def warm_up() -> int:
    """Fill numba's on-disk cache: the main compiled paths once, kernels forced, on a small mesh."""
    import numpy as np

    import shapeflow as sf
    from shapeflow import accel

    mesh = sf.subdivide(sf.load_example("spot"), 1)
    t0 = time.perf_counter()
    with accel.use(kernels="force"):
        sf.flow(mesh, 1.0)
        sf.flow(mesh, -100.0)
        sf.flow(mesh, 1.0, iterations=10)
        sf.flow(mesh, 1.0, feature_angle=30.0)
        sf.family(mesh, np.arange(0.0, -50.0, -5.0))
        brush = sf.Brush(mesh, lam=-50.0, radius=0.1 * mesh.diagonal)
        brush.dab(mesh.vertices[0])
        brush.undo()
        sf.subdivide(mesh, 1)
    print(f"compiled kernels {'on' if accel.available() else 'not installed'}; "
          f"warm-up {time.perf_counter() - t0:.1f} s")
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--only", help="comma-separated step names (see --dry-run); warm-up always joins, "
                                   "blender-zip joins the add-on steps")
    ap.add_argument("--dry-run", action="store_true", help="print the plan with each step's estimated duration")
    ap.add_argument("--quick", action="store_true", help="few repeats: a smoke test of this driver, not for the docs")
    ap.add_argument("--shared", help="the shared folder (meshes/, fixtures/); default $SHAPEFLOW_SHARED or "
                                     "shared/ beside the checkout")
    ap.add_argument("--blender-python", help="a Python with Blender's bpy (3.11, bpy 5.0.1)")
    ap.add_argument("--out", help="the results folder (default benchmarks/results/<date>-all)")
    ap.add_argument("--_warm-up", dest="warm_up", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.warm_up:
        return warm_up()
    steps = list(STEPS)
    if a.only:
        names = [n.strip() for n in a.only.split(",") if n.strip()]
        unknown = [n for n in names if n not in BY_NAME]
        if unknown:
            ap.error(f"unknown step {', '.join(unknown)}; steps: {', '.join(BY_NAME)}")
        names.append("warm-up")                       # no timed call of a subset compiles either
        if any("zip" in BY_NAME[n].needs for n in names):
            names.append("blender-zip")
        steps = [s for s in STEPS if s.name in names]
    shared = Path(a.shared or os.environ.get("SHAPEFLOW_SHARED") or ROOT.parent / "shared").resolve()
    if not (shared / "meshes").is_dir():
        ap.error(f"{shared} has no meshes/ folder: give --shared DIR (or set SHAPEFLOW_SHARED)")
    ctx = dict(shared=shared, bpy=find_blender_python(a.blender_python), tmp=Path("<tmp>"))
    if a.dry_run:
        ctx["zip"] = "<zip>"
        print(f"shared: {shared}; Python with bpy: {ctx['bpy'] or 'none'}; memory available "
              f"{mem_available_gb():.1f} GB; load average {' '.join(map(str, loadavg()))}\n")
        plan(steps, ctx, a.quick)
        lost = [f"{f.doc}: {f.anchor}" for f in FIGURES if doc_line(f.doc, f.anchor) is None]
        lost += [f"{u.doc}: {u.anchor}" for u in UNMEASURED if doc_line(u.doc, u.anchor) is None]
        print(f"\n{len(FIGURES)} doc figures from these steps, {len(UNMEASURED)} that no benchmark prints")
        if lost:
            print("anchors not found in the docs (figures.py needs updating):\n  " + "\n  ".join(lost))
        return 0

    out = out_dir(a.out, a.quick)
    (out / "logs").mkdir(parents=True, exist_ok=True)
    ctx["tmp"] = Path(tempfile.mkdtemp(prefix="shapeflow-measure-"))
    status = git("status", "--porcelain")
    meta = dict(date=time.strftime("%Y-%m-%d"), argv=["python", "benchmarks/measure_all.py", *(argv or sys.argv[1:])],
                quick=a.quick, started=time.strftime("%Y-%m-%d %H:%M:%S"), cores=os.cpu_count(),
                mem_total_gb=round(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30, 1),
                commit=git("rev-parse", "--short", "HEAD") + (f" + {len(status.splitlines())} uncommitted changes"
                                                             if status else ""),
                shared=str(shared), env={k: v for k, v in os.environ.items() if ENV_NOTED.match(k)},
                interpreters={"venv": versions(sys.executable, True)})
    if ctx["bpy"]:
        meta["interpreters"]["bpy"] = f"{ctx['bpy']}: " + versions(ctx["bpy"], False)
    print(f"results: {out}")
    plan(steps, dict(ctx, zip="<zip>"), a.quick)
    print(flush=True)
    records: list[dict] = []
    t0 = time.perf_counter()
    try:
        for step in steps:
            for run in range(1, (1 if a.quick else step.runs) + 1):
                if a.quick and step.quick is None or meta.get("interrupted"):
                    continue
                of = f" {run}/{step.runs}" if step.runs > 1 and not a.quick else ""
                print(f"[{time.strftime('%H:%M:%S')}] {step.name}{of} ...", end=" ", flush=True)
                rec = run_step(step, run, ctx, out / "logs", a.quick)
                records.append(rec)
                if rec.get("skipped"):
                    print(f"skipped: {rec['skipped']}", flush=True)
                else:
                    print(f"exit {rec['exit']}, {rec['seconds']} s {rec.get('timeout', '')}", flush=True)
                meta["interrupted"] = rec.get("exit") == "interrupted"
                if step.name == "blender-zip" and rec.get("exit") == 0:
                    lines = (out / rec["log"]).read_text().splitlines()
                    ctx["zip"] = next((x.strip() for x in reversed(lines) if x.strip().endswith(".zip")), None)
                write_summary(out, meta, records)
    except KeyboardInterrupt:      # between two steps
        meta["interrupted"] = True
    finally:
        shutil.rmtree(ctx["tmp"], ignore_errors=True)
    meta.update(finished=time.strftime("%Y-%m-%d %H:%M:%S"), seconds=round(time.perf_counter() - t0, 1))
    write_summary(out, meta, records)
    failed = [r["step"] for r in records if r.get("exit") not in (0, None, "interrupted")]
    print(f"{out / 'summary.md'}: {len(records)} invocations in {fmt_s(meta['seconds'])}"
          + (f"; failed: {', '.join(failed)}" if failed else "") + ("; interrupted" if meta.get("interrupted") else ""))
    return 1 if failed or meta.get("interrupted") else 0


if __name__ == "__main__":
    sys.exit(main())
