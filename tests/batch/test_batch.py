"""``shapeflow batch`` on a generated dataset with a real Dask LocalCluster (docs/batch.md).

Every good file's output must equal the single-file command's (run in this process through
the CLI's own ``main``), every bad file must fail with its message, the manifest must hold
one record per file, a rerun must skip what is done, and nothing may be lost when a worker
process is killed mid-run or a file overruns its time.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from conftest import need

distributed = need("distributed", "Dask's distributed (the 'batch' extra)")

from dataset import make_dataset  # noqa: E402

import shapeflow.batch as sb  # noqa: E402
from shapeflow import cli  # noqa: E402

OP = ["enhance", "--strength", "20"]
ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("dataset")
    good, bad = make_dataset(root)
    return root, good, bad


@pytest.fixture(scope="module")
def cluster():
    c, client = sb.local_cluster(2)
    yield client
    client.close()
    c.close()


def reference(src: Path, out: Path, op=OP) -> bytes:
    """The single-file command's output for ``src``."""
    assert cli.main([*op, str(src), str(out)]) == 0
    return out.read_bytes()


def records(outdir: Path) -> list[dict]:
    with open(outdir / sb.MANIFEST_NAME, encoding="utf-8") as f:
        return [json.loads(line) for line in f]


def test_dataset_done_failed_and_accounted_for(dataset, cluster, tmp_path):
    root, good, bad = dataset
    out = tmp_path / "out"
    rep = sb.run(str(root), str(out), OP, client=cluster, progress=False)
    assert len(rep.records) == len(good) + len(bad)
    by_input = {Path(r["input"]): r for r in records(out)}
    assert set(by_input) == set(good) | set(bad)          # one record per file, README.txt left out
    ref = tmp_path / "ref"
    ref.mkdir()
    for src in good:
        r = by_input[src]
        assert r["status"] == "done", r
        rel = src.relative_to(root)
        assert Path(r["output"]) == out / rel
        assert (out / rel).read_bytes() == reference(src, ref / src.name), src
        assert r["vertices"] > 0 and r["faces"] > 0 and r["peak_rss"] > 0 and r["seconds"] >= 0.0
        assert r["report"]["lam"] == -20.0 and r["report"]["solver"] != "none"
        assert r["params"] == rep.records[0]["params"] and r["input_stamp"][0] == src.stat().st_size
    for src, word in bad.items():
        r = by_input[src]
        assert r["status"] == "failed" and word in r["error"], r
        assert not Path(r["output"]).exists()
    # nothing but the outputs, the manifest and the batch's own folder in OUTDIR
    stray = [p for p in out.rglob("*") if p.is_file() and ".shapeflow-batch" not in p.parts
             and p.name != sb.MANIFEST_NAME and p.relative_to(out) not in {g.relative_to(root) for g in good}]
    assert stray == []
    assert not rep.ok and len(rep.done) == len(good) and len(rep.failed) == len(bad)
    assert "failed" in rep.summary() and "files/s" in rep.summary()

    # a rerun skips every file done; the failed ones get their chance again
    again = sb.run(str(root), str(out), OP, client=cluster, progress=False)
    assert sorted(map(Path, again.skipped)) == sorted(good)
    assert {Path(r["input"]) for r in again.records} == set(bad)
    # another parameter, or --force, redoes them
    forced = sb.run(str(root / "a"), str(out / "forced"), OP, client=cluster, progress=False, force=True)
    assert len(forced.done) == len(list((root / "a").iterdir()))
    # a changed input is redone
    touched = good[0]
    os.utime(touched, ns=(touched.stat().st_atime_ns, touched.stat().st_mtime_ns + 10**9))
    third = sb.run(str(root), str(out), OP, client=cluster, progress=False)
    assert [Path(r["input"]) for r in third.done] == [touched]


def test_pipeline_format_and_family(dataset, cluster, tmp_path):
    root, good, _ = dataset
    sources = [str(p) for p in good[:4]]
    manifest = tmp_path / "list.txt"
    manifest.write_text("# four files\n" + "\n".join(sources) + "\n")
    out = tmp_path / "out"
    op = "smooth -s 2 --then subdivide --levels 1"
    rep = sb.run(str(manifest), str(out), op, client=cluster, format="ply", progress=False)
    assert len(rep.done) == 4
    for r in rep.done:
        src = Path(r["input"])
        assert r["output"].endswith(".ply")
        mid = tmp_path / f"mid{src.suffix}"
        reference(src, mid, ["smooth", "-s", "2"])
        assert Path(r["output"]).read_bytes() == reference(mid, tmp_path / "ref.ply", ["subdivide", "--levels", "1"])
    fam = sb.run(sources[:2], str(tmp_path / "fam"), "family --lambdas 0,-10", client=cluster, progress=False)
    assert len(fam.done) == 2
    for r in fam.done:
        members = sorted(os.listdir(r["output"]))
        assert len(members) == 2 and len(r["report"]) == 1
    try:
        import vtk  # noqa: F401
    except ImportError:
        return
    pics = sb.run(sources[:2], str(tmp_path / "pics"), "render --size 160x120 --view iso", client=cluster,
                  progress=False)
    assert len(pics.done) == 2
    from PIL import Image

    for r in pics.done:
        assert r["output"].endswith(".png") and Image.open(r["output"]).size == (160, 120)


