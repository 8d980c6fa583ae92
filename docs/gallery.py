"""Regenerate every picture under ``docs/img/``: the paper's figures on real meshes.

    python docs/gallery.py [FIGURE ...] [--shared DIR] [--out DIR]

FIGURE is any of ``fig1 fig5 … fig14`` (default: all); needs the render extra.  The meshes come
from the repository's ``tests/data/meshes`` and the examples bundled with the package, so a fresh
clone makes every figure but two: fig8's camel, whose licence keeps it out of the repository, is
read from ``--shared DIR`` (a folder holding ``meshes/camel_tri.obj``; or ``$SHAPEFLOW_SHARED``, or
``shared/`` in or beside the repository), and fig14 needs Blender as a Python module for its
reference (``--blender-python PYTHON``, a Python with ``bpy==5.0.1``, or
``$SHAPEFLOW_BLENDER_PYTHON``).  A figure whose inputs are missing is skipped, naming them.  Each
picture is a 256-colour dithered PNG (about 20–130 KB); the script prints the numbers the captions
quote.  fig1 and fig5–fig12 are the paper's figures ("Shape Enhanced With an Adapted Laplacian
Operator For Hybrid Quad/Triangle Meshes"), fig13 (sharp features on a nut built here) and fig14
(creased subdivision against Blender's) shapeflow's own; each ``figureN_*`` function says what it
draws, and docs/gallery.md shows them with their captions.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import shapeflow as sf
from shapeflow.rendering import render_meshes

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
MAX_BYTES = 150_000


class Unavailable(RuntimeError):
    """A figure that cannot be made here (a module or a mesh is missing)."""


#: the Python with Blender's bpy that fig14 runs its reference in (set by main)
BLENDER_PYTHON: list = []
#: where meshes are looked for: the repository's test meshes, the bundled examples, then --shared
REPOSITORY_MESHES = ROOT / "tests" / "data" / "meshes"
BUNDLED_MESHES = Path(sf.__file__).resolve().parent / "data"


def shared_dir(arg: str | None) -> Path | None:
    """The folder holding ``meshes/``: ``--shared``, ``$SHAPEFLOW_SHARED``, ``shared/`` in or beside the repository."""
    for cand in (arg, os.environ.get("SHAPEFLOW_SHARED"), ROOT / "shared", ROOT.parent / "shared"):
        if cand and (Path(cand) / "meshes").is_dir():
            return Path(cand)
    if arg:
        raise SystemExit(f"--shared {arg}: no meshes/ folder there")
    return None


def save_small(path: Path, img: np.ndarray) -> int:
    """Save as a 256-colour PNG with Floyd–Steinberg dithering (no visible banding); return its size."""
    from PIL import Image

    im = Image.fromarray(img).convert("RGB")
    palette = im.quantize(colors=256, method=Image.Quantize.MEDIANCUT)
    im.quantize(palette=palette, dither=Image.Dither.FLOYDSTEINBERG).save(path, optimize=True)
    size = path.stat().st_size
    if size > MAX_BYTES:
        print(f"  warning: {path.name} is {size / 1e3:.0f} KB (> {MAX_BYTES / 1e3:.0f} KB)")
    return size


def load(meshes: list[Path], name: str) -> sf.Mesh:
    """``NAME.obj`` from the first of ``meshes`` (folders) that has it."""
    for folder in meshes:
        if (folder / f"{name}.obj").is_file():
            return sf.load(folder / f"{name}.obj")
    raise Unavailable(f"{name}.obj is neither in tests/data/meshes nor bundled: pass --shared DIR (a folder "
                      f"holding meshes/{name}.obj)")


def side_by_side(*images: np.ndarray) -> np.ndarray:
    """Pictures next to each other, top-aligned on white (panels with colour bars of their own)."""
    h = max(im.shape[0] for im in images)
    return np.hstack([np.vstack([im, np.full((h - im.shape[0], im.shape[1], 3), 255, np.uint8)]) for im in images])


def moved_range(mesh: sf.Mesh, reference: sf.Mesh, q: float = 98.0) -> tuple[float, float]:
    """± the ``q``-th percentile of how far the vertices that moved moved (the untouched would collapse it)."""
    d = np.linalg.norm(mesh.vertices - reference.vertices, axis=1)
    top = float(np.percentile(d[d > 1e-9 * reference.diagonal], q))
    return -top, top


def height_weights(v: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Weights from a coordinate: 0 at ``lo``, 1 at ``hi``, a linear ramp between (either order)."""
    return np.clip((v - lo) / (hi - lo), 0.0, 1.0)


