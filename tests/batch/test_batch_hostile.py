"""``shapeflow batch`` as a real command on hostile inputs: it writes inside OUTDIR only, never wedges,
and says what it does (docs/batch.md, docs/robustness.md).

Every run is a subprocess on small generated meshes; the assertions are on the output tree (the
folder around OUTDIR is listed before and after), on the exact lines printed and on exit codes.
"""

from __future__ import annotations

import functools
import http.server
import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

pytest.importorskip("distributed")

from dataset import make_dataset  # noqa: E402

from shapeflow import cli  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
ENV = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")])}
OP = ["enhance", "--strength", "20"]
SLOW = ["smooth", "-s", "1", "--iterations", "100000", "--update", "recompute"]
PREFIX = "shapeflow batch: "


def batch(*args, cwd=None, timeout=300) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "shapeflow", "batch", *map(str, args)], env=ENV, cwd=cwd,
                          capture_output=True, text=True, timeout=timeout)


def tree(folder: Path) -> dict[str, bytes | str]:
    """Everything under ``folder`` (links as their targets, not followed)."""
    out = {}
    for dirpath, dirs, files in os.walk(folder):
        for name in dirs + files:
            p = Path(dirpath) / name
            out[str(p.relative_to(folder))] = ("-> " + os.readlink(p) if p.is_symlink()
                                               else p.read_bytes() if p.is_file() else "dir")
    return out


def records(outdir: Path) -> list[dict]:
    with open(outdir / "shapeflow-batch.jsonl", encoding="utf-8") as f:
        return [json.loads(line) for line in f]


def reference(src: Path, tmp: Path, op=OP) -> bytes:
    out = tmp / ("ref" + src.suffix)
    assert cli.main([*op, str(src), str(out)]) == 0
    return out.read_bytes()


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("data")
    good, _ = make_dataset(root, 6)
    return root, good


@pytest.fixture(scope="module")
def server(data):
    """The dataset over HTTP on this machine (SimpleHTTPRequestHandler: it decodes %-escapes and drops
    '..'), so URL inputs are fetched for real."""
    pytest.importorskip("aiohttp")
    handler = functools.partial(type("Quiet", (http.server.SimpleHTTPRequestHandler,),
                                     {"log_message": lambda *a: None}), directory=str(data[0]))
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    t = threading.Thread(target=httpd.serve_forever, daemon=True)
    t.start()
    yield f"127.0.0.1:{httpd.server_address[1]}"
    httpd.shutdown()


def test_manifest_url_with_dot_segments_writes_inside_outdir(data, server, tmp_path):
    """The case that wrote outside OUTDIR: a manifest entry whose URL climbs with '..' segments."""
    root, good = data
    work = tmp_path / "deep" / "er"
    work.mkdir(parents=True)
    (work / "list.txt").write_text(f"http://{server}/a/../../../../../../../a/m00.obj\n")
    before = tree(tmp_path)
    run = batch(work / "list.txt", work / "out", *OP)
    assert run.returncode == 0, run.stderr
    (rec,) = records(work / "out")
    # the URL's path, normalised as RFC 3986 says ('..' never climbs above the root): a/m00.obj
    assert rec["status"] == "done" and rec["output"] == str(work / "out" / "a" / "m00.obj")
    assert (work / "out" / "a" / "m00.obj").read_bytes() == reference(root / "a" / "m00.obj", tmp_path / "deep")
    after = tree(tmp_path)
    new = {k for k in after if k not in before}
    assert all(k.startswith(os.path.join("deep", "er", "out")) or k == os.path.join("deep", "ref.obj")
               for k in new), new


