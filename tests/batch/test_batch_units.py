"""The parts of the batch runner that need no cluster: inputs, operations, sizes, the per-file function."""

from __future__ import annotations

import multiprocessing
import os
from pathlib import Path

import pytest
from conftest import need

import shapeflow as sf
from shapeflow import cli
from shapeflow.batch import Operation, expand_inputs, parse_operation, plan_jobs, process_file
from shapeflow.batch.estimate import estimate_peak_bytes, header_vertices
from shapeflow.cli.batch import parse_size
from shapeflow.errors import ParameterError


@pytest.fixture
def tree(tmp_path):
    m = sf.load_example("spot")
    for rel in ("a/x.obj", "a/b/y.ply", "z.off"):
        p = tmp_path / "in" / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        sf.save(p, m)
    (tmp_path / "in" / "notes.txt").write_text("hello\n")
    return tmp_path / "in"


def rels(pairs):
    return sorted(r for _, r in pairs)


def test_folder_glob_and_manifests(tree, tmp_path):
    assert rels(expand_inputs(str(tree))) == ["a/b/y.ply", "a/x.obj", "z.off"]
    assert rels(expand_inputs(str(tree / "**" / "*.ply"))) == ["a/b/y.ply"]
    assert rels(expand_inputs(str(tree / "a" / "*"))) == ["x.obj"]            # a folder is not a file
    assert rels(expand_inputs("file://" + str(tree / "z.off"))) == ["z.off"]
    txt = tmp_path / "list.txt"
    txt.write_text("# comment\n\nin/a/x.obj\nin/a/b/y.ply\n")
    assert expand_inputs(str(txt)) == [(str(tree / "a" / "x.obj"), "x.obj"),
                                       (str(tree / "a" / "b" / "y.ply"), "b/y.ply")]
    csv = tmp_path / "list.csv"
    csv.write_text("id,path\n1,in/z.off\n2,in/a/x.obj\n")
    assert rels(expand_inputs(str(csv))) == ["a/x.obj", "z.off"]
    with pytest.raises(ParameterError, match="nothing"):
        expand_inputs(str(tmp_path / "nothing"))


def test_plan_mirrors_the_tree_and_refuses_collisions(tree, tmp_path):
    out = tmp_path / "out"
    jobs = plan_jobs(str(tree), str(out), lambda ext: ".ply")
    assert sorted(os.path.relpath(j.output, out) for j in jobs) == ["a/b/y.ply", "a/x.ply", "z.ply"]
    sf.save(tree / "z.ply", sf.load_example("spot"))
    with pytest.raises(ParameterError, match="would both write"):
        plan_jobs(str(tree), str(out), lambda ext: ".ply")
    with pytest.raises(ParameterError, match="overwrite"):
        plan_jobs(str(tree / "z.off"), str(tree), lambda ext: ext)


def test_fsspec_urls(tree, tmp_path):
    fsspec = need("fsspec", "fsspec (the 'batch' extra)")
    fs = fsspec.filesystem("memory")
    fs.pipe("/set/a/m.obj", (tree / "a" / "x.obj").read_bytes())
    fs.pipe("/set/b/n.ply", (tree / "a" / "b" / "y.ply").read_bytes())
    fs.pipe("/set/list.txt", b"a/m.obj\nb/n.ply\n")
    assert rels(expand_inputs("memory://set/**/*.obj")) == ["a/m.obj"]
    assert rels(expand_inputs("memory://set")) == ["a/m.obj", "b/n.ply"]
    assert rels(expand_inputs("memory://set/list.txt")) == ["a/m.obj", "b/n.ply"]
    rec = process_file("memory://set/a/m.obj", str(tmp_path / "o.obj"), "enhance --strength 20")
    assert rec["status"] == "done", rec
    assert cli.main(["enhance", str(tree / "a" / "x.obj"), str(tmp_path / "ref.obj"), "-s", "20"]) == 0
    assert (tmp_path / "o.obj").read_bytes() == (tmp_path / "ref.obj").read_bytes()


