"""What the command line does for big files: stage notes, and no neighbour search on closed meshes."""

from __future__ import annotations

import numpy as np
from meshgen import grid, icosphere

import shapeflow as sf
from shapeflow import cli
from shapeflow.commands import common
from shapeflow.geometry.weld import may_need_weld


def test_stage_notes_for_big_files(tmp_path, capsys, monkeypatch):
    src = tmp_path / "ico.ply"
    sf.save(src, icosphere(3))
    monkeypatch.setattr(common, "STAGE_NOTES_FROM", 0)      # every file counts as big
    assert cli.main(["smooth", str(src), str(tmp_path / "out.ply"), "-s", "1"]) == 0
    err = capsys.readouterr().err
    assert f"reading {src}" in err and "642 vertices, 1,280 faces read in" in err
    assert cli.main(["smooth", str(src), str(tmp_path / "out2.ply"), "-s", "1", "--quiet"]) == 0
    assert capsys.readouterr().err == ""


def test_closed_meshes_skip_the_weld_and_keep_their_result(tmp_path):
    closed, opened = icosphere(2), grid(6)
    assert not may_need_weld(closed) and may_need_weld(opened)
    soup = tmp_path / "soup.stl"
    sf.save(soup, closed)
    assert may_need_weld(sf.load(soup))            # a triangle soup: every edge on a boundary
    src = tmp_path / "closed.ply"
    sf.save(src, closed)
    assert cli.main(["enhance", str(src), str(tmp_path / "out.ply"), "-s", "10", "-q"]) == 0
    np.testing.assert_array_equal(sf.load(tmp_path / "out.ply").vertices, sf.enhance(sf.load(src), 10.0).vertices)