def test_hostile_url_names(data, server, tmp_path):
    """Percent-encoded dots and slashes, backslashes, absolute paths and a NUL in URLs: every output
    lands inside OUTDIR, a name that cannot be one fails alone, nothing is made around OUTDIR."""
    root, good = data
    entries = {
        f"http://{server}/%2e%2e/%2e%2e/%2E%2E/a/m03.stl": ("done", "a/m03.stl"),
        f"http://{server}/..%2f..%2f..%2fb/c/m01.ply": ("done", "b/c/m01.ply"),
        f"http://{server}/b/c/..%5c..%5c..%5c..%5cm04.obj": ("failed", "m04.obj"),   # '\' is a separator
        f"http://{server}//{str(root / 'm02.off').lstrip('/')}": ("failed", None),     # an absolute path
        f"http://{server}/m05.ply?x=/../../../y": ("done", f"{server}/m05.ply"),
        f"http://{server}/%00.obj": ("failed", None),
        f"http://{server}/{'y' * 300}.obj": ("failed", f"{server}/{'y' * 300}.obj"),
    }
    work = tmp_path / "w"
    work.mkdir()
    (work / "list.txt").write_text("".join(e + "\n" for e in entries))
    before = tree(tmp_path)
    run = batch(work / "list.txt", work / "out", *OP)
    assert run.returncode == 1, run.stderr
    out = work / "out"
    recs = {r["input"]: r for r in records(out)}
    assert set(recs) == set(entries)
    for entry, (status, name) in entries.items():
        r = recs[entry]
        assert r["status"] == status, r
        if name is not None:
            assert r["output"] == str(out / name)
        if status == "done":
            src = root / name.split("/", 1)[1] if name.startswith(server) else root / name
            assert Path(r["output"]).read_bytes() == reference(src, tmp_path)
    absolute = recs[f"http://{server}//{str(root / 'm02.off').lstrip('/')}"]["output"]
    assert absolute == str(out / server / str(root / "m02.off").lstrip("/"))
    assert recs[f"http://{server}/%00.obj"]["error"] == f"'{server}/%00.obj': a file name cannot hold a NUL character"
    assert recs[f"http://{server}/%00.obj"]["output"] is None
    assert recs[f"http://{server}/{'y' * 300}.obj"]["error"] == (
        f"output '{out / server / ('y' * 300 + '.obj')}': a name of 304 bytes is longer than the 255 a file "
        "system takes")
    new = {k for k in tree(tmp_path) if k not in before}
    assert all(k.startswith(os.path.join("w", "out")) or k.startswith("ref.") for k in new), new


def test_hostile_local_names_and_links(data, tmp_path):
    """A name starting with '-', a NUL in a manifest, a folder of OUTDIR that is a link leading out of
    it, a manifest that is one: each ends as listed, and nothing outside OUTDIR changes."""
    root, good = data
    src = tmp_path / "in"
    (src / "a").mkdir(parents=True)
    (src / "-s.obj").write_bytes(good[0].read_bytes())
    (src / "a" / "m.obj").write_bytes(good[0].read_bytes())
    run = batch("*.obj", tmp_path / "dash", *OP, cwd=src)             # the source is '-s.obj' itself
    assert run.returncode == 0, run.stderr
    (rec,) = records(tmp_path / "dash")
    assert rec["input"] == "-s.obj" and rec["status"] == "done"
    assert (tmp_path / "dash" / "-s.obj").read_bytes() == reference(src / "-s.obj", tmp_path / "dash")

    outside = tmp_path / "outside"
    outside.mkdir()
    out = tmp_path / "out"
    out.mkdir()
    (out / "a").symlink_to(outside)                    # planted: out/a leads out of OUTDIR
    before = tree(tmp_path)
    run = batch(src, out, *OP)
    assert run.returncode == 1, run.stderr
    recs = {Path(r["input"]).name: r for r in records(out)}
    assert recs["-s.obj"]["status"] == "done" and Path(recs["-s.obj"]["output"]) == out / "-s.obj"
    assert recs["m.obj"]["status"] == "failed"
    assert recs["m.obj"]["error"] == (f"output '{out / 'a' / 'm.obj'}' would be written outside OUTDIR '{out}': "
                                      f"it leads to '{outside / 'm.obj'}' through a symbolic link")
    after = tree(tmp_path)
    assert {k: v for k, v in after.items() if not k.startswith("out")} == \
        {k: v for k, v in before.items() if not k.startswith("out")}
    assert sorted(os.listdir(outside)) == []

    # a manifest entry holding a NUL fails alone, named
    (tmp_path / "list.txt").write_bytes(f"{src / '-s.obj'}\n{src}/b\0c.obj\n".encode())
    run = batch(tmp_path / "list.txt", tmp_path / "out2", *OP)
    assert run.returncode == 1, run.stderr
    (bad,) = [r for r in records(tmp_path / "out2") if r["status"] == "failed"]
    assert bad["error"] == "'b\\x00c.obj': a file name cannot hold a NUL character"

    # OUTDIR's manifest a link to a file outside: the batch is refused before any work
    (outside / "victim.jsonl").write_text("keep\n")
    out3 = tmp_path / "out3"
    out3.mkdir()
    (out3 / "shapeflow-batch.jsonl").symlink_to(outside / "victim.jsonl")
    run = batch(src, out3, *OP)
    assert run.returncode == 2
    assert run.stderr.splitlines() == [
        f"shapeflow batch: error: the manifest '{out3 / 'shapeflow-batch.jsonl'}' would be written outside "
        f"OUTDIR '{out3}': it leads to '{outside / 'victim.jsonl'}' through a symbolic link"]
    assert (outside / "victim.jsonl").read_text() == "keep\n"
    assert sorted(p.name for p in out3.iterdir()) == ["shapeflow-batch.jsonl"]