def test_operations_are_checked_before_any_work():
    op = parse_operation("smooth -s 2 --then subdivide --levels 1")
    assert op.steps == (("smooth", "-s", "2"), ("subdivide", "--levels", "1")) and isinstance(op, Operation)
    assert op.output_suffix(".obj", None) == ".obj" and op.output_suffix(".obj", "PLY") == ".ply"
    assert parse_operation(["render", "--view", "iso"]).output_suffix(".obj", None) == ".png"
    assert parse_operation("family --lambdas 0,-5").output_suffix(".obj", "ply") == ""
    assert op.digest(None) != op.digest("ply") != parse_operation("smooth -s 3").digest("ply")
    for bad, word in [("", "no OPERATION"), ("info", "not a command"), ("enhance", "--strength"),
                      ("enhance -s 2 --then", "empty"), ("render --then smooth -s 1", "put it last"),
                      ("flow --lambda 1 --image x.png", "--image"), ("enhance -s 2 --format ply", "before INPUTS"),
                      ("enhance -s 'x", "quotation")]:
        with pytest.raises(ParameterError, match=word):
            parse_operation(bad)


def test_operations_are_parsed_once_into_options_that_travel():
    """Each step becomes its options object once, values checked before any file; the operation pickles
    (a Dask worker receives it) with its options, a family's list of λ included."""
    import pickle

    from shapeflow.commands import FamilyOptions, FlowOptions

    op = parse_operation("smooth -s 2 --iterations 3 --then family --lambdas 0,-5", fmt="obj")
    flow, fam = op.options
    assert isinstance(flow, FlowOptions) and (flow.command, flow.strength, flow.iterations) == ("smooth", 2.0, 3)
    assert isinstance(fam, FamilyOptions) and fam.lams == (0.0, -5.0) and fam.force and fam.format == "obj"
    assert pickle.loads(pickle.dumps(op)) == op
    for bad, message in [("enhance -s inf", "the operation (enhance -s inf): --strength must be finite, got inf"),
                         ("smooth -s 1 --then subdivide -l -1",
                          "step 2 of the operation (subdivide -l -1): --levels must be >= 0; got -1")]:
        with pytest.raises(ParameterError) as info:
            parse_operation(bad)
        assert str(info.value) == message


def test_sizes_and_estimates(tmp_path):
    assert parse_size("4G") == 4 * 2**30 and parse_size("512MiB") == 512 * 2**20 and parse_size("1000") == 1000
    assert parse_size("1.5k") == 1536
    for bad in ("lots", "-1G", "0"):
        with pytest.raises(ParameterError, match="max-memory"):
            parse_size(bad)
    m = sf.load_example("spot")
    for ext in (".ply", ".off"):
        sf.save(tmp_path / f"m{ext}", m)
        assert header_vertices(str(tmp_path / f"m{ext}")) == m.n_vertices
    sf.save(tmp_path / "m.stl", m)
    assert header_vertices(str(tmp_path / "m.stl")) == 3 * sf.load(tmp_path / "m.stl").n_faces
    def estimate(n, operation):
        return estimate_peak_bytes(n, parse_operation(operation).options)

    one = estimate(1000, "smooth -s 1")
    assert estimate(1000, "subdivide --levels 2") >= 4 * estimate(1000, "subdivide -l1") > one
    assert estimate(1000, "family --lambdas 0,1,2,3") > one


def test_process_file_in_a_plain_pool(tree, tmp_path):
    """The per-file function pickles and runs in a multiprocessing.Pool like any other."""
    jobs = [(str(tree / "a" / "x.obj"), str(tmp_path / "x.obj"), "smooth -s 3"),
            (str(tree / "notes.txt"), str(tmp_path / "n.obj"), "smooth -s 3")]
    with multiprocessing.get_context("spawn").Pool(2) as pool:
        recs = pool.starmap(process_file, jobs)
    assert recs[0]["status"] == "done" and recs[0]["vertices"] == sf.load_example("spot").n_vertices
    assert recs[1]["status"] == "failed" and "notes.txt" in recs[1]["error"]
    assert not Path(recs[1]["output"]).exists()
    assert cli.main(["smooth", str(tree / "a" / "x.obj"), str(tmp_path / "ref.obj"), "-s", "3"]) == 0
    assert (tmp_path / "x.obj").read_bytes() == (tmp_path / "ref.obj").read_bytes()
    assert sorted(os.listdir(tmp_path)) == ["in", "ref.obj", "x.obj"]      # no work folder left behind


