"""Every flow option of the command line gives exactly what the library gives with the same options."""

from __future__ import annotations

import numpy as np
import pytest

import shapeflow as sf
from shapeflow.cli import main


def _open_mesh():
    from meshgen import grid

    return grid(8, 7, jitter=0.15, seed=2, mix=0.4, z=lambda x, y: 0.2 * np.sin(x) * np.cos(0.7 * y))


CASES = [
    (["--compat", "blender"], {"compat": "blender"}),
    (["--preserve-volume"], {"preserve_volume": True}),
    (["--solver", "lu"], {"solver": "lu"}),
    (["--solver", "cg"], {"solver": "cg"}),
    (["--area-normalized"], {"normalized": False}),
    (["--update", "recompute", "--iterations", "3"], {"update": "recompute", "iterations": 3}),
    (["--invert-weights", "--weights", "{w}"], {"invert_weights": True, "weights": "W"}),
    (["--lambda-border", "4"], {"lam_border": 4.0}),
    (["--lambda-border=-3", "--iterations", "2"], {"lam_border": -3.0, "iterations": 2}),
    (["--axes", "xz"], {"axes": "xz"}),
    (["--scheme", "blender"], {"scheme": "blender"}),
]


@pytest.mark.parametrize("mesh_name", ["closed", "open"])
@pytest.mark.parametrize("args,options", CASES, ids=[" ".join(a) for a, _ in CASES])
def test_cli_flow_option_equals_library(tmp_path, capsys, mesh_name, args, options):
    mesh = sf.load_example("spot") if mesh_name == "closed" else _open_mesh()
    src = tmp_path / "in.ply"
    sf.save(src, mesh)
    w = np.linspace(0.0, 1.0, mesh.n_vertices)
    np.save(tmp_path / "w.npy", w)
    out = tmp_path / "out.ply"
    code = main(["flow", str(src), str(out), "--lambda", "-7", "-q"] +
                [a.format(w=tmp_path / "w.npy") for a in args])
    assert code == 0, capsys.readouterr().err
    opts = {k: (w if v == "W" else v) for k, v in options.items()}
    expect = sf.flow(mesh, -7.0, **opts)
    got = sf.load(out)
    assert np.array_equal(got.vertices, expect.vertices)     # binary PLY stores float64 exactly
    if "solver" in options:   # "auto" may pick the same one: the run must say it used the one asked for
        assert expect.report.solver == options["solver"]
        return
    # the option must matter, except where it cannot: a closed mesh has no border; on Spot's quads
    # Blender's ½·cot per corner triangle equals the mean of the two triangulations (the tqlbo weights)
    same = {("closed", "lam_border"), ("closed", "compat"), ("closed", "scheme")}
    if not any((mesh_name, k) in same for k in options):
        assert not np.array_equal(expect.vertices, sf.flow(mesh, -7.0).vertices)
