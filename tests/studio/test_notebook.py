"""``sf.studio(mesh)`` in a notebook: executed headless by nbclient in a real kernel, its output (an
iframe of the studio with its token) shown in a page of another site in Chromium — where the
page gets no SameSite=Strict cookie, so its scripts load with the token in their addresses — and
the mesh edited there comes back to Python with ``server.result()``."""

from __future__ import annotations

import functools
import http.server
import json
import threading

import numpy as np
import pytest
from conftest import need

need("aiohttp", "aiohttp (the 'studio' extra)")
need("selenium.webdriver", "selenium (a test dependency)")
nbformat = need("nbformat", "nbformat (a test dependency)")
nbclient = need("nbclient", "nbclient (a test dependency)")
need("ipykernel", "ipykernel (a test dependency)")
from browser import CHROMIUM, DRIVER, chromium_page, wait  # noqa: E402
from selenium.webdriver.common.action_chains import ActionChains  # noqa: E402

from shapeflow.studio.headless import READY, set_control  # noqa: E402

pytestmark = pytest.mark.skipif(not (CHROMIUM and DRIVER), reason="chromium and chromedriver are not installed")

CELLS = [
    "import numpy as np\nimport shapeflow as sf\nserver = sf.studio(sf.load_example('spot'))\nserver",
    "edited = server.result()\n"
    "print(json.dumps([edited.n_vertices, np.asarray(edited.vertices, np.float32).tolist()]))",
    "server.stop()",
]


@pytest.fixture
def site(tmp_path):
    """A web server of another site (localhost, where the studio is 127.0.0.1) serving ``tmp_path``."""
    handler = functools.partial(http.server.SimpleHTTPRequestHandler, directory=str(tmp_path))
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    yield f"http://localhost:{httpd.server_address[1]}/"
    httpd.shutdown()
    httpd.server_close()


def test_a_notebook_shows_the_studio_inline_and_gets_the_edited_mesh_back(tmp_path, site, monkeypatch):
    for var in ("JUPYTER_RUNTIME_DIR", "JUPYTER_DATA_DIR", "IPYTHONDIR"):
        monkeypatch.setenv(var, str(tmp_path / var.lower()))
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell("import json")]
                                  + [nbformat.v4.new_code_cell(c) for c in CELLS])
    client = nbclient.NotebookClient(nb, kernel_name="python3", timeout=300)
    with client.setup_kernel():
        client.execute_cell(nb.cells[0], 0)
        client.execute_cell(nb.cells[1], 1)
        out = nb.cells[1].outputs[-1]["data"]
        iframe = out["text/html"]
        assert iframe.startswith('<iframe src="http://127.0.0.1:') and "token=" in iframe
        (tmp_path / "notebook.html").write_text(f"<!doctype html><title>a notebook</title>{iframe}")
        with chromium_page(site + "notebook.html", size=(1280, 900), ready=None) as d:
            d.switch_to.frame(d.find_element("tag name", "iframe"))
            wait(d, READY, 120)
            # the page of another site's frame has no cookie: its scripts came with the token in their URLs
            scripts = d.execute_script("return performance.getEntriesByType('resource').map(e => e.name)"
                                       ".filter(n => n.includes('/static/'))")
            assert len(scripts) >= 8 and all("token=" in u for u in scripts)
            plain = d.execute_async_script("fetch('/static/app.js', {credentials: 'include'})"
                                           ".then(r => arguments[0](r.status))")
            assert plain == 403
            set_control(d, "mode", "sculpt")                                   # a stroke in the notebook
            canvas = d.find_element("css selector", "#view canvas")
            chain = ActionChains(d).move_to_element_with_offset(canvas, -30, 20).click_and_hold()
            for dx in range(-20, 31, 10):
                chain = chain.move_to_element_with_offset(canvas, dx, 20).pause(0.1)
            chain.release().perform()
            wait(d, "return window.studio.pending === 0 && !window.studio.stroking && window.studio.modified")
            shown = np.array(d.execute_script("return window.studio.positions()"), np.float32).reshape(-1, 3)
        client.execute_cell(nb.cells[2], 2)
        n, vertices = json.loads(nb.cells[2].outputs[-1]["text"])
        back = np.array(vertices, np.float32)
        import shapeflow as sf

        start = sf.load_example("spot").vertices.astype(np.float32)
        assert n == len(start) and np.abs(back - start).max() > 1e-3          # the stroke came back to Python
        np.testing.assert_array_equal(back, shown)                           # what the page showed
        client.execute_cell(nb.cells[3], 3)
