"""The studio's page in a headless Chromium: screenshots, recordings, tests and benchmarks.

Needs selenium (the ``test`` extra) and a Chromium with its driver (Debian: ``chromium`` and
``chromium-driver``).  WebGL runs on SwiftShader, the CPU renderer, so no GPU is needed.

>>> from shapeflow.studio import StudioServer                     # doctest: +SKIP
>>> from shapeflow.studio.headless import chromium_page
>>> with StudioServer(sf.load_example("spot")) as srv, chromium_page(srv.url) as page:   # doctest: +SKIP
...     png = page.get_screenshot_as_png()
"""

from __future__ import annotations

import shutil
import time
from contextlib import contextmanager

from ..errors import OptionalDependencyError

__all__ = ["chromium", "chromium_page", "wait", "set_control", "READY"]

#: true once the page drew the mesh and the family is solved
READY = "return window.studio && window.studio.ready && window.studio.family.state === 'done'"


def chromium() -> tuple[str | None, str | None]:
    """The Chromium binary and its driver found on PATH (None where missing)."""
    return (shutil.which("chromium") or shutil.which("chromium-browser"), shutil.which("chromedriver"))


@contextmanager
def chromium_page(url: str, *, size=(1100, 760), ready: str | None = READY, timeout: float = 120.0):
    """A headless Chromium (a selenium driver) showing ``url`` in a page of ``size`` CSS pixels (the
    viewport: ``innerWidth`` × ``innerHeight``); with ``ready``, once that script returns true.  The
    browser ends with the block."""
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.options import Options
        from selenium.webdriver.chrome.service import Service
    except Exception as exc:   # not installed, or installed and broken
        raise OptionalDependencyError("selenium", "test", "driving the studio in a browser", exc) from exc
    binary, driver = chromium()
    if not (binary and driver):
        raise FileNotFoundError("driving the studio needs chromium and chromedriver on PATH "
                                "(Debian: apt install chromium chromium-driver)")
    opts = Options()
    for a in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--use-angle=swiftshader",
              "--enable-unsafe-swiftshader", f"--window-size={size[0]},{size[1]}"):
        opts.add_argument(a)
    opts.binary_location = binary
    d = webdriver.Chrome(service=Service(driver), options=opts)
    try:
        # the page's own size (the window's, less the browser's frame, would be smaller): size exactly
        d.execute_cdp_cmd("Emulation.setDeviceMetricsOverride", {"width": int(size[0]), "height": int(size[1]),
                                                                 "deviceScaleFactor": 1, "mobile": False})
        d.get(url)
        if ready:
            wait(d, ready, timeout)
        yield d
    finally:
        d.quit()


def wait(d, script: str, timeout: float = 60.0) -> None:
    """Poll ``script`` in the page until it returns true; after ``timeout`` s a TimeoutError
    saying what the page holds."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if d.execute_script(script):
            return
        time.sleep(0.05)
    st = d.execute_script("const s = window.studio || {}; return [s.pending, s.version, s.error, s.family];")
    raise TimeoutError(f"timed out waiting for: {script} (page: pending, version, error, family = {st})")


def set_control(d, element_id: str, value=None, *, checked: bool | None = None, event: str = "change") -> None:
    """Set a control of the page as a user would: its value and/or checked state, then the event
    its handler listens to ("change"; "input" for the λ slider)."""
    js = f"const e = document.getElementById({element_id!r});"
    js += f"e.value = {value!r};" if value is not None else ""
    js += f"e.checked = {str(bool(checked)).lower()};" if checked is not None else ""
    d.execute_script(js + f"e.dispatchEvent(new Event({event!r}));")