# --------------------------------------------------------------------------
# figures

def figure1_family(meshes: list[Path], out: Path) -> str:
    """FIGURE 1: a family of shapes, λ = 0 … −240 in steps of −5, from one
    multi-shift solve, coloured blue (λ=0) → red (λ=−240); an evenly spaced
    subset of the members is drawn in a strip."""
    from shapeflow.commands.images import family_image
    from shapeflow.flow import family_meshes

    spot = load(meshes, "spot_quad")
    lams = [-5.0 * i for i in range(49)]                      # 0 … −240
    members = family_meshes(spot, lams)
    path = out / "fig1_family.png"
    family_image(str(path), members, lams, view=(-140, 20), max_panels=12, quiet=True)
    from PIL import Image

    with Image.open(path) as im:
        kb = save_small(path, np.asarray(im.convert("RGB"))) / 1e3
    return f"{path.name} ({kb:.0f} KB): {len(lams)} members, λ = 0 … −240 (12 drawn)"


def figure5_cage(meshes: list[Path], out: Path) -> str:
    """Weights painted on Spot's hybrid cage (triangles, quads, pentagons: head = 1), carried
    through 3 Catmull–Clark levels (smooth weight rule), then weighted enhancement at three λ,
    coloured by how far each result moved along the subdivided surface's normals, over one range
    (the middle result's), so the strongest saturates and the weakest stays pale."""
    cage = load(meshes, "spot_control_hybrid")
    y = cage.vertices[:, 1]
    w = (y >= y.min() + 0.65 * np.ptp(y)).astype(float)     # the top 35 % of the height: the head
    cage = cage.with_weights(w)
    fine = sf.subdivide(cage, 3, weights_rule="smooth")
    lams = (-30.0, -150.0, -600.0)
    res = [sf.flow(fine, lam, weights="weight") for lam in lams]
    size, view = (260, 290), (-140, 20)
    weights = render_meshes([cage, fine], None, labels=["cage + weights", "Catmull-Clark ×3"], color="weights",
                            edges=[True, False], shading=["flat", "smooth"], view=view, size=size)
    moved = render_meshes(res, None, labels=[f"weighted λ={lam:g}" for lam in lams], color="displacement",
                          reference=fine, clim=moved_range(res[1], fine), view=view, size=size)
    path = out / "fig5_cage_subdivision_weights.png"
    kb = save_small(path, side_by_side(weights, moved)) / 1e3
    c = cage.face_count_by_size()
    far = ", ".join(f"{np.linalg.norm(r.vertices - fine.vertices, axis=1).max() / fine.diagonal:.3f}" for r in res)
    return (f"{path.name} ({kb:.0f} KB): cage {cage.n_vertices} vertices ({c.get(3, 0)} tri, {c.get(4, 0)} quad, "
            f"{c.get(5, 0)} pentagons), {int(w.sum())} weighted; Catmull-Clark ×3: {fine.n_vertices} vertices; "
            f"max move {far} (× diagonal)")


def figure6_smooth_enhance(meshes: list[Path], out: Path) -> str:
    """The open rook cage (triangles + quads, open base): Catmull–Clark ×2, smoothing
    λ=60, λ_b=12, then enhancement λ=−200, λ_b=12. The last two are coloured by how far
    each step moved the surface along its normal (blue inwards, red outwards)."""
    cage = load(meshes, "rook_cage_hybrid_open")
    cc = sf.subdivide(cage, 2)
    smooth = sf.flow(cc, 60.0, lam_border=12.0)
    enh = sf.flow(smooth, -200.0, lam_border=12.0)
    img = render_meshes(
        [cage, cc, smooth, enh], None,
        labels=["cage", "Catmull-Clark ×2", "smoothed: λ=60, λb=12", "enhanced: λ=-200, λb=12"],
        color=["none", "none", "displacement", "displacement"], reference=[None, None, cc, smooth],
        edges=[True, False, False, False], shading=["flat", "smooth", "smooth", "smooth"],
        view=(30, 20), up="z", size=(300, 330))
    path = out / "fig6_smooth_then_enhance.png"
    kb = save_small(path, img) / 1e3
    d1 = np.linalg.norm(smooth.vertices - cc.vertices, axis=1).max() / cc.diagonal
    d2 = np.linalg.norm(enh.vertices - smooth.vertices, axis=1).max() / cc.diagonal
    return (f"{path.name} ({kb:.0f} KB): {cc.n_vertices} vertices; max move smooth {d1:.3f}, "
            f"enhance {d2:.3f} (× diagonal)")


