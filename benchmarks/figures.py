"""The measured figures of README.md and docs/performance.md, and where a benchmark prints each.

:data:`FIGURES` lists every figure that a ``benchmarks/`` invocation prints: the doc and a piece of
the text of its line (``anchor``; the line number is looked up when a summary is written, so the
list survives edits of the docs), the figure as the doc gives it (``says``), and the lines of the
output that give it (:class:`Pick`: a step of ``benchmarks/measure_all.py`` and a regular
expression, optionally inside a block of the output).  :data:`UNMEASURED` lists the figures of
those docs that no benchmark prints, and why, so that a re-dating of the docs knows which figures
a run of ``measure_all.py`` cannot renew.  A few figures of docs/method.md, docs/studio.md and
docs/io.md are listed too (the benchmarks that print them run in the same pass).
"""

from __future__ import annotations

from dataclasses import dataclass

README, PERF = "README.md", "docs/performance.md"


@dataclass(frozen=True)
class Pick:
    """Output lines of ``step`` matching the regular expression ``match`` (and the ``after`` lines
    after each), searched in the block that starts at the first line matching ``section`` and ends
    at the next empty line (the whole output without a ``section``)."""

    step: str
    match: str
    section: str = ""
    after: int = 0


@dataclass(frozen=True)
class Figure:
    doc: str
    anchor: str
    says: str
    picks: tuple[Pick, ...]
    note: str = ""


@dataclass(frozen=True)
class Unmeasured:
    doc: str
    anchor: str
    why: str


# output lines used by several figures
FLOW_HEAD = Pick("flow", r"^Suzanne subdivided 4x")             # which Suzanne (Blender's subsurf or ours)
FLOW_FRESH = Pick("flow", r"fresh mesh \(all included\)")
FLOW_WARM = Pick("flow", r"1 iteration, warm topology")
FLOW_TEN = Pick("flow", r"10 iterations \(fixed operator\)")
FLOW_1M = Pick("flow", r"^1M-vertex case")
BLENDER_SMOOTH = Pick("flow-blender", r"Laplacian Smooth, λ=1")
BLENDER_COMPAT = Pick("flow-blender", r"compat='blender' agrees")
TORUS_SUB = Pick("subdivision", r"subdivide\(levels=2\)\s+\d", section=r"^quad torus")
TORUS_SV = Pick("subdivision", r"S @ V", section=r"^quad torus")
TORUS_BLENDER = Pick("subdivision-blender", r"Blender Subdivision Surface", section=r"^quad torus")
FAMILY = (Pick("family", r"before:|family, fresh mesh|family, warm topology|x flow\(\), warm|after:"),)
FAMILY_BLENDER = Pick("family-blender", r"x Blender Laplacian Smooth", after=1)
RATIO = (Pick("family-ratio", r"before:|after:"), Pick("family-ratio", r"^  kernels (auto|force)", after=1))
RATIO_126K = (Pick("family-ratio-126k", r"before:|after:"),
              Pick("family-ratio-126k", r"^  kernels (auto|force)", after=1))
BRUSH_TABLE = Pick("brush", r".", section=r"^median wall ms per dab")
BRUSH_SIZES = Pick("brush-sizes", r"suzanne x|large / small|load average")
ADDON = (Pick("addon", r"^Blender \d|load average"), Pick("addon", r"^shapeflow_flow|Laplacian Smooth modifier"))
PEERS = tuple(Pick(step, r".", section=r"^\| method \| time") for step in ("peers", "peers-1-thread"))
PEERS_HEAD = tuple(Pick(step, r"^shapeflow .* triangles") for step in ("peers", "peers-1-thread"))
PEERS_WARM = tuple(Pick(step, r".", section=r"^\| warm, in rounds") for step in ("peers", "peers-1-thread"))
CONTENTION = Pick("contention", r"^\| (fresh flow|brush dab)")
SCAN = {n: (Pick(f"scan-{n}", r"^scan "), Pick(f"scan-{n}", r"peak resident memory")) for n in ("2M", "20M", "50M")}

