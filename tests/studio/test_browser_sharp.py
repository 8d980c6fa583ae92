""""Keep sharp edges" in headless Chromium: clicking the toggle sets the session's setting, draws
the box's sharp edges as lines (the scene's line count and the pixels of their colour), which follow
the slider's shape and go away with the toggle; the angle typed in the panel reaches the session,
a refused one shows the error and puts the field back; toggling is no edit; a file that marks edges
offers them."""

from __future__ import annotations

import os

import numpy as np
import pytest
from conftest import need

need("aiohttp", "aiohttp (the 'studio' extra)")
need("selenium.webdriver", "selenium (a test dependency)")
from browser import CHROMIUM, DRIVER, chromium_page, idle, pixels, shown, type_into, wait  # noqa: E402
from test_session_sharp import HALF, K, box_parts, flatness, obj_with_groups  # noqa: E402

from shapeflow.studio.headless import set_control  # noqa: E402

pytestmark = pytest.mark.skipif(not (CHROMIUM and DRIVER), reason="chromium and chromedriver are not installed")
#: the lines' colour (0xff40c0; unlit, so drawn as it is)
LINE = np.array([255, 64, 192])


@pytest.fixture(scope="module")
def server():
    from shapeflow.studio import StudioServer

    box, _ = box_parts()         # rotated off the axes: the front view shows three of its sides
    with StudioServer(box, lams=[0.0, -60.0, -120.0], name="box") as srv:
        yield srv


@pytest.fixture(scope="module")
def page(server):
    with chromium_page(server.url, size=(1280, 800)) as d:
        yield d


def line_pixels(d, name=None) -> int:
    """Pixels of the lines' colour in the view (right of the panel)."""
    png = d.get_screenshot_as_png()
    if name and os.environ.get("SHAPEFLOW_TEST_SHOTS"):      # to look at them: SHAPEFLOW_TEST_SHOTS=DIR
        with open(os.path.join(os.environ["SHAPEFLOW_TEST_SHOTS"], name), "wb") as f:
            f.write(png)
    px = pixels(d)[:, 272:]
    return int((np.abs(px - LINE).max(axis=2) < 40).sum())


def test_the_toggle_draws_the_sharp_edges_and_sets_the_session(page, server):
    s = server.session
    idle(page, server)
    assert page.execute_script("return window.studio.sharpLines()") == 0
    assert line_pixels(page, "sharp-off.png") == 0
    assert not page.find_element("id", "sharp").is_selected()
    undo_disabled = page.find_element("id", "undo").get_attribute("disabled")
    version = s.version

    page.find_element("id", "sharp").click()
    wait(page, f"return window.studio.sharpLines() === {12 * K} && window.studio.pending === 0")
    assert s.features == {"on": True, "angle": 30.0, "marked": False}
    assert page.execute_script("return window.studio.sharp.count") == len(s.sharp_edges()) == 12 * K
    idle(page, server)
    drawn = line_pixels(page, "sharp-on.png")
    assert drawn > 600, drawn          # 12 edges of 1 to 3.1 units, seen from the front: about 1,500 pixels
    assert s.version == version and page.find_element("id", "undo").get_attribute("disabled") == undo_disabled

    # the slider's shape: the family solved with the sharp edges, the lines on it
    set_control(page, "lam", -120, event="input")
    idle(page, server)
    diag = float(np.linalg.norm(2 * HALF))
    _, sides = box_parts()
    assert np.allclose(shown(page), s.shape_at(-120.0), atol=1e-5 * diag)
    assert flatness(s.shape_at(-120.0), sides) <= 1e-9 * diag
    assert line_pixels(page, "sharp-lam.png") > 600

    # the angle: typed, it reaches the session; 95° is more than the box bends: no line
    type_into(page, "sharp-angle", "95", enter=True)
    wait(page, "return window.studio.sharp.angle === 95 && window.studio.pending === 0")
    assert s.features["angle"] == 95.0 and page.execute_script("return window.studio.sharpLines()") == 0
    # refused: the error in view, the session and the field keep 95
    type_into(page, "sharp-angle", "200", enter=True)
    wait(page, "return window.studio.error !== null && window.studio.pending === 0")
    assert "angle" in page.find_element("id", "error").text and s.features["angle"] == 95.0
    wait(page, "return document.getElementById('sharp-angle').value === '95'")
    type_into(page, "sharp-angle", "30", enter=True)
    wait(page, f"return window.studio.sharpLines() === {12 * K} && window.studio.pending === 0")

    page.find_element("id", "sharp").click()           # off: no line, the session's setting off
    wait(page, "return window.studio.sharpLines() === 0 && window.studio.pending === 0")
    assert s.features["on"] is False
    idle(page, server)
    assert line_pixels(page) == 0
    assert s.version == version


def test_a_file_that_marks_edges_offers_them_in_the_panel(page, tmp_path):
    """The box as an OBJ with a smoothing group a side: the panel offers its 72 marked edges (the plain
    box did not), and ticking them at 180° (no edge by angle) keeps and draws exactly those."""
    import shapeflow as sf
    from shapeflow.studio import StudioServer

    assert not page.find_element("id", "sharp-marked-row").is_displayed()       # the plain box marks none
    box, sides = box_parts()
    mesh = sf.load(obj_with_groups(box, sides, tmp_path / "groups.obj"))
    with StudioServer(mesh, lams=[0.0, -120.0], name="groups.obj") as server, \
            chromium_page(server.url, size=(1280, 800)) as d:
        row = d.find_element("id", "sharp-marked-row")
        assert row.is_displayed() and f"({12 * K})" in row.text and "marked edges" in row.text
        type_into(d, "sharp-angle", "180", enter=True)
        wait(d, "return window.studio.sharp.angle === 180 && window.studio.pending === 0")
        d.find_element("id", "sharp-marked").click()
        d.find_element("id", "sharp").click()
        wait(d, f"return window.studio.sharpLines() === {12 * K} && window.studio.pending === 0")
        assert server.session.features == {"on": True, "angle": 180.0, "marked": True}
        idle(d, server)
        assert line_pixels(d, "sharp-marked.png") > 600
        last = d.execute_script("const r = document.getElementById('download').getBoundingClientRect();"
                                "return [r.bottom, document.getElementById('panel').scrollHeight]")
        assert last[0] <= 800 and last[1] <= 800                # the panel still fits 1280×800
