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