FIGURES: tuple[Figure, ...] = (
    # ------------------------------------------------------------------ README.md
    Figure(README, "On the 126K-vertex Suzanne the operator takes 0.3 s",
           "operator 0.3 s; Blender's Laplacian Smooth modifier 8.6 s", ADDON),
    Figure(README, "| flow λ=1, Suzanne ×4 (126,290 vertices, quads), fresh |",
           "72–73 ms; Blender's Laplacian Smooth 8.7–9.9 s, 80–108×",
           (FLOW_HEAD, FLOW_FRESH, BLENDER_SMOOTH),
           "the ratio: Blender's time (flow-blender) over the fresh time (flow), both of this run"),
    Figure(README, "| the same, 10 iterations |", "1.80–1.81× one iteration", (FLOW_TEN,)),
    Figure(README, "| flow on 937,730 vertices |", "0.89 s, 1.16 GB peak", (FLOW_1M,)),
    Figure(README, "| a 50M-vertex triangle scan (binary PLY)", "20 s + 43 s + 11 s, 20.1 GB peak", SCAN["50M"]),
    Figure(README, "| family of 48 shapes, 46,850 vertices |",
           "0.58 s; Suzanne ×3 1.7× default kernels, compiled 2.8× (one thread), 2.1× (default threads); "
           "Suzanne ×4 1.8× default threads, 2.6–2.7× one thread; 48 × flow() 14.2 s; 48 × Blender ≈ 123 s",
           (*FAMILY, *RATIO, *RATIO_126K, FAMILY_BLENDER)),
    Figure(README, "| Catmull–Clark level 2, 40K → 640K vertices |", "369 ms; Blender's Subdivision Surface 242 ms",
           (TORUS_SUB, TORUS_BLENDER)),
    Figure(README, "| brush dab with 2,600 vertices inside (11K–187K-vertex meshes) |",
           "2.6–4.7 ms; Suzanne 8K / 126K, interleaved: 3.18 / 3.12 ms", (BRUSH_TABLE, BRUSH_SIZES)),
    Figure(README, "| enhance Suzanne ×4 inside Blender (the extension) |", "0.30–0.34 s; Blender's modifier 8.6 s",
           ADDON),
    Figure(README, "| trimesh Taubin filter, 10 iterations (explicit) |",
           "one thread 198 vs trimesh 226 ms; default threads 99 vs 135 ms", (*PEERS_HEAD, *PEERS)),
    Figure(README, "| method | default threads | one thread | ratio to shapeflow (one thread) |",
           "the table: default threads (peers), one thread and ratios (peers-1-thread); warm 40 / 45 ms, "
           "trimesh in those rounds 66 / 83 ms", (*PEERS_HEAD, *PEERS, *PEERS_WARM)),
    # ------------------------------------------------------------------ docs/performance.md
    Figure(PERF, "| flow λ=1, 1 iteration, Suzanne ×4 (126,290 vertices, quads) — `bench_flow.py` |",
           "89–109 ms fresh (four runs of 11), 63–81 warm; 2026-11-24: 72–73 fresh, 46 warm; Blender 8.7–9.9 s: "
           "80–108× fresh, 113–152× warm", (FLOW_HEAD, FLOW_FRESH, FLOW_WARM, BLENDER_SMOOTH)),
    Figure(PERF, "| same, compiled kernels off (switched off in the process", "262–323 ms fresh, 161–198 ms warm",
           (Pick("flow", r"without compiled kernels: λ=1"),),
           "bench_flow.py switches the kernels off inside its process (accel.enabled(False))"),
    Figure(PERF, "| flow λ=1, 10 iterations, fixed operator — `bench_flow.py` |",
           "110–139 ms, 1.71–1.84× one iteration; 2.6× without kernels",
           (FLOW_TEN, Pick("flow", r"without compiled kernels: 10 iterations"))),
    Figure(PERF, "| flow λ=−100, 1 iteration: CG / cholespy / SuperLU — `bench_flow.py` |",
           "2026-11-24: 187–190 (53 iterations) / 1,190 / 895 ms",
           (Pick("flow", r"flow λ=-100, 1 iteration"), Pick("flow", r"solver=\w+\s+λ=-100"))),
    Figure(PERF, "| flow λ=1, 937,730 vertices (camel, Catmull–Clark ×3) — `bench_flow.py` |",
           "0.89 s, 1.16 GB, 7 CG iterations (2026-11-24)", (FLOW_1M,)),
    Figure(PERF, "| `compat=\"blender\"` against Blender, Suzanne ×4 |", "5.8e-8 × the diagonal", (BLENDER_COMPAT,)),
    Figure(PERF, "| topology derivation, 937,730 vertices — `bench_operators.py` |", "547 ms",
           (Pick("operators", r"topology derivation"),)),
    Figure(PERF, "| W (tqlbo), 937,730 vertices, fresh / warm — `bench_operators.py` |", "1,358 / 619 ms",
           (Pick("operators", r"W, scheme=tqlbo"),)),
    Figure(PERF, "| load amo_large_tri.obj (90K vertices) / its binary PLY — `bench_io.py` |",
           "312 ms / ~30 ms; meshio 780 ms, plyfile 620 ms",
           (Pick("io", r"^\| file \||^\| amo_large_tri\.obj|^\| amo\.ply"),),
           "plyfile is not among bench_io.py's readers: its 620 ms is not re-measured"),
    Figure(PERF, "| Catmull–Clark level 2, 40,000 → 640,000 vertices — `bench_subdivision.py` |",
           "369 ms; one S @ V frame 20 ms; Blender 242 ms", (TORUS_SUB, TORUS_SV, TORUS_BLENDER)),
    Figure(PERF, "| family of 48 shapes (λ = 0, −5, …, −235: figure 1's range without its last member), 46,850",
           "575 ms fresh, 535 ms warm; 48 × flow() 14.2 s (26.5× warm); 48 × Blender ≈ 123 s (from 4)",
           (*FAMILY, FAMILY_BLENDER)),
    Figure(PERF, "| family of 48 shapes (λ = 0 … −235) against one `flow()` at λ = −235",
           "×3 forced: 200 / 72.5 ms 2.77× (one thread), 154 / 73 ms 2.09× (default threads); auto: 339 / 208 ms "
           "1.66×, 342 / 210 ms 1.66×; ×4: 1.77–1.78× (default threads), 2.58–2.73× (one thread); member vs "
           "flow() 2.0e-10 (1.8e-10 on NumPy, 8.1e-11 on ×4)",
           (*RATIO, *RATIO_126K)),
    Figure(PERF, "| brush dab with 2,600 vertices inside, meshes of 11K–187K vertices — `bench_brush.py` |",
           "2.64–4.73 ms over three runs (p90 ≤ 5.3); 800: 0.98–1.63; 1,800: 2.03–2.94; --sizes 3.18 / 3.12 ms "
           "(CPU 2.88 / 2.85)", (Pick("brush", r"load average"), Pick("brush", r"^\s+(800|1800|2600) inside"),
                                 BRUSH_TABLE, BRUSH_SIZES)),
    Figure(PERF, "| render offscreen — `bench_render.py` |", "1.2 s (1.4 s with edges)",
           (Pick("render", r"faces\s+(plain|edges)"),),
           "the figures match the AMO mesh (1.08M triangles); the grid has exactly 1M quads"),
    Figure(PERF, "| Blender add-on, enhance Suzanne ×4 inside Blender — `bench_blender_addon.py` |",
           "0.30–0.34 s (re-run 0.15 s); Blender's modifier 8.6 s", ADDON),
    Figure(PERF, "ms idle (default against one thread",
           "90.8 / 89.6 ms idle; two busy processes 125 / 131 ms", (CONTENTION,)),
    Figure(PERF, "interleaved rounds, load 1.0, default threads) the family with its check takes 1.36×",
           "1.36× forced, 1.19× NumPy/SciPy (per-round medians); 15 rounds, load 1.0",
           (Pick("family-check-cost", r"before:|after:|^  kernels"),)),
    Figure(PERF, "do not. In the run of the table above",
           "69 iterations of 3 products against 95; 2.77× / 2.09× compiled on ×3 (one / default threads), "
           "2.73× / 1.78× on ×4 (2.58× / 1.77× as by default)",
           (*RATIO, *RATIO_126K)),
    Figure(PERF, "| dab, wall (p10–p90) |", "3.18 (2.57–7.60) / 3.12 (2.58–10.19) ms, 0.98",
           (BRUSH_SIZES,)),
    Figure(PERF, "| dab, CPU time |", "2.88 / 2.85 ms, 0.99", (BRUSH_SIZES,)),
    Figure(PERF, "| query / rim and degrees / commit with the cache update |",
           "0.05 / 0.09 / 0.36 ms; 0.11 / 0.20 / 0.60 ms (query / classify / commit)", (BRUSH_SIZES,)),
    Figure(PERF, "ms: a 2,600-vertex ball on the 126K mesh is a flat disc", "linear solve 1.50 / 2.06 ms",
           (BRUSH_SIZES,)),
    Figure(PERF, "| method | default | `--threads 1` |",
           "the columns 'default, last' and '--threads 1, last' (the other columns are earlier versions)",
           (*PEERS_HEAD, *PEERS, *PEERS_WARM)),
    Figure(PERF, "`python benchmarks/bench_peers.py --reps 9` (Suzanne 126K triangulated",
           "one thread 198 vs 226 ms (0.88); default threads 99 vs 135 ms (0.73); load 10.9–11.0",
           (*PEERS_HEAD, *PEERS)),
    Figure(PERF, "| fresh flow, λ=1, Suzanne 126K | idle |", "the table with the Gauss–Seidel CG",
           (CONTENTION,)),
    Figure(PERF, "| idle | 0.", "idle 0.280 / 0.262 / 0.156 / 0.159 s; busy 0.231 / 0.231 / "
           "0.137 / 0.143 s", (Pick("addon-busy", r"^Blender|^state|^idle|^busy"),)),
    Figure(PERF, "| 2,000,000 | 4,000,000 |", "1.1 + 1.9 + 0.5 s, 1.2 GB, 522 / 610 bytes a vertex", SCAN["2M"]),
    Figure(PERF, "| 19,996,488 | 39,992,976 |", "7.0 + 19.0 + 5.2 s, 8.2 GB, 338 / 426 bytes a vertex", SCAN["20M"]),
    Figure(PERF, "| 50,000,000 | 100,000,000 |", "20.1 + 43.1 + 11.3 s, 20.1 GB, 331 / 419 bytes a vertex",
           SCAN["50M"]),
    Figure(PERF, "| sequential loop, one process |", "3.73 / 2.41 / 2.86 s; overhead 5.7 / 11.0 / 10.5 ms",
           (Pick("batch", r".", section=r"^\d+ files"),)),
    Figure(PERF, "Starting the local cluster costs", "1.0 s", (Pick("batch", r"start-up, once"),)),
    # ------------------------------------------------------------------ the same pass, other docs
    Figure("docs/method.md", "(Mesh built from arrays:",
           "30°: 1.05–1.10× fresh (97.6 vs 105.0 ms), 1.16–1.18× warm; 5°: 1.23× fresh",
           (Pick("features", r".", section=r"^Suzanne"), Pick("features", r".", section=r"^  warm plain"))),
    Figure("docs/method.md", "level 2, 5,000 creased edges, 3,800 of them semi-sharp",
           "0.91–1.15× the plain subdivision",
           (Pick("features", r".", section=r"^subdivision \(medians"),)),
    Figure("docs/studio.md", "| a dab, pointer event to the end of the frame drawn with its answer, frames on demand",
           "the Responsiveness table (two runs of 118 dabs)", (Pick("studio", r"."),)),
    Figure("docs/io.md", "Measured 2026-11-26 in one run of `benchmarks/measure_all.py`",
           "the load-time table", (Pick("io", r"."),)),
)