def test_link_loops_outdir_inside_and_equal_to_inputs(data, tmp_path):
    root, good = data
    src = tmp_path / "in"
    (src / "d").mkdir(parents=True)
    for i, g in enumerate(good[:3]):
        (src / "d" / f"f{i}{g.suffix}").write_bytes(g.read_bytes())
    (src / "d" / "up").symlink_to("..")                # a loop: in/d/up/d/up/...
    (src / "self").symlink_to(".")                     # another
    (src / f"twin{good[0].suffix}").symlink_to(src / "d" / f"f0{good[0].suffix}")   # one file, two names
    out = src / "out"
    for inputs in (src, str(src / "**" / "*")):
        run = batch("--force", inputs, out, *OP)
        assert run.returncode == 0, run.stderr
        recs = records(out)
        done = sorted(Path(r["input"]).relative_to(src).as_posix() for r in recs[-3:])
        assert done == [f"d/f{i}{g.suffix}" for i, g in enumerate(good[:3])]
        lines = run.stderr.splitlines()
        assert lines[0] == f"shapeflow batch: OUTDIR {out} is inside INPUTS: its files are not taken as inputs"
    assert len(records(out)) == 6                      # each real file once a run, OUTDIR's files never
    for same in (src, src / "self"):
        before = tree(tmp_path)
        run = batch(src, same, *OP)
        assert run.returncode == 2
        assert run.stderr.splitlines() == [f"shapeflow batch: error: OUTDIR '{same}' is the INPUTS folder "
                                           f"'{src}' itself: the outputs would land among the inputs; "
                                           "choose another OUTDIR"]
        assert tree(tmp_path) == before


def test_missing_inputs_leave_nothing(tmp_path):
    before = tree(tmp_path)
    for missing in (tmp_path / "nothing", tmp_path / "nothing" / "**" / "*.ply", "file://" + str(tmp_path / "no")):
        run = batch(missing, tmp_path / "out" / "deeper", *OP)
        assert run.returncode == 2
        assert run.stderr.splitlines() == [f"shapeflow batch: error: INPUTS '{missing}': no such file, folder or "
                                           "glob match"]
        assert tree(tmp_path) == before


def test_damaged_manifest_lines_are_skipped_and_their_files_redone(data, tmp_path):
    root, good = data
    src = tmp_path / "in"
    src.mkdir()
    names = ["a.obj", "é.obj", "c.obj"]
    for n in names:
        (src / n).write_bytes(good[0].read_bytes())
    out = tmp_path / "out"
    assert batch(src, out, *OP).returncode == 0
    path = out / "shapeflow-batch.jsonl"
    lines = path.read_bytes().splitlines(keepends=True)
    by_name = {Path(json.loads(ln)["input"]).name: ln for ln in lines}
    wrong = json.loads(by_name["a.obj"])
    wrong["status"] = 7                                 # a number where a string belongs
    cut = by_name["é.obj"]
    cut = cut[:cut.index("é".encode()) + 1]             # inside the two bytes of 'é'
    path.write_bytes(json.dumps(wrong).encode() + b"\n" + by_name["c.obj"] + cut)
    run = batch(src, out, *OP)
    assert run.returncode == 0, run.stderr
    assert run.stderr.splitlines()[:3] == [
        f"shapeflow batch: manifest {path} line 1: 'status' is a number; skipped "
        f"({src / 'a.obj'} is done again)",
        f"shapeflow batch: manifest {path} line 3: cut short or not JSON; skipped (its file, if any, is done again)",
        "shapeflow batch: 3 files, 1 done before, 2 to do on 2 workers"]
    again = [json.loads(ln) for ln in path.read_bytes().splitlines()[-2:]]
    assert sorted(Path(r["input"]).name for r in again) == ["a.obj", "é.obj"]
    assert all(r["status"] == "done" for r in again)


