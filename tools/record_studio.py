"""Record a short screen recording of the studio (an animated WebP) in headless Chromium.

    python tools/record_studio.py [--out docs/img/studio.webp] [--levels 1] [--width 720]

Spot subdivided ``--levels`` times in the studio; the script scrubs the λ slider with the
curvature colours following, erases the weights on the horns with a stroke, enhances again
(the horns keep their shape), shows the before/after split and turns the model on the turntable.
Each frame is a screenshot of the view (WebGL on SwiftShader, no GPU needed); the frames are
written with Pillow.  Needs the ``studio`` extra, selenium, Pillow, chromium and chromedriver.
"""

from __future__ import annotations

import argparse
import io
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

import shapeflow as sf  # noqa: E402
from shapeflow.studio import StudioServer  # noqa: E402
from shapeflow.studio.headless import chromium_page, set_control, wait  # noqa: E402


class Film:
    """Screenshots of the page's view, each held for a given time."""

    def __init__(self, page, width: int):
        self.page, self.width = page, width
        self.frames, self.durations = [], []
        self.view = page.find_element("id", "view")

    def shot(self, ms: int = 110) -> None:
        from PIL import Image

        wait(self.page, "return window.studio.pending === 0")
        n = self.page.execute_script("window.studio.redraw(); return window.studio.frames")
        wait(self.page, f"return window.studio.frames > {n}")
        im = Image.open(io.BytesIO(self.view.screenshot_as_png)).convert("RGB")
        self.frames.append(im.resize((self.width, round(im.height * self.width / im.width)), Image.LANCZOS))
        self.durations.append(ms)

    def save(self, path: Path) -> None:
        self.frames[0].save(path, save_all=True, append_images=self.frames[1:], duration=self.durations,
                            loop=0, quality=72, method=6)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "img" / "studio.webp")
    ap.add_argument("--levels", type=int, default=1)
    ap.add_argument("--width", type=int, default=720)
    a = ap.parse_args()
    from selenium.webdriver.common.action_chains import ActionChains

    mesh = sf.subdivide(sf.load_example("spot"), a.levels) if a.levels else sf.load_example("spot")
    lams = [float(x) for x in range(0, -201, -10)]
    with StudioServer(mesh, lams=lams, name="spot") as srv, chromium_page(srv.url, size=(1180, 700)) as page:
        film = Film(page, a.width)
        set_control(page, "colours", "curvature")
        film.shot(700)
        for lam in [*range(-10, -161, -10), *range(-150, -79, 10)]:          # the colours follow the slider
            set_control(page, "lam", str(lam), event="input")
            film.shot()
        film.shot(600)
        set_control(page, "lam", "0", event="input")
        set_control(page, "colours", "weights")
        page.execute_script("document.getElementById('mode').value = 'erase';"
                            "document.getElementById('radius').value = 0.09;")
        canvas = page.find_element("css selector", "#view canvas")
        ActionChains(page).move_to_element_with_offset(canvas, 20, -175).click_and_hold().perform()
        for k in range(12):                                                  # across the horns
            ActionChains(page).move_to_element_with_offset(canvas, 20 + 9 * k, -178 + (k % 3)).pause(0.05).perform()
            film.shot(90)
        ActionChains(page).release().perform()
        page.execute_script("document.getElementById('mode').value = 'view';")
        film.shot(500)
        for lam in range(-20, -161, -20):                                     # the horns keep their shape
            set_control(page, "lam", str(lam), event="input")
            film.shot()
        film.shot(600)
        set_control(page, "split", checked=True)                                  # before | after
        film.shot(1400)
        set_control(page, "split", checked=False)
        set_control(page, "colours", "none")
        set_control(page, "turntable", checked=True)
        for _ in range(24):
            film.shot(90)
    a.out.parent.mkdir(parents=True, exist_ok=True)
    film.save(a.out)
    print(f"{a.out}: {len(film.frames)} frames, {sum(film.durations) / 1000:.1f} s, "
          f"{a.out.stat().st_size / 1024:.0f} KiB, {mesh.n_vertices:,} vertices")
    return 0


if __name__ == "__main__":
    sys.exit(main())
