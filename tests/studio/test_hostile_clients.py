"""The studio survives any client: hostile WebSocket messages are answered by an error and change
nothing, nothing non-finite is sent, a tab that stops reading costs bounded memory and is closed,
family solves never pile up, uploads are read in a bounded child, the studio welds like the CLI."""

from __future__ import annotations

import asyncio
import json
import os
import tempfile
import threading

import numpy as np
import pytest

import shapeflow as sf

pytest.importorskip("aiohttp", reason="aiohttp (the 'studio' extra) is not installed")

import aiohttp  # noqa: E402

from shapeflow.errors import MeshError, ParameterError  # noqa: E402
from shapeflow.studio import StudioServer, StudioSession  # noqa: E402
from shapeflow.studio.upload import read_upload  # noqa: E402


@pytest.fixture(scope="module")
def server():
    with StudioServer(sf.load_example("spot"), lams=[0.0, -20.0, -40.0]) as srv:
        srv.session.wait_family(120)
        yield srv


def ws_url(srv):
    return srv.address.replace("http", "ws") + f"ws?token={srv.token}"


async def until(ws, kind):
    """The next text message of ``kind`` (binary frames and other messages skipped)."""
    while True:
        m = await ws.receive(timeout=60)
        assert m.type in (aiohttp.WSMsgType.TEXT, aiohttp.WSMsgType.BINARY), m
        if m.type == aiohttp.WSMsgType.TEXT and json.loads(m.data)["type"] == kind:
            return json.loads(m.data)


HOSTILE = [
    ('{"op": "lam", "value": NaN}', "finite"),
    ('{"op": "lam", "value": Infinity}', "finite"),
    ('{"op": "lam", "value": -Infinity}', "finite"),
    ('{"op": "lam", "value": 1e400}', "finite"),
    ('{"op": "apply", "value": 1e13}', "value"),
    ('{"op": "lam", "value": ' + "9" * 5000 + "}", "JSON"),
    ('{"op": "lam", "value": ' + "9" * 400 + "}", "value"),
    ('{"op": "lam", "value": "3"}', "value must be a number"),
    ('{"op": "lam", "value": true}', "value must be a number"),
    ("[1, 2, 3]", "JSON object"),
    ('"lam"', "JSON object"),
    ("17", "JSON object"),
    ("null", "JSON object"),
    ("{not json", "not valid JSON"),
    ("[" * 20000 + "]" * 20000, "JSON"),
    ('{"op": "lam", "value": 1, "deep": ' + "[" * 30 + "]" * 30 + "}", "nests deeper"),
    ('{"op": "rm -rf"}', "unknown operation"),
    ('{"op": ["lam"]}', "unknown operation"),
    ('{"value": 1}', "unknown operation"),
    ('{"op": "lam", "value": 1, "__proto__": {}}', "unknown field"),
    ('{"op": "lam"}', "missing"),
    ('{"op": "dab", "center": [0, 0], "radius": 0.1}', "3 numbers"),
    ('{"op": "dab", "center": [0, 0, NaN], "radius": 0.1}', "finite"),
    ('{"op": "dab", "center": [0, 0, 0], "radius": 1e308}', "radius"),
    ('{"op": "dab", "center": [0, 0, 0], "radius": 0}', "radius"),
    ('{"op": "dab", "center": [0, 0, 0], "radius": -1}', "radius"),
    ('{"op": "dab", "center": [1e300, 0, 0], "radius": 0.1}', "far outside"),
    ('{"op": "dab", "center": [0, 0, 0], "radius": 0.1, "lam": 1e9}', "lam"),
    ('{"op": "dab", "center": [0, 0, 0], "radius": 0.1, "inflate": "yes"}', "true or false"),
    ('{"op": "paint", "center": [0, 0, 0], "radius": 0.1, "value": 2}', "value"),
    ('{"op": "options", "iterations": 10000000000}', "iterations"),
    ('{"op": "options", "compat": "maya"}', "compat"),
    ('{"op": "solve", "lams": []}', "lams"),
    ('{"op": "solve", "lams": ' + json.dumps([0.0] * 1001) + "}", "lams"),
    ('{"op": "solve", "lams": [0, "x"]}', "lams[1]"),
    ('{"op": "field", "name": "__class__"}', "name"),
    ('{"op": "begin", "tool": "rm"}', "unknown field"),
    ('{"op": "dab", "center": [0, 0, 0], "radius": 0.1, "inflate": true, "strength": 5}', "strength"),
    ('{"op": "paint", "center": [0, 0, 0], "radius": 0.1, "mirror": 1}', "true or false"),
    ('{"op": "solve", "from": 0, "to": -10, "step": 0}', "step"),
    ('{"op": "solve", "from": 0, "to": -10, "step": 5}', "gives no"),
    ('{"op": "solve", "from": 0, "to": -1000000, "step": -0.001}', "more than"),
    ('{"op": "solve", "lams": [0], "from": 0, "to": -10, "step": -1}', "not both"),
    ('{"op": "solve", "from": 0}', "from, to and step"),
    ('{"op": "lam", "value": 0, "id": -1}', "id"),
    ('{"op": "lam", "value": 0, "id": 1.5}', "id"),
]