def test_output_names_stay_below_the_root():
    """Hostile relative names, each with its normal form worked out by hand (RFC 3986 §5.2.4: '..'
    removes the segment before it and never climbs above the root)."""
    from shapeflow.batch.paths import OutsideOutdir, output_name

    cases = {("a/../../../x.ply", False): "x.ply", ("h/a/../../../../etc/x.ply", True): "etc/x.ply",
             ("%2e%2e/%2E%2e/x.ply", True): "x.ply", ("..%2f..%2fx.ply", True): "x.ply",
             ("a\\..\\..\\x.ply", False): "x.ply", ("/abs/./x.ply", False): "abs/x.ply",
             ("my%20scan.ply", True): "my scan.ply", ("my%20scan.ply", False): "my%20scan.ply",
             ("-x.ply", False): "-x.ply", ("a//b/./c.ply", False): "a/b/c.ply"}
    for (rel, url), want in cases.items():
        assert output_name(rel, url=url) == want, rel
    for rel, url in (("..", False), ("a/..", False), ("%2e%2e", True), ("x%00.ply", True), ("x\0.ply", False)):
        with pytest.raises(OutsideOutdir):
            output_name(rel, url=url)


def test_confine_refuses_every_way_out(tmp_path):
    from shapeflow.batch.paths import OutsideOutdir, confine

    out = tmp_path / "out"
    (out / "real").mkdir(parents=True)
    (tmp_path / "elsewhere").mkdir()
    (out / "link").symlink_to(tmp_path / "elsewhere")
    (out / "inner").symlink_to(out / "real")
    (out / "file.ply").symlink_to(tmp_path / "elsewhere" / "x.ply")
    assert confine(str(out), str(out / "real" / "x.ply")) == str(out / "real" / "x.ply")
    assert confine(str(out), str(out / "inner" / "x.ply"))          # a link that stays inside
    for bad in (out / ".." / "x.ply", out / "link" / "x.ply", out / "file.ply", tmp_path / "x.ply",
                str(out / "a\0b.ply"), out / ("n" * 256), out / "/".join(["d" * 200] * 21)):
        with pytest.raises(OutsideOutdir):
            confine(str(out), str(bad))


def test_worker_progress_bars_stay_off_and_messages_name_the_output(tree, tmp_path, monkeypatch):
    """A file runs with a stderr that is no terminal (the flow's own tqdm bar stays off), and what it
    says names its output, never the work folder's stand-in."""
    import sys

    pytest.importorskip("tqdm")
    written = []

    class Terminal:
        def isatty(self):
            return True

        def write(self, s):
            written.append(s)
            return len(s)

        def flush(self):
            pass

    out = tmp_path / "o.obj"
    monkeypatch.setattr(sys, "stderr", Terminal())
    rec = process_file(str(tree / "a" / "x.obj"), str(out), "smooth -s 1 --iterations 5")
    monkeypatch.undo()
    assert rec["status"] == "done" and written == []
    assert any(m.endswith(f"-> {out}") for m in rec["messages"]), rec["messages"]
    (tmp_path / "dir.obj").mkdir()                       # an output that cannot be replaced by a file
    rec = process_file(str(tree / "a" / "x.obj"), str(tmp_path / "dir.obj"), "smooth -s 1")
    assert rec["status"] == "failed" and str(tmp_path / "dir.obj") in rec["error"], rec
    assert ".shapeflow-batch-" not in rec["error"] + "".join(rec["messages"])


def test_the_digest_follows_the_contents_of_the_files_the_steps_read(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    n = sf.load_example("spot").n_vertices
    Path("w.txt").write_text("0.5\n" * n)
    Path("edges.txt").write_text("0 1\n")
    ops = ["smooth -s 2 --weights w.txt", "smooth -s 2 --weights=w.txt", "enhance -s 5 --sharp-edges edges.txt"]
    before = [parse_operation(o).digest(None) for o in ops]
    assert before == [parse_operation(o).digest(None) for o in ops]        # same files, same digest
    Path("w.txt").write_text("0.25\n" * n)
    Path("edges.txt").write_text("1 2\n")
    after = [parse_operation(o).digest(None) for o in ops]
    assert all(a != b for a, b in zip(before, after))
    # an attribute name is no file: the digest is the steps' alone
    assert parse_operation("smooth -s 2 --weights weight").read_files() == {}
    import hashlib

    assert parse_operation(ops[0]).read_files() == {"w.txt": hashlib.sha256(Path("w.txt").read_bytes()).hexdigest()}