def half_triangulated(quads: sf.Mesh, seed: int = 7) -> sf.Mesh:
    """Split a random half of the quads into two triangles, along a random diagonal."""
    rng = np.random.default_rng(seed)
    F = quads.face_indices.reshape(-1, 4)
    split = rng.random(len(F)) < 0.5
    diag = rng.random(len(F)) < 0.5
    a, b = split & diag, split & ~diag
    tris = np.concatenate([F[a][:, [0, 1, 2]], F[a][:, [0, 2, 3]], F[b][:, [0, 1, 3]], F[b][:, [1, 2, 3]]])
    keep = F[~split]
    sizes = np.r_[np.full(len(keep), 4), np.full(len(tris), 3)]
    return sf.Mesh.from_csr(quads.vertices, sizes, np.r_[keep.ravel(), tris.ravel()])


def figure7_tri_quad_mixed(meshes: list[Path], out: Path) -> str:
    """λ=7, 2 iterations on spot_tri, spot_quad and a randomly half-triangulated spot_quad
    (the same vertices): the results look alike. Top: inputs with their edges; bottom:
    results coloured by their displacement along the input normals."""
    quad = load(meshes, "spot_quad")
    tri = load(meshes, "spot_tri")
    if tri.n_vertices != quad.n_vertices or not np.array_equal(tri.vertices, quad.vertices):
        raise Unavailable("spot_tri and spot_quad no longer share their vertices")
    mixed = half_triangulated(quad)
    inputs = [tri, quad, mixed]
    res = [sf.flow(m, 7.0, iterations=2) for m in inputs]
    names = ["triangles", "quads", "mixed"]
    c = mixed.face_count_by_size()
    img = render_meshes(
        inputs + res, None, grid=(2, 3),
        labels=[f"triangles ({tri.n_faces})", f"quads ({quad.n_faces})", f"mixed ({c[3]} tri + {c[4]} quad)"]
        + [f"λ=7, 2 iterations: {n}" for n in names],
        color=["none"] * 3 + ["displacement"] * 3, reference=quad, edges=[True] * 3 + [False] * 3,
        view=(-140, 20), size=(300, 300))
    path = out / "fig7_tri_quad_mixed.png"
    kb = save_small(path, img) / 1e3
    moved = max(np.linalg.norm(r.vertices - quad.vertices, axis=1).max() for r in res)
    gap = max(np.linalg.norm(res[i].vertices - res[j].vertices, axis=1).max() for i, j in ((0, 1), (0, 2), (1, 2)))
    return (f"{path.name} ({kb:.0f} KB): max displacement {moved / quad.diagonal:.4f}, max difference between the "
            f"three results {gap / quad.diagonal:.4f} (× diagonal)")


def figure8_camel(meshes: list[Path], out: Path) -> str:
    """Camel: λ = −30, −100, −400 (top row); weights from height thresholds and weighted
    enhancement of the legs (λ=−50, 2 iterations) and of the head and neck (λ=−500), the two
    results coloured by how far they moved along the camel's normals."""
    camel = load(meshes, "camel_tri")
    V = camel.vertices
    lams = (-30.0, -100.0, -400.0)
    top = [sf.flow(camel, lam) for lam in lams]
    legs_w = height_weights(V[:, 1], -0.10, -0.18)                     # y: legs below the belly
    head_w = height_weights(V[:, 1], 0.02, 0.12) * height_weights(V[:, 2], 0.10, 0.20)  # high and in front
    legs_m, head_m = camel.with_weights(legs_w), camel.with_weights(head_w)
    legs = sf.flow(legs_m, -50.0, iterations=2, weights="weight")
    head = sf.flow(head_m, -500.0, weights="weight")
    size, view = (290, 290), (60, 12)
    row1 = render_meshes([camel, *top], None, labels=["camel", *(f"λ={lam:g}" for lam in lams)], color="none",
                         view=view, size=size)
    weights = render_meshes([legs_m, head_m], None, labels=["weights: legs", "weights: head and neck"],
                            color="weights", view=view, size=size)
    moved = render_meshes([legs, head], None, labels=["legs: λ=-50, 2 iterations", "head and neck: λ=-500"],
                          color="displacement", reference=camel, view=view, size=size)
    path = out / "fig8_camel.png"
    kb = save_small(path, np.vstack([row1, side_by_side(weights, moved)])) / 1e3
    far = [np.linalg.norm(m.vertices - V, axis=1).max() / camel.diagonal for m in (legs, head)]
    return (f"{path.name} ({kb:.0f} KB): {camel.n_vertices} vertices; weighted vertices: legs "
            f"{int((legs_w > 0).sum())}, head and neck {int((head_w > 0).sum())}; max move legs {far[0]:.3f}, "
            f"head and neck {far[1]:.3f} (× diagonal)")


