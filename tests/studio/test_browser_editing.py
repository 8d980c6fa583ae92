"""Editing at any slider position, driven as a user would in headless Chromium (typed λ, pointer
strokes, Ctrl+Z): a sculpt stroke at a previewed λ first applies the preview (one undo step) and
acts on what is shown; painting at a previewed λ keeps the preview, which follows the new weights;
a stroke is one undo step; opening a file with unsaved changes asks first."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import need

import shapeflow as sf

need("aiohttp", "aiohttp (the 'studio' extra)")
need("selenium.webdriver", "selenium (a test dependency)")
from browser import (  # noqa: E402
    CHROMIUM,
    DRIVER,
    changed_pixels,
    confirm,
    idle,
    pixels,
    press,
    shown,
    spot_studio,
    stroke,
    type_into,
    wait,
)
from selenium.webdriver.common.keys import Keys  # noqa: E402

from shapeflow.geometry.normals import vertex_normals  # noqa: E402
from shapeflow.studio.headless import set_control  # noqa: E402

pytestmark = pytest.mark.skipif(not (CHROMIUM and DRIVER), reason="chromium and chromedriver are not installed")


server, page = spot_studio((1100, 760))


def type_lam(d, value):
    """Type λ into the number box and press Enter, then wait for the preview."""
    type_into(d, "lam-num", value, enter=True)
    wait(d, f"return window.studio.lam === {value} && window.studio.pending === 0 && window.studio.previewing")


def facing_path(d, V, k=9, height=0.0, span=0.2):
    """k points of the surface ``V`` across the model at ``height`` (from its centre, along its up axis),
    each the one nearest the camera in its slice: what a horizontal stroke over the view touches."""
    views = d.execute_script("return window.studio.views()")
    cam = np.array(d.execute_script("return window.studio.cameraPosition()"))
    right, up = np.cross(views["front"]["up"], views["front"]["dir"]), np.array(views["front"]["up"])
    c = 0.5 * (V.min(axis=0) + V.max(axis=0))
    pts = []
    for x in np.linspace(-span, span, k):
        q = V - c
        sl = np.flatnonzero((np.abs(q @ right - x) < 0.04) & (np.abs(q @ up - height) < 0.08))
        pts.append(V[sl[np.argmin(np.linalg.norm(V[sl] - cam, axis=1))]])
    return pts


def undo_to_start(d, server, start):
    while server.session.can_undo:
        press(d, Keys.CONTROL, "z")
        idle(d, server)
    assert np.array_equal(server.session.vertices, start) and np.all(server.session.weights == 1.0)
    if d.execute_script("return window.studio.lam") != 0:
        type_into(d, "lam-num", 0, enter=True)
        wait(d, "return window.studio.lam === 0 && window.studio.pending === 0")


def test_an_inflate_stroke_at_a_previewed_lambda_acts_on_what_is_shown(page, server):
    s = server.session
    start = s.vertices
    idle(page, server)
    type_lam(page, -120)
    preview = s.shape_at(-120.0)
    np.testing.assert_array_equal(shown(page), preview.astype(np.float32))
    set_control(page, "mode", "inflate")
    idle(page, server)
    path = facing_path(page, preview)
    dabs, img0 = page.execute_script("return window.studio.dabs"), pixels(page)
    stroke(page, path)
    idle(page, server)
    img1 = pixels(page)
    V = s.vertices
    # the slider returned to 0: the page shows the current shape, which started from the preview
    assert page.execute_script("return [window.studio.lam, document.getElementById('lam').value]") == [0, "0"]
    np.testing.assert_array_equal(shown(page), V.astype(np.float32))
    assert page.execute_script("return window.studio.dabs") - dabs >= len(path) - 2    # (was 3 of 9)
    moved = np.linalg.norm(V - preview, axis=1) > 1e-12
    assert moved.sum() > 30
    out = ((V - preview) * vertex_normals(s.base.with_vertices(preview))).sum(axis=1)[moved]
    assert (out > 0).mean() > 0.95 and out.sum() > 0                 # outwards: no dent
    radius = page.execute_script("return window.studio.brush().radius")
    last = np.linalg.norm(preview - path[-1], axis=1) < 0.5 * radius
    assert moved[last].all()                                         # the stroke's last dab counted
    assert changed_pixels(img0, img1) > 3000
    # two steps: the preview applied, then the stroke (one step however many dabs)
    press(page, Keys.CONTROL, "z")
    idle(page, server)
    np.testing.assert_array_equal(s.vertices, preview)
    press(page, Keys.CONTROL, "z")
    idle(page, server)
    np.testing.assert_array_equal(s.vertices, start)
    np.testing.assert_array_equal(shown(page), start.astype(np.float32))
    press(page, Keys.CONTROL, Keys.SHIFT, "z")                       # redo, as Blender
    idle(page, server)
    np.testing.assert_array_equal(s.vertices, preview)
    press(page, Keys.CONTROL, "y")                                   # and as most editors
    idle(page, server)
    np.testing.assert_array_equal(s.vertices, V)
    undo_to_start(page, server, start)


def test_enhancement_dabs_at_a_previewed_lambda_change_the_shape(page, server):
    s = server.session
    start = s.vertices
    idle(page, server)
    type_lam(page, -171)
    preview = s.shape_at(-171.0)
    set_control(page, "mode", "sculpt")
    path = facing_path(page, preview, k=10)
    img0 = pixels(page)
    stroke(page, path)
    idle(page, server)
    V = s.vertices
    d = np.linalg.norm(V - preview, axis=1)
    assert d.max() > 0.004 * s.base.diagonal                           # (changed nothing before)
    assert changed_pixels(img0, pixels(page)) > 1500
    radius = page.execute_script("return window.studio.brush().radius")
    reach = np.min([np.linalg.norm(preview - p, axis=1) for p in path], axis=0)
    assert np.all(d[reach > 1.5 * radius] == 0.0)                     # nothing far from the stroke moved
    press(page, Keys.CONTROL, "z")                                   # the stroke: one step
    idle(page, server)
    np.testing.assert_array_equal(s.vertices, preview)
    undo_to_start(page, server, start)


def test_painting_at_a_previewed_lambda_keeps_the_preview_and_it_follows(page, server):
    s = server.session
    start = s.vertices
    idle(page, server)
    type_lam(page, -120)
    before = s.shape_at(-120.0)
    set_control(page, "mode", "erase")
    stroke(page, facing_path(page, before))
    idle(page, server)
    assert page.execute_script("return window.studio.lam") == -120      # the preview stays
    np.testing.assert_array_equal(s.vertices, start)                    # painting moves nothing
    assert s.weights.min() < 0.9
    # the family was solved again with the new weights: the preview follows
    wait(page, "return window.studio.previewing && window.studio.family.state === 'done' && "
               "window.studio.pending === 0")
    idle(page, server)
    after = s.shape_at(-120.0)
    scale = np.abs(before - start).max()
    assert np.abs(after - before).max() > 0.05 * scale
    np.testing.assert_array_equal(shown(page), after.astype(np.float32))
    ref = sf.flow(s.mesh, -120.0, weights=s.weights).vertices          # the library's own flow
    assert np.abs(after - ref).max() < 1e-5 * scale
    press(page, Keys.CONTROL, "z")                                      # the stroke was one step
    idle(page, server)
    assert np.all(s.weights == 1.0)
    wait(page, "return window.studio.family.state === 'done' && window.studio.previewing")
    idle(page, server)
    assert np.abs(s.shape_at(-120.0) - before).max() < 1e-6 * scale
    undo_to_start(page, server, start)


def test_the_page_says_what_a_format_drops_before_and_after_downloading(page, server):
    """Spot's UVs and painted weights: OFF keeps neither (the note under the menu says so as the format
    is chosen, and the blue banner after the download), PLY keeps both."""
    idle(page, server)
    server.session.paint(server.session.vertices[0], 0.3, value=0.0)
    set_control(page, "format", "off")
    wait(page, "return (window.studio.formatNote || '').startsWith('⚠')")
    note = page.find_element("id", "format-note").text
    assert "OFF" in note and "'weight'" in note and "'uv'" in note
    page.find_element("id", "download").click()
    wait(page, "return (window.studio.downloadLosses || []).length === 1 && window.studio.pending === 0")
    info = page.find_element("id", "info")
    assert info.is_displayed() and "spot-studio.off downloaded" in info.text and "'weight'" in info.text
    assert not page.find_element("id", "error").is_displayed()
    set_control(page, "format", "ply")
    wait(page, "return window.studio.formatNote === 'PLY keeps all this mesh holds'")
    page.find_element("id", "info-close").click()
    assert not info.is_displayed()


def test_opening_a_file_with_unsaved_changes_asks_first(page, server, tmp_path):
    from meshgen import cube_sphere

    s = server.session
    idle(page, server)
    set_control(page, "mode", "erase")
    stroke(page, facing_path(page, s.vertices, k=4))
    idle(page, server)
    assert s.modified and "unsaved" in page.find_element("id", "status").text
    path = tmp_path / "other.off"
    sf.save(path, cube_sphere(4))
    page.find_element("id", "open-file").send_keys(str(path))
    assert "unsaved changes" in confirm(page, accept=False)            # Cancel: nothing opens
    idle(page, server)
    assert server.session is s and s.modified
    page.find_element("id", "download").click()                         # downloaded: saved
    wait(page, "return window.studio.modified === false && window.studio.pending === 0")
    assert not s.modified and "unsaved" not in page.find_element("id", "status").text
    press(page, Keys.CONTROL, "z")                                      # the state downloaded is the saved one
    wait(page, "return window.studio.modified === true && window.studio.pending === 0")
    press(page, Keys.CONTROL, Keys.SHIFT, "z")
    wait(page, "return window.studio.modified === false && window.studio.pending === 0")
    page.find_element("id", "open-file").send_keys(str(path))           # nothing unsaved: no question
    wait(page, "return window.studio.name === 'other.off' && window.studio.ready")
    assert server.session is not s and not server.session.modified