def test_rerun_notices_and_force(data, tmp_path):
    root, good = data
    out = tmp_path / "out"
    assert batch(root / "a", out, *OP).returncode == 0
    n = len(list((root / "a").iterdir()))
    runs = [(["--quiet"], OP, []),
            ([], ["enhance", "--strength", "10"],
             [f"parameters (or a file they name) changed since the last run: {n} files done before will be done "
              "again"]),
            (["--force"], ["enhance", "--strength", "10"], [f"--force: {n} files done before will be done again"]),
            ([], ["enhance", "--strength", "10"], [f"{n} files, {n} done before, 0 to do on no workers"])]
    for opts, op, expected in runs:
        run = batch(*opts, root / "a", out, *op)
        assert run.returncode == 0, run.stderr
        assert run.stderr.splitlines()[:len(expected)] == [PREFIX + e for e in expected]
    (out / "m00.obj").unlink()
    run = batch(root / "a", out, "enhance", "--strength", "10")
    assert run.stderr.splitlines()[0] == PREFIX + ("1 file done before will be done again: input changed or "
                                                   "output missing")


LINE = re.compile(r"shapeflow batch: (\d+)/(\d+) files, (\d+) done, (\d+) failed, (\d+\.\d\d) files/s, "
                  r"ETA (\d+:\d\d:\d\d|unknown)")


def test_progress_lines_off_a_terminal(data, tmp_path):
    root, good = data
    run = batch("--progress-interval", "0.05", root, tmp_path / "out", "smooth", "-s", "1", "--iterations", "20",
                "--update", "recompute")
    assert run.returncode == 1, run.stderr          # the dataset's bad files fail
    lines = [ln for ln in run.stderr.splitlines() if "/s, ETA" in ln]
    assert lines, run.stderr
    total = len(records(tmp_path / "out"))
    last = (0, 0)
    for ln in lines:
        m = LINE.fullmatch(ln)
        assert m, ln
        finished, of, done, failed = map(int, m.groups()[:4])
        assert of == total and finished == done + failed <= total and (done, failed) >= last
        assert (m.group(6) == "unknown") == (finished == 0)
        last = (done, failed)
    assert not [ln for ln in run.stderr.splitlines() if "it/s" in ln or "\r" in ln]   # no worker's bar


def _start(args, tmp_path) -> tuple[subprocess.Popen, list[str]]:
    p = subprocess.Popen([sys.executable, "-m", "shapeflow", "batch", *map(str, args)], env=ENV,
                         stderr=subprocess.PIPE, text=True, start_new_session=True)
    lines: list[str] = []
    threading.Thread(target=lambda: lines.extend(p.stderr), daemon=True).start()
    return p, lines


def _wait_for(cond, seconds=120):
    deadline = time.monotonic() + seconds
    while not cond():
        assert time.monotonic() < deadline, "timed out waiting"
        time.sleep(0.05)


@pytest.mark.parametrize("sig, when, code", [(signal.SIGINT, "running", 130), (signal.SIGTERM, "running", 143),
                                             (signal.SIGINT, "starting", 130)])