def figure9_brushes(meshes: list[Path], out: Path) -> str:
    """FIGURE 9: one stroke along Spot's back and rump with the shape-enhancement brush (section 4.3,
    λ=−30 per dab) and with an inflate brush (each dab moves along the vertex normals), seen from the
    front Spot faces (−z, the bundled example's); colours show how far each vertex moved along its
    normal, each brush over its own range.  The enhancement brush exaggerates the shape that is there
    (the rump and the shoulders rise, the dip between them deepens); inflating swells everything
    under the stroke alike."""
    from shapeflow.examples import FRONT

    spot = load(meshes, "spot_quad").with_metadata(front=FRONT["spot"])
    V = spot.vertices
    # a stroke along the back to the rump (the head lies towards −z): the highest vertex of each slice
    slices = [np.flatnonzero(np.abs(V[:, 2] - z) < 0.04) for z in np.linspace(0.3, 0.95, 8)]
    stroke = np.array([V[sl[np.argmax(V[sl, 1])]] for sl in slices])
    radius = 0.2
    enh = sf.Brush(spot, lam=-30.0, radius=radius, falloff="smooth")
    enh.stroke(stroke)
    inf = sf.InflateBrush(spot, strength=0.06, radius=radius, falloff="smooth")
    inf.stroke(stroke)
    size, view = (320, 300), (50, 35)
    panels = [render_meshes([spot], None, labels=["Spot"], color="none", view=view, size=size)]
    for brush, label in ((enh, "enhancement brush, λ=-30"), (inf, "inflate brush")):
        panels.append(render_meshes([brush.mesh], None, labels=[label], color="displacement", reference=spot,
                                    clim=moved_range(brush.mesh, spot), view=view, size=size))
    path = out / "fig9_brushes.png"
    kb = save_small(path, side_by_side(*panels)) / 1e3
    moved = [np.linalg.norm(b.mesh.vertices - V, axis=1) for b in (enh, inf)]
    return (f"{path.name} ({kb:.0f} KB): {len(stroke)} stroke points, radius {radius:g}; max move enhance "
            f"{moved[0].max():.4f}, inflate {moved[1].max():.4f} (diagonal {spot.diagonal:.3f})")