def test_killed_worker_loses_nothing(dataset, tmp_path):
    """A worker process killed (SIGKILL) while it runs a file: the file is retried, the batch completes."""
    root, good, _ = dataset
    op = ["smooth", "--strength", "1", "--iterations", "30", "--update", "recompute"]
    files = [str(p) for p in good[:12]]
    cluster, client = sb.local_cluster(2)
    out = tmp_path / "out"
    killed = []

    def killer():
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not killed:
            busy = [w for w, keys in client.processing().items() if keys]   # one file each at most
            if busy:
                pids = client.run(os.getpid, workers=busy[:1])
                os.kill(next(iter(pids.values())), signal.SIGKILL)
                killed.append(busy[0])
            time.sleep(0.05)

    t = threading.Thread(target=killer)
    try:
        t.start()
        rep = sb.run(files, str(out), op, client=client, progress=False)
        t.join()
    finally:
        client.close()
        cluster.close()
    assert killed, "no worker was killed: the test did not test anything"
    assert rep.ok and len(rep.done) == len(files)
    left = [p for p in out.rglob("*") if p.name.startswith(sb.task.WORK_PREFIX)]
    assert left == []                    # the killed task's work folder is gone too
    recs = {r["input"]: r for r in records(out)}
    assert set(recs) == set(files) and all(r["status"] == "done" for r in recs.values())
    ref = tmp_path / "ref"
    ref.mkdir()
    for f in files:
        assert Path(recs[f]["output"]).read_bytes() == reference(Path(f), ref / Path(f).name, op)


def test_a_file_whose_worker_dies_twice_fails_with_the_reason(tmp_path):
    """The retry is one: a second death of the worker running the same file fails that file."""
    from meshgen import cube_sphere

    import shapeflow as sf

    slow = tmp_path / "slow.obj"
    sf.save(slow, cube_sphere(30))
    cluster, client = sb.local_cluster(2, retries=1)
    kills = []

    def killer():
        deadline = time.monotonic() + 120
        last = None
        while time.monotonic() < deadline and len(kills) < 2:
            busy = [w for w, keys in client.processing().items() if keys and w != last]
            if busy:
                try:
                    pids = client.run(os.getpid, workers=busy[:1])
                except Exception:   # the worker went away between the two calls: look again
                    continue
                os.kill(next(iter(pids.values())), signal.SIGKILL)
                kills.append(busy[0])
                last = busy[0]
            time.sleep(0.05)

    t = threading.Thread(target=killer)
    try:
        t.start()
        rep = sb.run([str(slow)], str(tmp_path / "out"), "smooth -s 1 --iterations 100000 --update recompute",
                     client=client, progress=False)
        t.join()
    finally:
        client.close()
        cluster.close()
    assert len(kills) == 2
    (rec,) = rep.records
    assert rec["status"] == "failed" and "worker process died 2 times" in rec["error"], rec
    assert not Path(rec["output"]).exists()
    assert [p.name for p in (tmp_path / "out").iterdir() if not p.name.startswith(".")] == [sb.MANIFEST_NAME]


def test_timeout_and_memory_limits(dataset, tmp_path):
    root, good, bad = dataset
    slow = tmp_path / "slow.obj"
    from meshgen import cube_sphere

    import shapeflow as sf

    sf.save(slow, cube_sphere(60))
    files = [str(slow), str(good[0]), str(root / "bad" / "huge.ply")]
    cluster, client = sb.local_cluster(2, retries=1)
    try:
        rep = sb.run(files, str(tmp_path / "out"), "smooth -s 1 --iterations 100000 --update recompute",
                     client=client, timeout=3, max_memory=2 * 2**30, progress=False)
    finally:
        client.close()
        cluster.close()
    recs = {r["input"]: r for r in rep.records}
    assert recs[str(slow)]["status"] == "failed" and "timed out after 3 s" in recs[str(slow)]["error"]
    assert "estimated peak memory" in recs[files[2]]["error"] and "1000000000000" in recs[files[2]]["error"]
    assert recs[files[1]]["status"] in ("done", "failed")
    if recs[files[1]]["status"] == "failed":     # 100,000 recomputed steps on a small mesh may overrun too
        assert "timed out" in recs[files[1]]["error"]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_scheduler_address_with_separate_worker_processes(dataset, tmp_path):
    """``--scheduler``: a scheduler and two workers started as processes of their own, as on a cluster."""
    root, good, _ = dataset
    port = _free_port()
    addr = f"tcp://127.0.0.1:{port}"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")])}
    procs = [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                               "--port", str(port), "--no-dashboard"], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        for _ in range(2):
            procs.append(subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", addr,
                                           "--nthreads", "1", "--no-dashboard"], env=env,
                                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        with distributed.Client(addr, timeout="60s") as c:
            c.wait_for_workers(2, timeout=60)
        out = tmp_path / "out"
        run = subprocess.run([sys.executable, "-m", "shapeflow", "batch", "--scheduler", addr, str(root / "a"),
                              str(out), *OP], env=env, capture_output=True, text=True, timeout=300)
        assert run.returncode == 0, run.stderr
        files = sorted((root / "a").iterdir())
        recs = records(out)
        assert sorted(Path(r["input"]) for r in recs) == files and all(r["status"] == "done" for r in recs)
        assert "2 workers" in run.stderr and "done" in run.stderr
    finally:
        for p in procs:
            p.terminate()
        for p in procs:
            p.wait(timeout=30)