def test_hostile_messages_are_answered_by_an_error_and_change_nothing(server):
    s = server.session

    async def go():
        async with aiohttp.ClientSession() as cs:
            async with cs.ws_connect(ws_url(server), max_msg_size=0) as ws:
                await until(ws, "state")
                before = (s.version, s.vertices.copy(), s.weights.copy(), s.family_status().lams)
                for text, words in HOSTILE:
                    await ws.send_str(text)
                    err = await until(ws, "error")
                    assert words.lower() in err["message"].lower(), (text[:60], err["message"])
                    assert len(err["message"]) < 300
                await ws.send_bytes(b"\x00" * 100)                       # binary: refused the same way
                assert "JSON text" in (await until(ws, "error"))["message"]
                after = (s.version, s.vertices, s.weights, s.family_status().lams)
                assert before[0] == after[0] and np.array_equal(before[1], after[1])
                assert np.array_equal(before[2], after[2]) and before[3] == after[3]
                await ws.send_str('{"op": "lam", "value": -20}')          # the socket still works
                st = await until(ws, "state")
                assert st["lam"] == -20.0
                await ws.send_str('{"op": "lam", "value": 0}')
                await until(ws, "state")

    asyncio.run(go())


def test_a_too_long_message_closes_only_that_socket(server):
    async def go():
        async with aiohttp.ClientSession() as cs:
            async with cs.ws_connect(ws_url(server)) as a, cs.ws_connect(ws_url(server)) as b:
                await until(a, "state")
                await until(b, "state")
                await a.send_str('{"op": "lam", "value": 0, "pad": "' + "x" * 70000 + '"}')
                m = await a.receive(timeout=30)
                while m.type == aiohttp.WSMsgType.BINARY or m.type == aiohttp.WSMsgType.TEXT:
                    m = await a.receive(timeout=30)
                assert m.type in (aiohttp.WSMsgType.CLOSE, aiohttp.WSMsgType.CLOSED, aiohttp.WSMsgType.CLOSING)
                await b.send_str('{"op": "lam", "value": 0}')             # the other tab is unaffected
                assert (await until(b, "state"))["lam"] == 0.0

    asyncio.run(go())


def test_coordinates_a_page_cannot_draw_are_refused_before_anything_is_sent():
    mesh = sf.load_example("spot")
    with pytest.raises(ParameterError, match="float32"):
        StudioServer(mesh.with_vertices(mesh.vertices * 1e38), solve=False)