def figure10_brush_speed(meshes: list[Path], out: Path) -> str:
    """FIGURE 10: sculpted vertices per second by dab size and model size, plotted from the output of
    ``python benchmarks/bench_brush.py --json benchmarks/results/brush.json`` (medians of 100 dabs per
    case), with the paper's 2012 figures (800 vertices in 0.1 s, 2,600 in 0.5 s) for scale."""
    import json

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    res = HERE.parent / "benchmarks" / "results" / "brush.json"
    if not res.is_file():
        raise Unavailable(f"{res} is missing: run benchmarks/bench_brush.py --json {res}")
    data = json.loads(res.read_text())
    rows, meta = data["rows"], data["meta"]
    fig = Figure(figsize=(6.4, 3.8), dpi=110)
    ax = fig.add_subplot()
    for name in dict.fromkeys(r["mesh"] for r in rows):
        rs = [r for r in rows if r["mesh"] == name]
        ax.plot([r["inside"] for r in rs], [r["vertices_per_second"] for r in rs], "o-",
                label=name)
    ax.plot([800, 2600], [800 / 0.1, 2600 / 0.5], "k--", label="paper (2012, quad-core)")
    ax.set_yscale("log")
    ax.set_xlabel("vertices inside the brush sphere")
    ax.set_ylabel("sculpted vertices per second")
    ax.set_title(f"enhancement brush, λ = {meta['lam']:g}, median of {meta['timed_dabs']} dabs "
                 f"({meta['date']}, {meta['cores']} cores)", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path = out / "fig10_brush_speed.png"
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    img = np.asarray(canvas.buffer_rgba())[:, :, :3]
    kb = save_small(path, img) / 1e3
    slow = min(r["vertices_per_second"] for r in rows)
    return f"{path.name} ({kb:.0f} KB): {len(rows)} cases; slowest {slow / 1e3:.0f}K vertices/s"


def figure11_normalisation(meshes: list[Path], out: Path) -> str:
    """Spot scaled so that its mean edge length is 1 (×1) and 4 times larger (×4); λ=−50 with the
    normalised operator (eq. 10, the default) and the area-normalised one (eq. 9,
    normalized=False). Each row is framed with one camera, so sizes compare within a row."""
    from shapeflow.geometry import mean_edge_length

    spot = load(meshes, "spot_quad")
    c = spot.vertices.mean(axis=0)
    s = 1.0 / mean_edge_length(spot)
    row = []
    notes = []
    for k in (4.0, 1.0):
        m = spot.with_vertices((spot.vertices - c) * s * k)
        a = sf.flow(m, -50.0)
        b = sf.flow(m, -50.0, normalized=False)
        row += [m, a, b]
        move = [np.linalg.norm(r.vertices - m.vertices, axis=1).max() / m.diagonal for r in (a, b)]
        notes.append(f"×{k:g}: max move normalised {move[0]:.3f}, area-normalised {move[1]:.3f}")
    img = render_meshes(
        row, None, grid=(2, 3), framing="rows",
        labels=["×4", "×4, normalised λ=-50", "×4, area-normalised λ=-50",
                "×1 (mean edge 1)", "×1, normalised λ=-50", "×1, area-normalised λ=-50"],
        color="none", view=(-140, 20), size=(290, 280))
    path = out / "fig11_normalised_vs_area.png"
    kb = save_small(path, img) / 1e3
    return f"{path.name} ({kb:.0f} KB): " + "; ".join(notes) + " (× diagonal)"


def bend(V: np.ndarray, angle_deg: float, pivot=(0.0, 0.3, 0.0), band=(-0.1, 0.1), legs=(-0.3, -0.1)):
    """A simple skeletal bend of Spot's head: vertices in front of the neck (z < band[0]) and above the
    front legs (y > legs[1]) turn rigidly about the x axis through ``pivot``; across the neck and
    shoulder bands the two bones blend linearly (skinning).  Returns the positions and the rotation."""
    a = np.radians(angle_deg)
    R = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(a), -np.sin(a)], [0.0, np.sin(a), np.cos(a)]])
    p = np.asarray(pivot)
    t = (np.clip((band[1] - V[:, 2]) / (band[1] - band[0]), 0.0, 1.0)       # 1 on the head, 0 on the body
         * np.clip((V[:, 1] - legs[0]) / (legs[1] - legs[0]), 0.0, 1.0))[:, None]
    return (1.0 - t) * V + t * ((V - p) @ R.T + p), R


def figure12_poses(meshes: list[Path], out: Path) -> str:
    """FIGURE 12: the same weighted enhancement (λ=−60, weights 1 on the head, ramping to 0 towards the
    neck and throat) on three poses of Spot made by bending the neck (0°, +30°, −30°, linear-blend skinning).
    The operator is intrinsic, and every vertex sharing a face with a weighted one moves rigidly, so
    the enhanced head is the same shape in every pose: its displacement, turned back by the pose's
    rotation, is compared with the rest pose's."""
    spot = load(meshes, "spot_quad")
    V = spot.vertices
    # the head (z < -0.35, y > 0.25) = 1, 0 from z = -0.25 and below y = 0.15 on (clear of the bent bands)
    w = height_weights(V[:, 2], -0.25, -0.35) * height_weights(V[:, 1], 0.15, 0.25)
    posed, enhanced, rots = [], [], []
    for angle in (0.0, 30.0, -30.0):
        P, R = bend(V, angle)
        m = spot.with_vertices(P)
        posed.append(m)
        enhanced.append(sf.flow(m, -60.0, weights=w))
        rots.append(R)
    d0 = enhanced[0].vertices - posed[0].vertices
    head = w > 0
    errs = []
    for m, e, R in zip(posed[1:], enhanced[1:], rots[1:]):
        d = (e.vertices - m.vertices) @ R             # turned back: R^T d, row-wise
        errs.append(float(np.abs(d[head] - d0[head]).max() / np.abs(d0[head]).max()))
    img = render_meshes(
        posed + enhanced, None, grid=(2, 3), framing="each",
        labels=["rest pose", "neck bent +30°", "neck bent -30°",
                "enhanced (head weighted)", "enhanced", "enhanced"],
        color=["none"] * 3 + ["displacement"] * 3, reference=posed + posed, view=(-90, 10), size=(300, 260))
    path = out / "fig12_poses.png"
    kb = save_small(path, img) / 1e3
    return (f"{path.name} ({kb:.0f} KB): {int(head.sum())} weighted vertices; head displacement in the bent "
            f"poses, turned back, differs from the rest pose's by at most {max(errs):.1e} of its size")