def test_interrupted_run_leaves_no_semaphores(data, tmp_path, sig, when, code):
    """Ctrl-C (SIGINT to the process group, as a terminal sends it) or SIGTERM while files run or while the
    cluster starts: the run ends with its code, one line, no traceback, no leaked-semaphore warning, no
    process left, and the same command then finishes the work."""
    psutil = pytest.importorskip("psutil")
    root, good = data
    out = tmp_path / "out"
    p, lines = _start([root / "a", out, *SLOW], tmp_path)
    if when == "running":
        _wait_for(lambda: any("to do on" in ln for ln in lines))
    else:
        _wait_for(lambda: (out / ".shapeflow-batch" / "workers.log").exists())
    kids = psutil.Process(p.pid).children(recursive=True)
    os.killpg(p.pid, sig)
    assert p.wait(timeout=120) == code
    psutil.wait_procs(kids, timeout=60)
    assert not [k for k in kids if k.is_running()]
    time.sleep(0.5)
    log = out / ".shapeflow-batch" / "workers.log"
    text = "".join(lines) + (log.read_text(errors="replace") if log.exists() else "")
    assert "leaked" not in text and "Traceback" not in text, text
    assert lines[-1].rstrip("\n") in (f"{PREFIX}terminated by SIGTERM; nothing was left half-written",
                                      f"{PREFIX}manifest: {out / 'shapeflow-batch.jsonl'}")
    assert not [p for p in out.rglob("*") if p.name.startswith(".shapeflow-batch-")]


def test_killed_run_leaves_no_semaphores_for_the_next(data, tmp_path):
    """SIGKILL of the batch process: its workers close by themselves, nothing warns of leaked semaphores,
    and the next run completes the files."""
    psutil = pytest.importorskip("psutil")
    root, good = data
    out = tmp_path / "out"
    p, lines = _start([root / "a", out, "smooth", "-s", "1", "--iterations", "50", "--update", "recompute"], tmp_path)
    _wait_for(lambda: any("to do on" in ln for ln in lines))
    kids = psutil.Process(p.pid).children(recursive=True)
    p.kill()
    p.wait(timeout=60)
    gone, alive = psutil.wait_procs(kids, timeout=60)
    assert alive == []
    log = (out / ".shapeflow-batch" / "workers.log").read_text(errors="replace")
    assert "leaked" not in "".join(lines) + log
    run = batch(root / "a", out, "smooth", "-s", "1", "--iterations", "50", "--update", "recompute")
    assert run.returncode == 0, run.stderr
    assert "leaked" not in run.stderr and "Traceback" not in run.stderr
    assert {r["input"] for r in records(out) if r["status"] == "done"} == {str(g) for g in (root / "a").iterdir()}


def test_url_inputs_with_default_options(data, tmp_path):
    """memory:// (only this process sees it: the driver sends its bytes), file:// and local:// URLs, each
    with the default options (a local cluster of worker processes), same bytes as the single-file command."""
    fsspec = pytest.importorskip("fsspec")
    import shapeflow.batch as sb

    root, good = data
    a = sorted((root / "a").iterdir())
    fs = fsspec.filesystem("memory")
    for p in a:
        fs.pipe(f"/hostile-set/{p.name}", p.read_bytes())
    rep = sb.run("memory://hostile-set", str(tmp_path / "mem"), OP, progress=False)
    assert rep.ok and len(rep.done) == len(a), rep.summary()
    for p in a:
        assert (tmp_path / "mem" / p.name).read_bytes() == reference(p, tmp_path)
    for scheme in ("file://", "local://"):
        out = tmp_path / scheme[:-3]
        run = batch(scheme + str(root / "a"), out, *OP)
        assert run.returncode == 0, run.stderr
        assert sorted(r["input"] for r in records(out)) == [str(p) for p in a]
        assert all((out / p.name).read_bytes() == reference(p, tmp_path) for p in a)


def test_on_a_terminal_only_the_batch_bar(data, tmp_path):
    """stderr a terminal: the batch's tqdm bar is the only bar (each file's flow would draw its own), and no
    progress line is printed."""
    pytest.importorskip("tqdm")
    import fcntl
    import pty
    import struct
    import termios

    root, good = data
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))    # a 100-column terminal
    p = subprocess.Popen([sys.executable, "-m", "shapeflow", "batch", "--progress-interval", "0.05", str(root / "a"),
                          str(tmp_path / "out"), "smooth", "-s", "1", "--iterations", "20"],
                         env=ENV, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=slave)
    os.close(slave)
    chunks = []
    while True:
        try:
            chunk = os.read(master, 4096)
        except OSError:                    # the terminal's other end closed
            break
        if not chunk:
            break
        chunks.append(chunk)
    assert p.wait(timeout=300) == 0
    os.close(master)
    text = b"".join(chunks).decode(errors="replace")
    bars = [seg for seg in re.split(r"[\r\n]", text) if "%|" in seg]
    assert bars and all(seg.lstrip("\x1b[A ").startswith("batch:") for seg in bars), bars
    assert "files/s, ETA" not in text and "flow:" not in text


