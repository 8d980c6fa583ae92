"""Another web page in the same real browser (headless Chromium) cannot drive a running studio: not
from another site, not from another port of this machine (same site: the studio's cookie is sent),
not even knowing the token; the studio's own page, opened with its address, works."""

from __future__ import annotations

import http.server
import json
import threading

import pytest

import shapeflow as sf

pytest.importorskip("aiohttp", reason="aiohttp (the 'studio' extra) is not installed")
pytest.importorskip("selenium.webdriver", reason="selenium (a test dependency) is not installed")
from browser import CHROMIUM, DRIVER, chromium_page, wait  # noqa: E402

pytestmark = pytest.mark.skipif(not (CHROMIUM and DRIVER), reason="chromium and chromedriver are not installed")

ATTACK = """
const [studio, token, done] = [arguments[0], arguments[1], arguments[arguments.length - 1]];
const out = {};
const body = "v 0 0 0\\nv 1 0 0\\nv 0 1 0\\nf 1 2 3\\n";
const tryit = async (name, f) => { try { out[name] = await f(); } catch (e) { out[name] = "error: " + e.name; } };
(async () => {
  // a "simple" cross-origin POST: no preflight, the response is opaque, but it is sent
  await tryit("post_no_cors", async () => (await fetch(studio + "open?name=x.obj",
      { method: "POST", mode: "no-cors", body, headers: { "Content-Type": "text/plain" } })).type);
  await tryit("post_no_cors_token", async () => (await fetch(studio + "open?name=x.obj&token=" + token,
      { method: "POST", mode: "no-cors", body, credentials: "include" })).type);
  await tryit("read_download", async () => (await fetch(studio + "download/x.ply?token=" + token,
      { credentials: "include" })).status);
  await tryit("read_page", async () => (await fetch(studio, { credentials: "include" })).status);
  for (const [name, url] of [["ws", studio.replace("http", "ws") + "ws"],
                             ["ws_token", studio.replace("http", "ws") + "ws?token=" + token]]) {
    out[name] = await new Promise((resolve) => {
      const ws = new WebSocket(url);
      ws.onmessage = () => { resolve("message"); ws.close(); };
      ws.onerror = () => resolve("error");
      ws.onclose = () => resolve("closed");
      ws.onopen = () => ws.send(JSON.stringify({ op: "undo" }));
    });
  }
  // a form posted into a hidden frame: the classic CSRF
  const f = document.createElement("form");
  f.method = "POST"; f.action = studio + "open?name=y.obj&token=" + token; f.enctype = "text/plain"; f.target = "sink";
  const i = document.createElement("input"); i.name = "v 0 0 0\\nv 1 0 0\\nv 0 1 0\\nf 1 2 3\\n#"; i.value = "";
  f.appendChild(i);
  const frame = document.createElement("iframe"); frame.name = "sink"; document.body.appendChild(frame);
  document.body.appendChild(f);
  await new Promise((resolve) => { frame.onload = resolve; f.submit(); setTimeout(resolve, 5000); });
  done(out);
})();
"""


class _Evil(http.server.BaseHTTPRequestHandler):
    def do_GET(self):
        self.send_response(200)
        self.send_header("Content-Type", "text/html")
        self.end_headers()
        self.wfile.write(b"<!doctype html><title>another page</title><p>hello</p>")

    def log_message(self, *a):
        pass


def test_a_page_of_another_origin_cannot_drive_the_studio_even_knowing_the_token():
    from shapeflow.studio import StudioServer

    evil = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _Evil)
    threading.Thread(target=evil.serve_forever, daemon=True).start()
    try:
        with StudioServer(sf.load_example("spot"), lams=[0.0, -20.0]) as srv, chromium_page(srv.url) as page:
            s = srv.session
            before = (s.n_input_vertices, s.version)
            assert page.get_cookie(f"shapeflow-studio-{srv.port}") is not None   # the studio's page has its cookie
            page.get(f"http://127.0.0.1:{evil.server_address[1]}/")              # same site, another origin
            page.set_script_timeout(60)
            out = page.execute_async_script(ATTACK, srv.address, srv.token)
            assert out["read_download"].startswith("error") and out["read_page"].startswith("error"), out
            assert out["ws"] in ("error", "closed") and out["ws_token"] in ("error", "closed"), out
            assert srv.session is s and (s.n_input_vertices, s.version) == before and not s.can_undo
            page.get(srv.url)                                                     # the studio's own page works
            wait(page, "return window.studio && window.studio.ready")
            c = json.dumps(s.vertices[100].tolist())
            page.execute_script(f"window.studio.send({{op: 'dab', center: {c}, radius: 0.2, lam: -60}});")
            wait(page, f"return window.studio.pending === 0 && window.studio.version > {before[1]}")
            assert s.version > before[1] and s.can_undo and page.execute_script("return window.studio.error") is None
    finally:
        evil.shutdown()