# --------------------------------------------------------------------------
# sharp features

def hex_nut(per_side: int = 8, rings: int = 3, layers: int = 4, width: float = 2.0, height: float = 0.9,
            chamfer: float = 0.12, hole: float = 0.55, sink: float = 0.1, triangles=(1, 4)) -> sf.Mesh:
    """A hexagonal nut standing on its face (axis z, a flat side facing −y): flat-to-flat ``width``, a round
    hole of radius ``hole``; the outer rims chamfered by ``chamfer`` and the hole countersunk by ``sink``,
    both at 45°.  Every loop around the axis has 6 × ``per_side`` points; the loops, outside up, over the
    top, down the hole and under the bottom, are joined by bands of quads.  The walls of the sides listed
    in ``triangles`` and the middle ring of each face are cut into triangles: a mix of quads and triangles."""
    n = 6 * per_side
    k = np.arange(n)
    side, t = k // per_side, (k % per_side) / per_side
    a0, a1 = np.radians(60.0 * side), np.radians(60.0 * side + 60.0)     # corners at 0°, 60°, …: flats at 30°, 90°, …
    hexagon = (1 - t)[:, None] * np.c_[np.cos(a0), np.sin(a0)] + t[:, None] * np.c_[np.cos(a1), np.sin(a1)]
    ang = np.arctan2(hexagon[:, 1], hexagon[:, 0])
    circle = np.c_[np.cos(ang), np.sin(ang)]                               # the hole's points at the same angles
    corner = width / np.sqrt(3.0)
    inner = corner - chamfer / np.cos(np.radians(30.0))                     # the chamfered face's hexagon
    h = height / 2
    face = [(1 - i / rings) * inner * hexagon + (i / rings) * (hole + sink) * circle for i in range(rings + 1)]
    loops = ([(corner * hexagon, z) for z in np.linspace(-h + chamfer, h - chamfer, layers + 1)]
             + [(xy, h) for xy in face] + [(hole * circle, z) for z in np.linspace(h - sink, -h + sink, layers + 1)]
             + [(xy, -h) for xy in face[::-1]])
    V = np.vstack([np.c_[xy, np.full(n, z)] for xy, z in loops])
    faces = []
    for lo in range(len(loops)):
        hi = (lo + 1) % len(loops)
        quads = np.c_[lo * n + k, lo * n + (k + 1) % n, hi * n + (k + 1) % n, hi * n + k]
        middle = lo in (layers + 1 + rings // 2, len(loops) - 2 - rings // 2)    # a ring of each face
        cut = np.isin(side, triangles) if lo < layers else np.full(n, middle)
        faces += quads[cut][:, [0, 1, 2]].tolist() + quads[cut][:, [0, 2, 3]].tolist() + quads[~cut].tolist()
    return sf.Mesh(V, faces)


def flat_regions(mesh: sf.Mesh, sharp: np.ndarray) -> list[np.ndarray]:
    """Vertex sets of the regions bounded by sharp edges (faces joined across the other edges) that are flat."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    t = mesh.topology
    two = np.flatnonzero((t.edge_face_count == 2) & ~sharp)
    o = t.edge_corner_offsets[two]
    f0, f1 = t.corner_face[t.edge_corners[o]], t.corner_face[t.edge_corners[o + 1]]
    m = mesh.n_faces
    _, label = connected_components(sp.coo_matrix((np.ones(two.size), (f0, f1)), shape=(m, m)), directed=False)
    corner_label = np.repeat(label, mesh.face_sizes)
    out = []
    for c in np.unique(label):
        ids = np.unique(mesh.face_indices[corner_label == c])
        if flatness(mesh.vertices[ids]) <= 1e-12 * mesh.diagonal:
            out.append(ids)
    return out


def flatness(P: np.ndarray) -> float:
    """Largest distance of the points from their best-fit plane."""
    c = P.mean(axis=0)
    return float(np.abs((P - c) @ np.linalg.svd(P - c)[2][2]).max())


def figure13_hard_surface(meshes: list[Path], out: Path) -> str:
    """A hexagonal nut with a countersunk round hole and chamfered rims (quads and triangles, built here):
    plain enhancement bends its flat faces and straight edges; feature-aware enhancement (edges bent by
    more than 30°, found at the input) keeps them flat and straight while the hole, a round part, still
    enhances.  The input's sharp edges are drawn on all three."""
    from shapeflow.geometry.features import angle_sharp_edges

    nut = hex_nut()
    strength = 10.0                                       # λ = −10
    sharp = angle_sharp_edges(nut, 30.0)
    plain = sf.enhance(nut, strength)
    kept = sf.enhance(nut, strength, feature_angle=30.0)
    regions = flat_regions(nut, sharp)
    diag = nut.diagonal
    worst = [max(flatness(m.vertices[r]) for r in regions) / diag for m in (plain, kept)]
    hole = np.linalg.norm(nut.vertices[:, :2], axis=1) < 0.56
    moved = np.linalg.norm(kept.vertices[hole] - nut.vertices[hole], axis=1).max() / diag
    c = nut.face_count_by_size()
    img = render_meshes(
        [nut, plain, kept], None,
        labels=[f"nut: {c[4]} quads, {c[3]} triangles", f"enhanced (λ={-strength:g})",
                "enhanced, feature_angle=30"],
        color="none", shading="flat", up="z", view=(20, 35), size=(340, 300),
        feature_lines=nut.topology.edges[sharp])
    path = out / "fig13_hard_surface.png"
    kb = save_small(path, img) / 1e3
    return (f"{path.name} ({kb:.0f} KB): {int(sharp.sum())} sharp edges, {len(regions)} flat regions; their "
            f"largest distance from a plane: plain {worst[0]:.3g}, feature-aware {worst[1]:.1e}; the hole moves by "
            f"{moved:.3f} (× diagonal)")


def crease_block() -> tuple[sf.Mesh, np.ndarray, np.ndarray, str]:
    """A 3 × 2 × 1.2 block cage (each side 2 × 2 quads) with Blender edge creases: 1 on the top outline,
    0.5 on the vertical edges, 0.2 on the bottom outline.  Returns the cage, the pairs, their values and a
    caption for them."""
    box = sf.Mesh([[x, y, z] for x in (-1.5, 1.5) for y in (-1.0, 1.0) for z in (0.0, 1.2)],
                  [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]])
    cage = sf.subdivide(box, 1, scheme="simple")
    E = cage.topology.edges
    V = cage.vertices
    end_x, end_y = np.abs(V[:, 0]) == 1.5, np.abs(V[:, 1]) == 1.0          # on the block's sides
    rim = end_x | end_y
    both = lambda mask: mask[E[:, 0]] & mask[E[:, 1]]                     # noqa: E731 - both ends in mask
    top, bottom = both(rim & (V[:, 2] == 1.2)), both(rim & (V[:, 2] == 0.0))
    vertical = both(end_x & end_y)
    pairs = np.vstack([E[top], E[vertical], E[bottom]])
    values = np.concatenate([np.full(top.sum(), 1.0), np.full(vertical.sum(), 0.5), np.full(bottom.sum(), 0.2)])
    return cage, pairs, values, "creases 1, 0.5, 0.2"