def test_a_tab_that_stops_reading_costs_bounded_memory_and_is_closed():
    from shapeflow.studio.server import hub_of

    limit = 1 << 20
    with StudioServer(sf.load_example("spot"), lams=[0.0, -20.0], outbox_limit=limit, stall_seconds=2.0) as srv:
        srv.session.wait_family(120)
        hub = hub_of(srv._app)
        snapshot = sum(len(m) if isinstance(m, bytes) else 256 for m in hub.snapshot())

        async def go():
            import socket

            host, port = srv.address.split("/")[2].split(":")
            sleeper = socket.create_connection((host, int(port)))           # upgrades, then never reads
            sleeper.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            sleeper.sendall((f"GET /ws?token={srv.token} HTTP/1.1\r\nHost: {host}:{port}\r\nUpgrade: websocket\r\n"
                             "Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                             "Sec-WebSocket-Version: 13\r\n\r\n").encode())
            async with aiohttp.ClientSession() as cs:
                async with cs.ws_connect(ws_url(srv), max_msg_size=0) as ws:
                    await until(ws, "state")
                    assert len(hub.sockets) == 2
                    boxes = list(hub.sockets.values())
                    for k in range(300):                   # ~35 KB of positions to every tab per message
                        await ws.send_str(json.dumps({"op": "lam", "value": -20.0 * (k % 2)}))
                        await until(ws, "state")
                    for _ in range(200):                   # the sleeper is closed once a send stalls 2 s
                        if len(hub.sockets) == 1:
                            break
                        await asyncio.sleep(0.1)
                    assert len(hub.sockets) == 1
                    stalled = [b for b in boxes if b.stalled]
                    assert len(stalled) == 1
                    assert max(b.peak for b in boxes) <= limit + snapshot
                    await ws.send_str('{"op": "lam", "value": 0.5}')    # the reading tab goes on
                    while (await until(ws, "state"))["lam"] != 0.5:
                        pass
            sleeper.close()

        asyncio.run(go())


def test_family_solves_never_overlap_and_superseded_ones_stop(monkeypatch):
    import importlib

    fam = importlib.import_module("shapeflow.flow.family")

    real, running, peak, calls, finished = fam.family, [0], [0], [0], [0]
    lock = threading.Lock()

    def counting(*a, **kw):
        with lock:
            running[0] += 1
            calls[0] += 1
            peak[0] = max(peak[0], running[0])
        try:
            out = real(*a, **kw)
            finished[0] += 1
            return out
        finally:
            with lock:
                running[0] -= 1

    monkeypatch.setattr(fam, "family", counting)
    s = StudioSession(sf.load_example("spot"))
    lams = np.linspace(0.0, -240.0, 40)
    for k in range(6):
        s.solve_family(lams * (1 + k / 10))
    st = s.wait_family(300)
    assert st.state == "done" and st.lams[0] == pytest.approx(-240.0 * 1.5)
    assert peak[0] == 1                          # one solve at a time
    assert finished[0] < 6                       # superseded ones stopped, their results dropped
    np.testing.assert_allclose(s.shape_at(-240.0 * 1.5), real(s.base, [-240.0 * 1.5])[0], atol=1e-6)


def test_upload_reading_is_bounded_in_time_and_memory(tmp_path):
    path = tmp_path / "big.obj"
    n = 60_000
    rows = "\n".join(f"v {i} {i % 7} {i % 11}" for i in range(n))
    faces = "\n".join(f"f {i + 1} {i + 2} {i + 3}" for i in range(n - 2))
    path.write_text(rows + "\n" + faces + "\n")
    with pytest.raises(MeshError, match=r"^big.obj: reading it took longer than the studio allows \(0 s\)$"):
        read_upload(str(path), "big.obj", seconds=0.01)
    with pytest.raises(MeshError, match=r"^big.obj: reading it needs more memory than the studio allows"):
        read_upload(str(path), "big.obj", memory=1 << 20)
    mesh = read_upload(str(path), "big.obj")
    assert mesh.n_vertices == n and mesh.n_faces == n - 2


def test_upload_errors_never_name_a_temporary_path(server):
    import urllib.error
    import urllib.request

    for name, body in (("bad.obj", b"f 1 2 3\n"), ("bad.ply", b"ply\nformat ascii 1.0\nelement vertex 99\n"),
                       ("bad.stl", b"solid x\nfacet normal 0 0 1\n")):
        req = urllib.request.Request(server.link("open", name=name), data=body)
        with pytest.raises(urllib.error.HTTPError) as exc:
            urllib.request.urlopen(req, timeout=60)
        text = exc.value.read().decode()
        assert exc.value.code == 400 and text.startswith(name), text
        assert tempfile.gettempdir() not in text and "shapeflow-studio-" not in text and "/" not in text


def soup_stl() -> bytes:
    """A binary STL of a unit cube: 12 triangles, 36 corners, each a vertex of its own."""
    import struct

    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
    F = [(0, 2, 1), (0, 3, 2), (4, 5, 6), (4, 6, 7), (0, 1, 5), (0, 5, 4), (1, 2, 6), (1, 6, 5), (2, 3, 7),
         (2, 7, 6), (3, 0, 4), (3, 4, 7)]
    out = bytearray(b"\0" * 80 + struct.pack("<I", len(F)))
    for f in F:
        out += struct.pack("<3f", 0, 0, 0) + b"".join(struct.pack("<3f", *V[i]) for i in f) + b"\0\0"
    return bytes(out)


def test_the_studio_welds_an_stl_soup_edits_it_and_saves_its_own_layout(tmp_path):
    import urllib.request

    with StudioServer(sf.load_example("spot"), solve=False) as srv:
        r = urllib.request.urlopen(urllib.request.Request(srv.link("open", name="cube.stl"), data=soup_stl()))
        assert json.loads(r.read()) == {"n_vertices": 8, "n_faces": 12, "welded": True}
        s = srv.session
        assert s.welded and s.vertices.shape == (8, 3) and s.n_input_vertices == 36
        moved = s.dab([1.0, 1.0, 1.0], radius=0.6, inflate=True)
        assert moved.size
        body = urllib.request.urlopen(srv.link("download/cube.stl")).read()
        path = tmp_path / "cube.stl"
        path.write_bytes(body)
        from stl import mesh as npstl  # numpy-stl: an independent reader

        tri = npstl.Mesh.from_file(str(path)).vectors.reshape(-1, 3)
        assert tri.shape == (36, 3)                         # the soup's own layout: 36 corners
        want = s.vertices.astype(np.float32)
        # every corner sits on one of the 8 edited vertices, and every edited vertex is used
        d = np.linalg.norm(tri[:, None, :] - want[None, :, :], axis=2)
        assert np.all(d.min(axis=1) < 1e-6) and set(np.argmin(d, axis=1)) == set(range(8))
        assert np.abs(want - s.input_vertices).max() > 1e-3          # and the dab moved some of them


def test_weights_of_the_file_as_opened_map_onto_the_welded_vertices(tmp_path):
    soup = tmp_path / "cube.stl"
    soup.write_bytes(soup_stl())
    s = StudioSession(sf.load(str(soup)))
    w = np.linspace(0.0, 1.0, 36)
    s.set_weights(w)
    first = np.unique(s.base.weld_map, return_index=True)[1]
    np.testing.assert_array_equal(s.weights, w[first])
    np.testing.assert_array_equal(s.mesh.weights, w[first][s.base.weld_map])
    os.remove(soup)


def test_half_sent_requests_are_closed_and_connections_capped(monkeypatch):
    """Slowloris: connections that send part of a request and stop are closed after the keepalive
    time, past the cap at once, and the user's own requests are answered meanwhile."""
    import socket
    import urllib.request

    import shapeflow.studio.run as run

    monkeypatch.setattr(run, "connection_cap", lambda: 8)
    with StudioServer(sf.load_example("spot"), solve=False, keepalive=1.0) as srv:
        host, port = srv.address.split("/")[2].split(":")
        socks = []
        for _ in range(20):
            s = socket.create_connection((host, int(port)))
            s.sendall(b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: ")       # and nothing more
            s.settimeout(30)
            socks.append(s)
        closed = 0
        for s in socks:                       # each is closed by the server: recv sees the end
            try:
                closed += s.recv(1) in (b"",)
            except ConnectionResetError:
                closed += 1
            s.close()
        assert closed == 20
        assert urllib.request.urlopen(srv.url, timeout=30).status == 200


def test_opening_a_file_stops_the_replaced_sessions_family_solve(tmp_path):
    import urllib.request

    from meshgen import cube_sphere

    with StudioServer(cube_sphere(60), lams=list(np.linspace(0.0, -240.0, 60))) as srv:
        old = srv.session
        urllib.request.urlopen(urllib.request.Request(srv.link("open", name="t.obj"),
                                                      data=b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"), timeout=120)
        assert srv.session is not old
        st = old.wait_family(120)
        assert st.state in ("stopped", "done", "none")            # ended: no thread left solving it
        assert not any(t.is_alive() for t in [old._thread] if t is not None)


def test_ending_the_studio_kills_a_reader_under_way(tmp_path):
    """A file being read for a page when the studio ends: its reader is killed, not waited for."""
    from shapeflow.studio.upload import readers_under_way, stop_readers

    fifo = tmp_path / "slow.obj"
    os.mkfifo(fifo)                                    # the reader blocks on it until killed
    out = []
    t = threading.Thread(target=lambda: out.append(_read_or_error(str(fifo))), daemon=True)
    t.start()
    import time as _t

    for _ in range(600):                               # until its child is under way
        if readers_under_way():
            break
        _t.sleep(0.05)
    stop_readers()
    t.join(60)
    assert not t.is_alive() and out and out[0].startswith("slow.obj: the reader failed on this file (signal 9)")


def _read_or_error(path):
    try:
        read_upload(path, "slow.obj", seconds=600)
        return "read"
    except MeshError as exc:
        return str(exc)


@pytest.mark.parametrize("ext", [".usda", ".usdc"])
def test_usd_uploads_are_read(tmp_path, ext):
    pytest.importorskip("pxr", reason="usd-core (the 'usd' extra) is not installed")
    path = tmp_path / ("spot" + ext)
    sf.save(path, sf.load_example("spot"))
    mesh = read_upload(str(path), path.name)
    np.testing.assert_allclose(mesh.vertices, sf.load_example("spot").vertices, atol=1e-6)


@pytest.mark.parametrize("name,body,words", [
    ("points.ply", b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                   b"end_header\n0 0 0\n1 0 0\n0 1 0\n",
     "points.ply: the mesh has no faces (3 points): the studio edits surfaces"),
    ("points.obj", b"v 0 0 0\nv 1 0 0\n", "has no faces"),
])
def test_a_file_without_faces_is_refused_and_nothing_changes(server, name, body, words):
    import urllib.error
    import urllib.request

    s, v = server.session, server.session.version
    with pytest.raises(urllib.error.HTTPError) as exc:
        urllib.request.urlopen(urllib.request.Request(server.link("open", name=name), data=body), timeout=60)
    text = exc.value.read().decode()
    assert exc.value.code == 400 and words in text and text.startswith(name), text
    assert server.session is s and s.version == v


def test_a_full_temporary_folder_is_one_line(server, tmp_path, monkeypatch):
    import urllib.error
    import urllib.request

    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setattr(tempfile, "tempdir", str(blocker / "tmp"))     # no temporary folder can be made
    for url, data in ((server.link("open", name="t.obj"), b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"),
                      (server.link("download/x.ply"), None), (server.link("download/x.usdc"), None)):
        with pytest.raises(urllib.error.HTTPError) as exc:
            urllib.request.urlopen(urllib.request.Request(url, data=data), timeout=60)
        text = exc.value.read().decode()
        assert exc.value.code == 507 and "temporary folder cannot hold it" in text and "\n" not in text.strip()
        assert str(tmp_path) not in text


def test_a_port_in_use_is_one_line_and_leaves_nothing_running():
    import socket
    import subprocess
    import sys

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        p = subprocess.run([sys.executable, "-m", "shapeflow", "studio", "--no-browser", "--port", str(port),
                            "example:spot"], capture_output=True, text=True, timeout=120)
    assert p.returncode == 2
    assert p.stderr.splitlines() == [f"shapeflow studio: error: the studio cannot listen on 127.0.0.1:{port} "
                                     "(Address already in use)"], p.stderr
