"""The studio driven in a real headless Chromium (Debian's chromium and chromium-driver, WebGL on
SwiftShader): the page shows what the server's session holds after each step, and the pixels
change where a stroke went and nowhere far from it."""

from __future__ import annotations

import json
import urllib.error
import urllib.request

import numpy as np
import pytest
from conftest import need

import shapeflow as sf

need("aiohttp", "aiohttp (the 'studio' extra)")
need("selenium.webdriver", "selenium (a test dependency)")
from browser import CHROMIUM, DRIVER, canvas_box, chromium_page, pixels, settled, shown, wait  # noqa: E402

from shapeflow.studio.headless import set_control  # noqa: E402

pytestmark = pytest.mark.skipif(not (CHROMIUM and DRIVER), reason="chromium and chromedriver are not installed")


@pytest.fixture(scope="module")
def server():
    from shapeflow.studio import StudioServer

    with StudioServer(sf.load_example("spot"), lams=[0.0, -20.0, -40.0, -60.0, -80.0]) as srv:
        yield srv


@pytest.fixture(scope="module")
def page(server):
    with chromium_page(server.url) as d:
        yield d


def test_the_slider_shows_the_family(page, server):
    before = shown(page)
    np.testing.assert_array_equal(before, server.session.vertices.astype(np.float32))
    set_control(page, "lam", -50, event="input")
    wait(page, "return window.studio.pending === 0")
    np.testing.assert_array_equal(shown(page), server.session.shape_at(-50.0).astype(np.float32))
    assert not np.array_equal(shown(page), before)
    set_control(page, "lam", 0, event="input")
    wait(page, "return window.studio.pending === 0")
    np.testing.assert_array_equal(shown(page), before)


def test_a_paint_stroke_changes_the_weights_and_only_the_pixels_near_it(page, server):
    from selenium.webdriver.common.action_chains import ActionChains

    settled(page, server)
    page.execute_script("document.getElementById('mode').value = 'erase';")
    left, top, width, height = canvas_box(page)
    img0 = pixels(page)
    version = server.session.version
    canvas = page.find_element("css selector", "#view canvas")
    chain = ActionChains(page).move_to_element_with_offset(canvas, -40, 0).click_and_hold()
    for dx in range(-30, 41, 10):
        chain = chain.move_to_element_with_offset(canvas, dx, 0).pause(0.1)
    chain.release().perform()
    wait(page, f"return window.studio.version > {version}")
    settled(page, server)
    w = server.session.weights
    assert (w < 1.0).sum() > 5 and w.min() < 0.9
    np.testing.assert_array_equal(np.array(page.execute_script("return window.studio.weightList()"), np.float32),
                                  w.astype(np.float32))
    img1 = pixels(page)
    cx, cy = left + width // 2, top + height // 2
    near = np.abs(img1[cy - 40:cy + 40, cx - 80:cx + 80] - img0[cy - 40:cy + 40, cx - 80:cx + 80]).sum(axis=2) > 30
    far = np.abs(img1[top + 5:top + 60, left + width - 120:left + width - 5]
                 - img0[top + 5:top + 60, left + width - 120:left + width - 5]).sum(axis=2) > 30
    assert near.sum() > 200 and far.sum() == 0

    while server.session.can_undo:              # the stroke was several paint steps: undo them all
        page.find_element("id", "undo").click()
        settled(page, server)
    assert np.array_equal(server.session.weights, np.ones(server.session.mesh.n_vertices))
    page.execute_script("document.getElementById('mode').value = 'view';")


def test_a_dab_a_second_tab_and_the_download(page, server):
    settled(page, server)
    c = server.session.vertices[100].tolist()
    page.execute_script(f"window.studio.send({{op: 'dab', center: {json.dumps(c)}, radius: 0.2, lam: -60}});")
    settled(page, server)
    moved = server.session.vertices
    np.testing.assert_array_equal(shown(page), moved.astype(np.float32))
    assert not np.array_equal(moved, sf.load_example("spot").vertices)
    first = page.current_window_handle
    page.switch_to.new_window("tab")                 # a second tab sees the same session
    page.get(server.url)
    wait(page, "return window.studio && window.studio.ready")
    np.testing.assert_array_equal(shown(page), moved.astype(np.float32))
    page.close()
    page.switch_to.window(first)
    body = urllib.request.urlopen(server.link("download/result.ply")).read()
    path = f"{pytest.importorskip('tempfile').mkdtemp()}/result.ply"
    with open(path, "wb") as f:
        f.write(body)
    back = sf.load(path)
    np.testing.assert_array_equal(back.vertices, moved)
    assert back.weights is None and (server.session.weights == 1.0).all()   # nothing painted: none written


def test_the_server_is_local_and_serves_only_its_own_files(server):
    assert server.url.startswith("http://127.0.0.1:")
    for bad in ("static/../server.py", "static/%2e%2e/server.py", "download/x.exe"):
        with pytest.raises(urllib.error.HTTPError) as exc:
            urllib.request.urlopen(server.link(bad))
        assert exc.value.code in (400, 403, 404)


def test_colour_fields_and_the_brush_circle(page, server):
    from selenium.webdriver.common.action_chains import ActionChains

    settled(page, server)
    set_control(page, "colours", "curvature")
    wait(page, "return window.studio.field && window.studio.field.name === 'curvature' && window.studio.pending === 0")
    values = np.array(page.execute_script("return Array.from(window.studio.field.values)"), np.float32)
    np.testing.assert_array_equal(values, server.session.field("curvature").astype(np.float32))
    assert page.execute_script("return document.getElementById('legend').style.visibility") == "visible"
    ref = sf.mean_curvature(server.session.mesh, area="barycentric")     # the library's own curvature
    np.testing.assert_allclose(values, ref, rtol=1e-6, atol=1e-6 * np.abs(ref).max())
    page.execute_script("document.getElementById('mode').value = 'sculpt';")
    canvas = page.find_element("css selector", "#view canvas")
    ActionChains(page).move_to_element_with_offset(canvas, 5, 5).move_to_element_with_offset(canvas, 0, 0).perform()
    wait(page, "return window.studio.ring && window.studio.ring.visible")
    center = np.array(page.execute_script("return window.studio.ring.center"))
    V = server.session.vertices
    assert np.linalg.norm(V - center, axis=1).min() < 0.05 * np.linalg.norm(np.ptp(V, axis=0))   # on the surface
    page.execute_script("document.getElementById('mode').value = 'view';")
    set_control(page, "colours", "weights")