def blender_subdivision(cage: sf.Mesh, levels: int, pairs, values) -> tuple[sf.Mesh, str]:
    """Blender's Subdivision Surface with creases on the cage (benchmarks/blender_ref.py, run in BLENDER_PYTHON)."""
    if not BLENDER_PYTHON:
        raise Unavailable("needs Blender's bpy for the reference: --blender-python PYTHON (a Python with bpy 5.0.1)")
    with tempfile.TemporaryDirectory() as tmp:
        src, dst = Path(tmp) / "cage.npz", Path(tmp) / "blender.npz"
        np.savez(src, V=cage.vertices, fs=cage.face_sizes, fi=cage.face_indices, pairs=pairs, values=values)
        code = ("import sys, numpy as np\n"
                f"sys.path.insert(0, {str(ROOT / 'benchmarks')!r})\n"
                "import bpy, blender_ref\n"
                f"d = np.load({str(src)!r})\n"
                f"P, fs, fi, _, _ = blender_ref.subdivision_surface(d['V'], d['fs'], d['fi'], levels={levels}, "
                "creases=(d['pairs'], d['values']))\n"
                f"np.savez({str(dst)!r}, V=P, fs=fs, fi=fi, version=bpy.app.version_string)\n")
        proc = subprocess.run([BLENDER_PYTHON[0], "-c", code], capture_output=True, text=True, timeout=600)
        if proc.returncode != 0:
            last = (proc.stderr.strip().splitlines() or [""])[-1]
            raise Unavailable(f"Blender's run ({BLENDER_PYTHON[0]}) ended with status {proc.returncode}: {last}")
        d = np.load(dst)
        return sf.Mesh.from_csr(d["V"], d["fs"], d["fi"]), str(d["version"])


