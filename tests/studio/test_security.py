"""Who can reach a running studio: a real server on loopback, requests forged as another web page,
a DNS-rebinding page, a script without the token or another network peer would send them."""

from __future__ import annotations

import asyncio
import os
import signal
import subprocess
import sys
import time
import urllib.error
import urllib.request

import pytest

import shapeflow as sf

pytest.importorskip("aiohttp", reason="aiohttp (the 'studio' extra) is not installed")

from shapeflow.studio import StudioServer  # noqa: E402
from shapeflow.studio.security import Guard, check_name, content_disposition  # noqa: E402

OBJ = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"


@pytest.fixture(scope="module")
def server():
    with StudioServer(sf.load_example("spot"), solve=False) as srv:
        yield srv


def request(url, *, headers=None, data=None, method=None):
    """(status, body, headers) of one request, errors included."""
    req = urllib.request.Request(url, headers=headers or {}, data=data, method=method)
    try:
        with urllib.request.urlopen(req, timeout=30) as r:
            return r.status, r.read(), r.headers
    except urllib.error.HTTPError as e:
        return e.code, e.read(), e.headers


def untouched(server, before):
    s = server.session
    return s.n_input_vertices == before[0] and s.version == before[1] and not s.can_undo


def state(server):
    return server.session.n_input_vertices, server.session.version


def test_the_address_carries_a_fresh_token_per_start(server):
    assert server.url == f"{server.address}?token={server.token}"
    assert len(server.token) >= 40
    with StudioServer(sf.load_example("spot"), solve=False) as other:
        assert other.token != server.token


@pytest.mark.parametrize("path", ["", "static/app.js", "static/vendor/three/three.module.js",
                                  "download/shape.ply"])
def test_every_route_needs_the_token(server, path):
    assert request(server.address + path)[0] == 403
    assert request(server.address + path + "?token=" + "x" * 43)[0] == 403
    assert request(server.address + path, headers={"X-Shapeflow-Token": server.token[:-1]})[0] == 403
    assert request(server.link(path))[0] == 200                                   # the query parameter
    assert request(server.address + path, headers={"X-Shapeflow-Token": server.token})[0] == 200
    # the page's cookie opens the page and its scripts, nothing else; the token in a cookie is no key
    page_cookie = f"shapeflow-studio-{server.port}={page_cookie_of(server)}"
    assert request(server.address + path, headers={"Cookie": page_cookie})[0] == (403 if "download" in path else 200)
    token_cookie = f"shapeflow-studio-{server.port}={server.token}"
    assert request(server.address + path, headers={"Cookie": token_cookie})[0] == 403


def page_cookie_of(server) -> str:
    status, _, headers = request(server.url)
    assert status == 200
    return headers["Set-Cookie"].split(";")[0].split("=", 1)[1]


def test_opening_the_page_sets_a_strict_cookie_only_with_the_token(server):
    status, _, headers = request(server.url)
    assert status == 200
    cookie = headers["Set-Cookie"]
    assert cookie.startswith(f"shapeflow-studio-{server.port}=")
    assert "HttpOnly" in cookie and "SameSite=Strict" in cookie
    # browsers send a cookie to every port of its host: its value is not the token
    value = cookie.split(";")[0].split("=", 1)[1]
    assert len(value) >= 40 and value != server.token and server.token not in cookie
    assert headers["X-Content-Type-Options"] == "nosniff"
    assert request(server.address)[2].get("Set-Cookie") is None


def test_posts_need_the_token_itself_not_the_cookie(server):
    before = state(server)
    cookie = {"Cookie": f"shapeflow-studio-{server.port}={page_cookie_of(server)}"}
    for url, headers in ((server.address + "open?name=t.obj", {}),
                         (server.address + "open?name=t.obj", cookie),
                         (server.address + "weights?name=w.txt", cookie)):
        status, body, _ = request(url, headers=headers, data=OBJ)
        assert status == 403 and b"token" in body
    assert untouched(server, before)


@pytest.mark.parametrize("host", ["evil.example:{port}", "evil.example", "127.0.0.1:1", "localhost.evil.example:{port}",
                                  "10.0.0.1:{port}", "[::2]:{port}", "127.0.0.1:{port}@evil", ""])
def test_dns_rebinding_a_foreign_host_is_refused(server, host):
    status, body, _ = request(server.link(""), headers={"Host": host.format(port=server.port)})
    assert status in (400, 403)
    assert server.token.encode() not in body


