"""The λ slider and the view, driven in headless Chromium: the default family spans smoothing and
enhancement (+60 … −240, one solve), the label keeps its place at three-digit λ, a typed λ and the
slider follow each other, the family's range is edited from the page; the model's front faces the
camera on opening (the project's view rule: Spot shows its face), Blender's numpad keys turn the
view, Home frames the model, and the camera backs off when a shape outgrows the frame."""

from __future__ import annotations

import io
import urllib.request

import numpy as np
import pytest
from conftest import need

import shapeflow as sf

need("aiohttp", "aiohttp (the 'studio' extra)")
need("selenium.webdriver", "selenium (a test dependency)")
from browser import (  # noqa: E402
    CHROMIUM,
    DRIVER,
    canvas_box,
    idle,
    pixels,
    press,
    settled,
    shown,
    spot_studio,
    type_into,
    wait,
)
from selenium.webdriver.common.action_chains import ActionChains  # noqa: E402
from selenium.webdriver.common.actions.wheel_input import ScrollOrigin  # noqa: E402
from selenium.webdriver.common.keys import Keys  # noqa: E402

from shapeflow.studio.headless import set_control  # noqa: E402

pytestmark = pytest.mark.skipif(not (CHROMIUM and DRIVER), reason="chromium and chromedriver are not installed")


server, page = spot_studio((1100, 760))


def box(d, element_id):
    r = d.execute_script(f"const r = document.getElementById('{element_id}').getBoundingClientRect();"
                         "return [r.left, r.top, r.width, r.height];")
    return [round(v, 2) for v in r]


def direction(d):
    """The unit vector from the camera's target towards the camera."""
    p = np.array(d.execute_script("return window.studio.cameraPosition()"))
    t = np.array(d.execute_script("return window.studio.cameraTarget()"))
    return (p - t) / np.linalg.norm(p - t)


def test_the_default_family_spans_smoothing_and_enhancement(page, server):
    s = server.session
    idle(page, server)
    lams = s.family_status().lams
    assert lams == [float(x) for x in range(-240, 61, 10)]                       # 31 members, one solve
    assert page.execute_script("const s = document.getElementById('lam'); return [s.min, s.max]") == ["-240", "60"]
    mesh = s.mesh
    for lam in (60.0, -240.0):                                                   # the library's own flow
        ref = sf.flow(mesh, lam).vertices
        assert np.abs(s.shape_at(lam) - ref).max() < 1e-5 * np.abs(ref - mesh.vertices).max()
    set_control(page, "lam", 60, event="input")                                  # right: smoothing
    wait(page, "return window.studio.pending === 0 && window.studio.previewing")
    np.testing.assert_array_equal(shown(page), s.shape_at(60.0).astype(np.float32))


def test_the_label_keeps_its_place_and_the_typed_value_follows_the_slider(page, server):
    idle(page, server)
    boxes, labels = {}, {}
    for lam in (0, -5, -240, 60, -123):
        set_control(page, "lam", lam, event="input")
        wait(page, f"return window.studio.pending === 0 && window.studio.lam === {lam}")
        boxes[lam] = (box(page, "lam"), box(page, "lam-value"), box(page, "lam-num"))
        labels[lam] = page.find_element("id", "lam-value").text
        assert page.find_element("id", "lam-num").get_attribute("value") == str(lam)   # the number box follows
    assert len({str(b) for b in boxes.values()}) == 1, boxes                      # nothing moved or wrapped
    assert boxes[0][1][3] < 20                                                     # one line
    assert labels[-240] == "−240 enhance" and labels[60] == "+60 smooth" and labels[0] == "0 · as is"
    type_into(page, "lam-num", -171, enter=True)                                   # and the slider the number
    wait(page, "return window.studio.pending === 0 && window.studio.lam === -171")
    assert page.execute_script("return document.getElementById('lam').value") == "-171"
    np.testing.assert_array_equal(shown(page), server.session.shape_at(-171.0).astype(np.float32))
    type_into(page, "lam-num", -900, enter=True)                                   # outside: the end, and why
    wait(page, "return window.studio.pending === 0 && window.studio.lam === -240")
    info, error = page.find_element("id", "info"), page.find_element("id", "error")
    assert "outside the family" in info.text and not error.is_displayed()        # information, not an error
    assert info.value_of_css_property("background-color") != error.value_of_css_property("background-color")
    set_control(page, "lam", 0, event="input")
    wait(page, "return window.studio.pending === 0 && window.studio.lam === 0")


