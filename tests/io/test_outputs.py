"""Output files: links followed, read-only and bundled files kept, no stray temporaries, every path checked first."""

from __future__ import annotations

import hashlib
import os
import signal
import subprocess
import sys
import textwrap

import pytest
from conftest import run_cli

import shapeflow as sf
from shapeflow import io as sio
from shapeflow.errors import OutputError
from shapeflow.io import atomic


def tri():
    return sf.Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])


# --- symbolic links -------------------------------------------------------------------------

@pytest.mark.parametrize("dangling", [False, True])
def test_save_through_a_symlink_writes_its_target(tmp_path, dangling):
    real_dir = tmp_path / "real"
    real_dir.mkdir()
    target = real_dir / "mesh.obj"
    if not dangling:
        target.write_text("old\n")
    link = tmp_path / "link.obj"
    link.symlink_to(target)
    sio.save(link, tri())
    assert link.is_symlink() and os.readlink(link) == str(target)
    assert sio.load(target) == tri()
    assert sorted(os.listdir(real_dir)) == ["mesh.obj"] and sorted(os.listdir(tmp_path)) == ["link.obj", "real"]


def test_cli_through_a_symlink(tmp_path, capsys):
    target = tmp_path / "t.ply"
    sio.save(target, tri())
    link = tmp_path / "l.ply"
    link.symlink_to(target.name)          # a relative link
    code, _, err = run_cli(["smooth", "example:spot", link, "--strength", "1", "-q"], capsys)
    assert code == 0, err
    assert link.is_symlink() and sio.load(target).n_vertices == sf.load_example("spot").n_vertices


# --- read-only files and bundled data ----------------------------------------------------------

def test_read_only_file_needs_force(tmp_path, capsys):
    out = tmp_path / "ro.obj"
    sio.save(out, tri())
    os.chmod(out, 0o444)
    before = out.read_bytes()
    with pytest.raises(OutputError, match=r"ro\.obj: is read-only; pass --force"):
        sio.save(out, sf.load_example("spot"))
    code, _, err = run_cli(["smooth", "example:spot", out, "--strength", "1"], capsys)
    assert code == 2 and "read-only" in err and out.read_bytes() == before
    code, _, err = run_cli(["smooth", "example:spot", out, "--strength", "1", "--force", "-q"], capsys)
    assert code == 0 and out.read_bytes() != before
    assert os.stat(out).st_mode & 0o777 == 0o444          # the file keeps its mode


@pytest.mark.parametrize("name", ["spot", "spot_cage"])
def test_bundled_examples_are_never_written(capsys, name):
    path = sf.example_path(name)
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    for args in (["smooth", f"example:{name}", path, "--strength", "1", "--force"],
                 ["subdivide", f"example:{name}", path, "--force"]):
        code, _, err = run_cli(args, capsys)
        assert code == 2 and "bundled example data" in err and len(err.strip().splitlines()) == 1
    with pytest.raises(OutputError, match="never written"):
        sio.save(path, tri(), force=True)
    assert hashlib.sha256(path.read_bytes()).hexdigest() == digest


# --- every output path checked before any work, named as the user gave it ------------------------

@pytest.fixture
def no_work(monkeypatch):
    """Any flow, subdivision or picture at all fails the test: the check must come first."""
    flow_mod = sys.modules["shapeflow.flow"]

    def forbidden(*a, **k):
        raise AssertionError("work started before the output paths were checked")

    monkeypatch.setattr(flow_mod.FlowSolver, "run", forbidden)
    import shapeflow.subdivision as sub
    monkeypatch.setattr(sub, "subdivide", forbidden)


@pytest.mark.parametrize("args,match", [
    (["smooth", "example:spot", "{tmp}/missing/out.obj", "--strength", "1"],
     "output folder '{tmp}/missing' does not exist"),
    (["smooth", "example:spot", "{tmp}/o.obj", "--strength", "1", "--image", "{tmp}/nope/i.png"],
     "output folder '{tmp}/nope' does not exist"),
    (["smooth", "example:spot", "{tmp}", "--strength", "1"], "{tmp}: is a directory"),
    (["subdivide", "example:spot", "{tmp}/s.obj", "--weights-out", "{tmp}/no/w.npy"], "output folder '{tmp}/no'"),
    (["curvature", "example:spot", "{tmp}/c.ply", "--image", "{tmp}/x/c.png"], "output folder '{tmp}/x'"),
    (["render", "example:spot", "{tmp}/y/r.png"], "output folder '{tmp}/y'"),
    (["family", "example:spot", "{tmp}/a/b", "--to=-10", "--step=-5"], "does not exist"),
])
def test_outputs_checked_before_work(tmp_path, capsys, no_work, args, match):
    code, _, err = run_cli([a.format(tmp=tmp_path) for a in args], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert match.format(tmp=tmp_path) in err
    assert ".tmp" not in err
    assert os.listdir(tmp_path) == []


def test_write_error_names_the_users_path(tmp_path, monkeypatch):
    def boom(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(atomic.os, "replace", boom)
    with pytest.raises(OutputError, match=r"out\.ply: cannot write: No space left on device") as info:
        sio.save(tmp_path / "out.ply", tri())
    assert ".tmp" not in str(info.value) and isinstance(info.value, OSError)
    assert os.listdir(tmp_path) == []


# --- signals during a write leave nothing behind ---------------------------------------------------

CHILD = textwrap.dedent("""
    import dataclasses, sys, time
    import shapeflow.io as sio
    from shapeflow.cli import main
    if {named}:
        import shapeflow.io.atomic as atomic
        atomic.unnamed_file = lambda d: None          # the named-temporary-file path
    def slow(f, mesh, **kw):
        f.write(b"x" * 100000)
        f.flush()
        print("writing", flush=True)
        time.sleep(60)
    sio.FORMATS[".ply"] = dataclasses.replace(sio.FORMATS[".ply"], writer=slow)
    sys.exit(main(["smooth", "example:spot", sys.argv[1], "--strength", "1", "-q"]))
""")


# a killed process cannot remove a named file: that is what the unnamed file (O_TMPFILE) is for
@pytest.mark.parametrize("sig,named", [(signal.SIGTERM, False), (signal.SIGHUP, False), (signal.SIGKILL, False),
                                       (signal.SIGTERM, True), (signal.SIGHUP, True)])
def test_signal_during_write_leaves_no_temporary(tmp_path, sig, named):
    out = tmp_path / "out.ply"
    sio.save(out, tri())
    before = out.read_bytes()
    p = subprocess.Popen([sys.executable, "-c", CHILD.format(named=named), str(out)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert p.stdout.readline().strip() == "writing"
        p.send_signal(sig)
        p.wait(timeout=60)
    finally:
        p.kill()
    assert p.returncode == (-sig if sig == signal.SIGKILL else 128 + sig)
    if sig != signal.SIGKILL:
        assert "nothing was left half-written" in p.stderr.read()
    assert os.listdir(tmp_path) == ["out.ply"] and out.read_bytes() == before