@pytest.mark.parametrize("host", ["127.0.0.1:{port}", "localhost:{port}", "LOCALHOST:{port}"])
def test_the_loopback_names_are_accepted(server, host):
    assert request(server.link(""), headers={"Host": host.format(port=server.port)})[0] == 200


@pytest.mark.parametrize("origin", ["http://evil.example", "null", "http://127.0.0.1:1", "https://127.0.0.1:{port}",
                                    "http://localhost.evil.example:{port}"])
def test_a_foreign_origin_is_refused_even_with_the_token(server, origin):
    before = state(server)
    o = origin.format(port=server.port)
    assert request(server.link(""), headers={"Origin": o})[0] == 403
    # a cross-origin "simple" POST: text/plain, no preflight
    status, _, _ = request(server.link("open", name="t.obj"), data=OBJ,
                           headers={"Origin": o, "Content-Type": "text/plain"})
    assert status == 403
    assert untouched(server, before)


def test_requests_marked_cross_site_cannot_change_anything(server):
    before = state(server)
    for site in ("cross-site", "same-site"):
        status, _, _ = request(server.link("open", name="t.obj"), data=OBJ, headers={"Sec-Fetch-Site": site})
        assert status == 403
    assert untouched(server, before)


def test_the_own_origin_may_post(tmp_path):
    with StudioServer(sf.load_example("spot"), solve=False) as srv:
        status, body, _ = request(srv.link("open", name="t.obj"), data=OBJ,
                                  headers={"Origin": f"http://127.0.0.1:{srv.port}", "Sec-Fetch-Site": "same-origin"})
        assert status == 200, body
        assert srv.session.n_input_vertices == 3


def ws_attempt(url, headers=None):
    """Connect a WebSocket: the first message's type, or the HTTP status that refused the upgrade."""
    import aiohttp

    async def go():
        async with aiohttp.ClientSession() as cs:
            try:
                async with cs.ws_connect(url, headers=headers or {}) as ws:
                    msg = await ws.receive(timeout=30)
                    return "open", msg.json()["type"] if msg.type == aiohttp.WSMsgType.TEXT else msg.type
            except aiohttp.WSServerHandshakeError as exc:
                return "refused", exc.status

    return asyncio.run(go())


def test_the_websocket_checks_token_origin_and_host(server):
    ws = server.address.replace("http", "ws") + "ws"
    cookie = {"Cookie": f"shapeflow-studio-{server.port}={page_cookie_of(server)}"}
    assert ws_attempt(ws) == ("refused", 403)
    assert ws_attempt(ws, cookie) == ("refused", 403)                        # a cookie alone never edits
    assert ws_attempt(ws + f"?token={server.token}") == ("open", "mesh")
    assert ws_attempt(ws, {"X-Shapeflow-Token": server.token}) == ("open", "mesh")
    assert ws_attempt(ws + f"?token={server.token}", {"Origin": "http://evil.example"}) == ("refused", 403)
    assert ws_attempt(ws + f"?token={server.token}", {"Host": f"evil.example:{server.port}"})[0] == "refused"
    assert ws_attempt(ws + f"?token={server.token}",
                      {"Origin": f"http://127.0.0.1:{server.port}"}) == ("open", "mesh")


@pytest.mark.parametrize("name", ["a\0.obj", "a\r\nSet-Cookie: x=1.obj", 'a".obj', "a\\b.obj", "../a.obj",
                                  "x" * 300 + ".obj", "a\x85.obj", "a\u202egpj.obj", "a\u2028.obj", "a<b>.obj",
                                  "a:b.obj", "a|b?.obj", "a*.obj", "\ue000.obj"])
def test_names_with_control_characters_quotes_or_paths_are_refused(server, name):
    before = state(server)
    assert request(server.link("open", name=name), data=OBJ)[0] == 400
    assert request(server.link("download/" + name.replace(".obj", ".ply")))[0] in (400, 404)
    assert untouched(server, before)


def test_download_names_are_encoded_as_rfc_6266_says(server):
    status, body, headers = request(server.link("download/tête de vache.ply"))
    assert status == 200 and body.startswith(b"ply")
    assert headers["Content-Disposition"] == \
        "attachment; filename=\"t_te de vache.ply\"; filename*=UTF-8''t%C3%AAte%20de%20vache.ply"
    assert content_disposition('a%b.obj') == "attachment; filename=\"a_b.obj\"; filename*=UTF-8''a%25b.obj"
    assert check_name("ok name.obj") is None and check_name("a\x7f.obj") is not None
    assert request(server.link("download/.scan.ply"))[0] == 200          # a name may start with a dot
    assert check_name(".scan.ply") is None and check_name("..") is not None and check_name(".") is not None