_PROFILE = "measured once by hand (a profile or timers), no script in benchmarks/"
_GONE = "a variant or an earlier version no longer in the code"
UNMEASURED: tuple[Unmeasured, ...] = (
    Unmeasured(README, "all 81 reference cases agree to 1.9e-6",
               "an accuracy check against shared/fixtures/blender (tests/blender), not a benchmark"),
    Unmeasured(README, "| the paper (2012): ~500 ms |", "the paper's figure"),
    Unmeasured(PERF, "At 126K vertices (warm): cotangent assembly ~11 ms", _PROFILE),
    Unmeasured(PERF, "points switch NumPy's hint off while they run", _PROFILE + " (small pages on and off)"),
    Unmeasured(PERF, "126K matrix in ~1.3 s and CHOLMOD in ~0.7 s",
               _PROFILE + "; bench_flow.py's 'solver=cholesky λ=1' row is the nearest"),
    Unmeasured(PERF, "uniform grid, ~0.07 ms per 2,600-vertex query", _PROFILE),
    Unmeasured(PERF, "process pays ~0.6 s once to load the cached compiled code",
               _PROFILE + "; bench_flow.py's 1M case prints its process's first call"),
    Unmeasured(PERF, "| Suzanne 126K triangulated, λ = 0.1 | 6 (error 5.6e-9)",
               "the Jacobi / Gauss–Seidel iteration table: " + _PROFILE),
    Unmeasured(PERF, "The CG of a fresh step on Suzanne 126K triangulated takes 24 ms",
               _PROFILE + "; the 0.83–0.85 of the previous version: " + _GONE),
    Unmeasured(PERF, "Measured: at λ = 300 CG 0.39 s", _PROFILE),
    Unmeasured(PERF, "27.3 against 24.2 ms for the same 7 iterations", _GONE),
    Unmeasured(PERF, "(rank 15–16 of", _PROFILE + " (also the BLAS-thread times 0.2 / 0.4–0.8 s)"),
    Unmeasured(PERF, "| polynomial preconditioner of degree 1", "the table of options not adopted: " + _GONE),
    Unmeasured(PERF, "systems, 0.65–0.88× the one-band solve",
               "36 captured dab systems: " + _PROFILE + "; bench_brush.py --solvers times the solvers per dab size"),
    Unmeasured(PERF, "padded to 65 (a band-63 system", _PROFILE),
    Unmeasured(PERF, "a brush on Suzanne ×2 (7,958 vertices) holds 5.8 MB", "array sizes, computed"),
    Unmeasured(PERF, "| the same, previous version (", _GONE),
    Unmeasured(PERF, "The previous version's dab medians in its run, 8.8 and", _GONE),
    Unmeasured(PERF, "the gathers stay in cache (2.1 → 1.6 ms per", _PROFILE),
    Unmeasured(PERF, "| `--threads 1`, before | `--threads 1`, first |", "the peers table's earlier columns: " + _GONE),
    Unmeasured(PERF, "the same, in the same run: on one thread", "earlier runs of bench_peers.py"),
    Unmeasured(PERF, "the step 71.7 → 68.1 ms, trimesh 78.8 ms", _GONE),
    Unmeasured(PERF, "| stage | previous | now | inside the stage (now) |", _PROFILE + "; 'previous': " + _GONE),
    Unmeasured(PERF, "| stage | before | after | how |", _GONE),
    Unmeasured(PERF, "Where the ~62–65 ms of a fresh step go now", _PROFILE + "; the variants not adopted: " + _GONE),
    Unmeasured(PERF, "same call took 117–127 ms instead of 92–95 ms", _PROFILE),
    Unmeasured(PERF, "normalised λ = 1e4 2.0 s and λ = 1e5 1.4 s", _PROFILE + " (also AMG and the orderings)"),
    Unmeasured(PERF, "| fresh flow, λ=1, Suzanne 126K | idle | 93.3 ms |", "the Jacobi-CG contention table: " + _GONE),
    Unmeasured(PERF, "the same machine gave 229–268 ms against 111–131 ms", _GONE),
    Unmeasured(PERF, "So a triangle scan of N vertices needs about **420 × N bytes**",
               "derived from the scan table (and the 2.6 s search for coincident vertices: " + _PROFILE + ")"),
    Unmeasured(PERF, "ms a file against a Pool's", "derived from the batch table"),
)