def test_the_family_range_is_edited_from_the_page(page, server):
    idle(page, server)
    for eid, value in (("fam-from", "20"), ("fam-to", "-60"), ("fam-step", "-20")):
        type_into(page, eid, value)
    page.find_element("id", "fam-solve").click()
    wait(page, "return window.studio.pending === 0 && window.studio.family.state === 'done' && "
               "window.studio.lams.length === 5")
    assert server.session.family_status().lams == [-60.0, -40.0, -20.0, 0.0, 20.0]
    assert page.execute_script("const s = document.getElementById('lam'); return [s.min, s.max]") == ["-60", "20"]
    for eid, value in (("fam-from", "60"), ("fam-to", "-240"), ("fam-step", "-10")):   # back to the default
        type_into(page, eid, value, enter=eid == "fam-step")
    wait(page, "return window.studio.pending === 0 && window.studio.family.state === 'done' && "
               "window.studio.lams.length === 31")


def blue_pixels(d) -> int:
    """Pixels of the view drawn in weight 0's colour (blue: the page draws weight 0 as (0.25, 0.35, 0.9))."""
    left, top, width, height = canvas_box(d)
    img = pixels(d)[top:top + height, left:left + width]
    return int(((img[:, :, 2] - img[:, :, 0] > 60) & (img[:, :, 2] > 120)).sum())


def test_spot_shows_its_face_and_the_numpad_turns_the_view(page, server):
    s = server.session
    idle(page, server)
    press(page, "1")
    # Spot faces -z (its metadata, the project's rule): the front view looks from -z
    np.testing.assert_allclose(direction(page), [0.0, 0.0, -1.0], atol=1e-6)
    V = s.vertices
    face = V[:, 2] < V[:, 2].min() + 0.15 * np.ptp(V[:, 2])                    # the snout
    buf = io.BytesIO()
    np.save(buf, np.where(face, 0.0, 1.0))
    urllib.request.urlopen(urllib.request.Request(server.link("weights", name="face.npy"), data=buf.getvalue()))
    set_control(page, "colours", "weights")
    settled(page, server)
    front = blue_pixels(page)
    press(page, "9")                                                             # the other side: the back
    np.testing.assert_allclose(direction(page), [0.0, 0.0, 1.0], atol=1e-6)
    settled(page, server)
    back = blue_pixels(page)
    assert front > 10000 and back < 0.01 * front, (front, back)
    views = {"3": [-1.0, 0.0, 0.0], "7": [0.0, 1.0, 0.0]}                    # right: the model's right (−x)
    for key, want in views.items():
        press(page, key)
        assert np.dot(direction(page), want) > 0.9999, key
    press(page, Keys.CONTROL, "3")
    assert np.dot(direction(page), [1.0, 0.0, 0.0]) > 0.9999
    press(page, Keys.NUMPAD1)
    np.testing.assert_allclose(direction(page), [0.0, 0.0, -1.0], atol=1e-6)
    press(page, Keys.CONTROL, "z")                                              # the weights: one step
    idle(page, server)
    assert np.all(s.weights == 1.0)


def test_home_frames_the_model_and_the_camera_backs_off_when_a_shape_outgrows_it(page, server):
    idle(page, server)
    press(page, "1")
    page.execute_script("window.studio.send({op: 'solve', from: 0, to: -3000, step: -500});")
    wait(page, "return window.studio.pending === 0 && window.studio.family.state === 'done' && "
               "window.studio.lams.length === 7")
    d0 = np.linalg.norm(np.array(page.execute_script("return window.studio.cameraPosition()"))
                        - page.execute_script("return window.studio.cameraTarget()"))
    refits = page.execute_script("return window.studio.refits || 0")
    set_control(page, "lam", -3000, event="input")
    wait(page, "return window.studio.pending === 0 && window.studio.previewing")
    settled(page, server)
    grown = server.session.shape_at(-3000.0)
    assert np.ptp(grown, axis=0).max() > 1.2 * np.ptp(server.session.vertices, axis=0).max()
    assert page.execute_script("return window.studio.refits") > refits
    assert page.execute_script("return window.studio.outside()") == 0                # all of it in the picture
    d1 = np.linalg.norm(np.array(page.execute_script("return window.studio.cameraPosition()"))
                        - page.execute_script("return window.studio.cameraTarget()"))
    assert d1 > d0
    np.testing.assert_allclose(direction(page), [0.0, 0.0, -1.0], atol=1e-6)         # from where it looked
    canvas = page.find_element("css selector", "#view canvas")
    ActionChains(page).scroll_from_origin(ScrollOrigin.from_element(canvas), 0, -2000).perform()   # zoomed in
    wait(page, "return window.studio.outside() > 0")
    press(page, Keys.HOME)                                                           # Home frames it again
    wait(page, "return window.studio.outside() === 0")
    set_control(page, "lam", 0, event="input")
    page.execute_script("window.studio.send({op: 'solve', from: 60, to: -240, step: -10});")
    wait(page, "return window.studio.pending === 0 && window.studio.family.state === 'done' && "
               "window.studio.lams.length === 31")