@pytest.mark.parametrize("host", ["127.0.0.1:{arabic}", "127.0.0.1.:{port}", "localhost.:{port}",
                                  "localhost..:{port}", "127.0.0.1:+{port}", "127.0.0.1: {port}"])
def test_hosts_are_read_strictly(server, host):
    import socket

    arabic = "".join(chr(0x660 + int(d)) for d in str(server.port))     # Arabic-Indic digits
    h, port = server.address.split("/")[2].split(":")
    with socket.create_connection((h, int(port))) as s:                 # raw: the header as UTF-8 bytes
        s.sendall(f"GET /?token={server.token} HTTP/1.1\r\nHost: {host.format(port=server.port, arabic=arabic)}"
                  "\r\nConnection: close\r\n\r\n".encode())
        answer = b""
        while chunk := s.recv(65536):
            answer += chunk
    assert answer.startswith((b"HTTP/1.1 400", b"HTTP/1.1 403")), answer[:80]


def test_an_absolute_request_target_is_refused(server):
    import socket

    host, port = server.address.split("/")[2].split(":")
    with socket.create_connection((host, int(port))) as s:
        s.sendall(f"GET http://evil.example/?token={server.token} HTTP/1.1\r\nHost: {host}:{port}\r\n"
                  "Connection: close\r\n\r\n".encode())
        answer = b""
        while chunk := s.recv(65536):
            answer += chunk
    assert answer.startswith(b"HTTP/1.1 400") and b"not absolute addresses" in answer


def test_the_guard_on_every_interface_takes_ip_literals_and_named_hosts_only():
    g = Guard("t" * 43, "0.0.0.0", 8765, allow_hosts=["box.lan"])
    assert g.host_ok("192.168.1.5:8765") and g.host_ok("[fe80::1]:8765") and g.host_ok("box.lan:8765")
    assert g.host_ok("localhost:8765")
    assert not g.host_ok("evil.example:8765") and not g.host_ok("192.168.1.5:8766")
    g = Guard("t" * 43, "192.168.1.5", 8765)
    assert g.host_ok("192.168.1.5:8765") and not g.host_ok("127.0.0.1:8765") and not g.host_ok("10.0.0.1:8765")


def studio_process(*args):
    """A ``shapeflow studio`` process and the address it printed."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    p = subprocess.Popen([sys.executable, "-m", "shapeflow", "studio", "--no-browser", "--port", "0", *args],
                         stderr=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env)
    lines = []
    t0 = time.monotonic()
    while time.monotonic() - t0 < 120:
        line = p.stderr.readline()
        if not line:
            break
        lines.append(line)
        if "(Ctrl-C ends it)" in line:
            return p, lines
    p.kill()
    raise AssertionError("the studio did not start: " + "".join(lines))


def test_a_network_address_keeps_the_token_and_says_so():
    p, lines = studio_process("example:spot", "--host", "0.0.0.0")
    try:
        url = lines[-1].split(" at ")[1].split(" ")[0]
        assert "?token=" in url
        warning = p.stderr.readline()
        assert warning.startswith("shapeflow studio: warning: listening on 0.0.0.0: anyone who can reach this machine "
                                  "and has the address above (its token) can edit")
        base = url.split("?")[0]
        assert request(base)[0] == 403 and request(url)[0] == 200
    finally:
        p.kill()
        p.wait()


def test_ctrl_c_ends_the_studio_at_once_even_with_a_tab_that_stopped_reading(tmp_path):
    import socket

    from meshgen import cube_sphere

    big = tmp_path / "big.ply"          # ~9 MB of frames for the new tab: more than the sockets' buffers
    sf.save(big, cube_sphere(150))
    p, lines = studio_process(str(big))
    try:
        url = lines[-1].split(" at ")[1].split(" ")[0]
        host_port = url.split("/")[2]
        token = url.split("token=")[1]
        s = socket.create_connection(tuple([host_port.split(":")[0], int(host_port.split(":")[1])]))
        s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        s.sendall((f"GET /ws?token={token} HTTP/1.1\r\nHost: {host_port}\r\nUpgrade: websocket\r\n"
                   "Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                   "Sec-WebSocket-Version: 13\r\n\r\n").encode())
        time.sleep(1.0)                                # the server is writing the mesh to a socket nobody reads
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=60)             # a hang fails here
        assert p.returncode == 130, err
        assert "Traceback" not in err
        s.close()
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
