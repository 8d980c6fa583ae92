"""What the tests in tests/studio read from the studio's page in headless Chromium
(:mod:`shapeflow.studio.headless` starts it)."""

from __future__ import annotations

import io
import time

import numpy as np

from shapeflow.studio.headless import chromium, chromium_page, wait  # noqa: F401 (the tests import them from here)

CHROMIUM, DRIVER = chromium()


def settled(d, server, timeout=60.0):
    """The page has its answers and has drawn since: no edit in flight, and the session's version
    (read afresh: a stroke's last edits may still be arriving) shown for a quarter of a second."""
    t0, since = time.monotonic(), None
    while time.monotonic() - t0 < timeout:
        ok = d.execute_script(f"return window.studio.pending === 0 && "
                              f"window.studio.version === {server.session.version}")
        since = (since or time.monotonic()) if ok else None
        if since is not None and time.monotonic() - since > 0.25:
            break
        time.sleep(0.05)
    else:
        raise AssertionError("the page did not settle")
    frames = d.execute_script("window.studio.redraw(); return window.studio.frames")
    wait(d, f"return window.studio.frames > {frames}")


def shown(d) -> np.ndarray:
    return np.array(d.execute_script("return window.studio.positions()"), np.float32).reshape(-1, 3)


def pixels(d) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(d.get_screenshot_as_png())).convert("RGB"), np.int16)


def canvas_box(d):
    r = d.execute_script("const r = document.querySelector('#view canvas').getBoundingClientRect();"
                         "return [r.left, r.top, r.width, r.height];")
    return [int(round(v)) for v in r]


def confirm(d, accept: bool = True, timeout: float = 10.0) -> str:
    """Answer the page's confirm dialog (OK or Cancel); its text."""
    from selenium.webdriver.support import expected_conditions
    from selenium.webdriver.support.ui import WebDriverWait

    WebDriverWait(d, timeout).until(expected_conditions.alert_is_present())
    alert = d.switch_to.alert
    text = alert.text
    alert.accept() if accept else alert.dismiss()
    return text


def canvas_offset(d, point) -> tuple[int, int]:
    """Where a point of the model is on the screen, as an offset from the canvas's centre (selenium's
    ``move_to_element_with_offset``)."""
    x, y = d.execute_script(f"return window.studio.toScreen({[float(v) for v in point]})")
    left, top, width, height = canvas_box(d)
    return int(round(x - left - width / 2)), int(round(y - top - height / 2))


def stroke(d, points, *, pause: float = 0.12, hold=()):
    """A pointer stroke over the model through ``points`` (3D points, projected with the page's
    camera), with keys ``hold`` held down (selenium Keys); returns the offsets it went through."""
    from selenium.webdriver.common.action_chains import ActionChains

    canvas = d.find_element("css selector", "#view canvas")
    offsets = [canvas_offset(d, p) for p in points]
    chain = ActionChains(d)
    for k in hold:
        chain = chain.key_down(k)
    chain = chain.move_to_element_with_offset(canvas, *offsets[0]).click_and_hold().pause(pause)
    for o in offsets[1:]:
        chain = chain.move_to_element_with_offset(canvas, *o).pause(pause)
    chain = chain.release()
    for k in hold:
        chain = chain.key_up(k)
    chain.perform()
    return offsets


def press(d, *keys):
    """Press a key combination as a user would, e.g. ``press(d, Keys.CONTROL, "z")``."""
    from selenium.webdriver.common.action_chains import ActionChains

    chain = ActionChains(d)
    for k in keys[:-1]:
        chain = chain.key_down(k)
    chain = chain.send_keys(keys[-1])
    for k in reversed(keys[:-1]):
        chain = chain.key_up(k)
    chain.perform()


def idle(d, server, timeout=120.0):
    """No edit in flight, no stroke open, the family not being solved, and the page settled."""
    wait(d, "return window.studio.pending === 0 && !window.studio.stroking && window.studio.family && "
            "window.studio.family.state !== 'running'", timeout)
    settled(d, server, timeout)


def changed_pixels(a, b, threshold: int = 30) -> int:
    """How many pixels differ by more than ``threshold`` (sum over the channels) between two screenshots."""
    return int((np.abs(a - b).sum(axis=2) > threshold).sum())


def spot_studio(size=(1100, 760)):
    """Module fixtures ``server`` (the studio on the bundled Spot) and ``page`` (it in Chromium at ``size``):
    ``server, page = spot_studio()`` in a test module."""
    import pytest

    import shapeflow as sf

    @pytest.fixture(scope="module")
    def server():
        from shapeflow.studio import StudioServer

        with StudioServer(sf.load_example("spot"), name="spot") as srv:
            yield srv

    @pytest.fixture(scope="module")
    def page(server):
        with chromium_page(server.url, size=size) as d:
            yield d

    return server, page


def type_into(d, element_id: str, text: str, enter: bool = False):
    """Click a box of the page, replace its text as a user would (Ctrl+A, typing), optionally Enter."""
    from selenium.webdriver.common.keys import Keys

    box = d.find_element("id", element_id)
    box.click()
    box.send_keys(Keys.CONTROL, "a")
    box.send_keys(str(text), *([Keys.ENTER] if enter else []))