def test_a_relative_outdir_is_confined_as_an_absolute_one(data, tmp_path):
    """OUTDIR given relative to the current folder: links planted in it (its manifest, its batch
    folder, a folder of outputs) lead nowhere outside, as with an absolute OUTDIR."""
    root, good = data
    (tmp_path / "in" / "z" / "sub").mkdir(parents=True)
    (tmp_path / "in" / "z" / "sub" / "t.obj").write_bytes(good[0].read_bytes())
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "victim.txt").write_text("precious\n")
    for planted, target in (("shapeflow-batch.jsonl", outside / "victim.txt"), (".shapeflow-batch", outside)):
        (tmp_path / "out").mkdir()
        (tmp_path / "out" / planted).symlink_to(target)
        before = tree(outside)
        run = batch("in", "out", *OP, cwd=tmp_path)
        assert run.returncode == 2 and "would be written outside OUTDIR 'out'" in run.stderr, run.stderr
        assert tree(outside) == before
        (tmp_path / "out" / planted).unlink()
        os.rmdir(tmp_path / "out")
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "z").symlink_to(outside)               # a folder of outputs leading out
    before = tree(outside)
    run = batch("in", "out", *OP, cwd=tmp_path)
    assert run.returncode == 1, run.stderr
    (rec,) = records(tmp_path / "out")
    assert rec["status"] == "failed" and "would be written outside OUTDIR 'out'" in rec["error"]
    assert tree(outside) == before                             # no folder made there, nothing written


def test_outputs_never_replace_an_input_or_a_file_the_batch_did_not_write(data, tmp_path):
    root, good = data
    src = tmp_path / "in"
    (src / "out").mkdir(parents=True)
    (src / "a.obj").write_bytes(good[0].read_bytes())
    (src / "out" / "a.obj").write_bytes(good[1].read_bytes())   # an input where a.obj's output would go
    (tmp_path / "list.txt").write_text(f"{src / 'a.obj'}\n{src / 'out' / 'a.obj'}\n")
    run = batch(tmp_path / "list.txt", src / "out", *OP)
    assert run.returncode == 2
    assert run.stderr.splitlines()[-1] == (
        f"shapeflow batch: error: the output of '{src / 'a.obj'}' would overwrite the input "
        f"'{src / 'out' / 'a.obj'}'; choose an OUTDIR that holds no input")
    assert (src / "out" / "a.obj").read_bytes() == good[1].read_bytes()

    # OUTDIR inside INPUTS already holding the user's own file where an output goes: that file fails
    mine = tmp_path / "in6"
    (mine / "sub").mkdir(parents=True)
    (mine / "y.obj").write_bytes(good[0].read_bytes())
    (mine / "sub" / "y.obj").write_bytes(good[1].read_bytes())
    run = batch(mine, mine / "sub", *OP)
    assert run.returncode == 1, run.stderr
    (rec,) = records(mine / "sub")
    assert rec["status"] == "failed" and rec["error"] == (
        f"{mine / 'sub' / 'y.obj'} exists and was not written by shapeflow batch: move it away, or give --force "
        "to replace it")
    assert (mine / "sub" / "y.obj").read_bytes() == good[1].read_bytes()
    run = batch("--force", mine, mine / "sub", *OP)
    assert run.returncode == 0, run.stderr
    assert (mine / "sub" / "y.obj").read_bytes() == reference(mine / "y.obj", tmp_path)


def test_a_manifest_that_cannot_be_written_is_named(tmp_path, monkeypatch):
    from shapeflow.batch.manifest import Manifest
    from shapeflow.errors import OutputError

    with Manifest(str(tmp_path)) as m:
        class Full:
            def write(self, text):
                raise OSError(28, "No space left on device")

            flush = fileno = close = lambda self: None

        real, m._file = m._file, Full()
        with pytest.raises(OutputError) as exc:
            m.append({"input": "a.obj"})
        assert str(exc.value) == (f"the manifest '{tmp_path / 'shapeflow-batch.jsonl'}' cannot be written: "
                                  "No space left on device")
        m._file = real