def figure14_creases(meshes: list[Path], out: Path) -> str:
    """Creased Catmull–Clark subdivision (3 levels) of a block cage: shapeflow's
    ``sf.subdivide(cage, 3, creases=...)`` beside Blender's Subdivision Surface modifier with the same
    creases (``crease_edge``), and the distance from each of shapeflow's points to Blender's."""
    from scipy.spatial import cKDTree

    cage, pairs, values, what = crease_block()
    levels = 3
    ours = sf.subdivide(cage, levels, creases=(pairs, values))
    theirs, version = blender_subdivision(cage, levels, pairs, values)
    dist, j = cKDTree(theirs.vertices).query(ours.vertices)
    if np.unique(j).size != j.size or theirs.n_vertices != ours.n_vertices:
        raise RuntimeError("shapeflow's and Blender's points do not pair up one to one")
    rel = dist / theirs.diagonal
    label = "distance to Blender's point, 1e-8 × diagonal"
    img = render_meshes(
        [cage, ours, theirs, ours.with_attributes(**{label: rel * 1e8})], None,
        labels=[f"cage, {what}", f"shapeflow, {levels} levels", f"Blender {version}", "distance"],
        color=["none", "none", "none", label], clim=(0.0, float(rel.max() * 1e8)), edges=[True, False, False, False],
        shading=["flat", "smooth", "smooth", "smooth"],
        feature_lines=[pairs, None, None, None], up="z", view=(30, 22), size=(290, 260))
    path = out / "fig14_creased_subdivision.png"
    kb = save_small(path, img) / 1e3
    return (f"{path.name} ({kb:.0f} KB): {ours.n_vertices} points; largest distance to Blender {version}'s "
            f"{rel.max():.2g} of the diagonal (median {np.median(rel):.2g})")


FIGURES = {
    "fig1": figure1_family,
    "fig5": figure5_cage,
    "fig6": figure6_smooth_enhance,
    "fig7": figure7_tri_quad_mixed,
    "fig8": figure8_camel,
    "fig9": figure9_brushes,
    "fig10": figure10_brush_speed,
    "fig11": figure11_normalisation,
    "fig12": figure12_poses,
    "fig13": figure13_hard_surface,
    "fig14": figure14_creases,
}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="Regenerate docs/img/ (the pictures of docs/gallery.md and the README).")
    ap.add_argument("figures", nargs="*", metavar="FIGURE",
                    help=f"which figures ({', '.join(FIGURES)}; default all)")
    ap.add_argument("--shared", help="folder holding meshes/ for the meshes the repository does not carry (the "
                                     "camel; default: $SHAPEFLOW_SHARED, or shared/ in or beside the repository)")
    ap.add_argument("--out", default=str(HERE / "img"), help="output folder (default docs/img)")
    ap.add_argument("--blender-python", default=os.environ.get("SHAPEFLOW_BLENDER_PYTHON"), metavar="PYTHON",
                    help="a Python with bpy 5.0.1 for fig14's reference (default: this one, if it has bpy)")
    a = ap.parse_args(argv)
    unknown = [f for f in a.figures if f not in FIGURES]
    if unknown:
        ap.error(f"unknown figure(s) {', '.join(unknown)}; choose from {', '.join(FIGURES)}")
    from shapeflow.rendering import available

    if not available():
        print("rendering is not available: pip install 'shapeflow[render]'", file=sys.stderr)
        return 1
    shared = shared_dir(a.shared)
    meshes = [REPOSITORY_MESHES, BUNDLED_MESHES] + ([shared / "meshes"] if shared is not None else [])
    if a.blender_python:
        BLENDER_PYTHON.append(a.blender_python)
    elif importlib.util.find_spec("bpy") is not None:
        BLENDER_PYTHON.append(sys.executable)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    failed = 0
    for name in a.figures or list(FIGURES):
        t0 = time.perf_counter()
        try:
            msg = FIGURES[name](meshes, out)
        except Unavailable as exc:
            print(f"{name}: skipped: {exc}")
            continue
        except Exception as exc:  # keep going: report every figure
            failed += 1
            print(f"{name}: FAILED: {type(exc).__name__}: {exc}")
            continue
        print(f"{name}: {msg} [{time.perf_counter() - t0:.1f} s]")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
