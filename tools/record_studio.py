"""Record the studio in headless Chromium: a short screen recording (an animated WebP) and a still.

    python tools/record_studio.py [--out docs/img/studio.webp] [--still docs/img/studio.png]
                                  [--levels 1] [--width 1280] [--quality 80]

Spot subdivided ``--levels`` times in the studio, the whole page at 1280×800.  The recording: the
page opens on Spot's front; the λ slider walks the family from smoothing (+60) to enhancement with
the curvature colours following; Mirror X on, one stroke erases the weight on one horn and its
mirror image erases the other; the enhancement leaves the horns as they were; at a previewed λ an
inflate stroke on a cheek (mirrored) applies the preview and acts on it, the slider back at 0;
Ctrl+Z twice takes back the stroke and the applied preview; the before/after split; the
turntable.  The still: the page with the horns erased, the preview at λ = −120 and both brush
circles.  Each frame is a screenshot (WebGL on SwiftShader, no GPU needed), written with Pillow; at the
default width (the page's own, no scaling) the panel's 12–13 px text stays readable.
Needs the ``studio`` extra, selenium, Pillow, chromium and chromedriver.
"""

from __future__ import annotations

import argparse
import io
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

import shapeflow as sf  # noqa: E402
from shapeflow.studio import StudioServer  # noqa: E402
from shapeflow.studio.headless import chromium_page, set_control, wait  # noqa: E402

SIZE = (1280, 800)


class Film:
    """Screenshots of the page, each held for a given time."""

    def __init__(self, page, width: int, quality: int):
        self.page, self.width, self.quality = page, width, quality
        self.frames, self.durations = [], []

    def shot(self, ms: int = 110) -> None:
        from PIL import Image

        wait(self.page, "return window.studio.pending === 0")
        n = self.page.execute_script("window.studio.redraw(); return window.studio.frames")
        wait(self.page, f"return window.studio.frames > {n}")
        im = Image.open(io.BytesIO(self.page.get_screenshot_as_png())).convert("RGB")
        if im.width != self.width:
            im = im.resize((self.width, round(im.height * self.width / im.width)), Image.LANCZOS)
        self.frames.append(im)
        self.durations.append(ms)

    def save(self, path: Path) -> None:
        self.frames[0].save(path, save_all=True, append_images=self.frames[1:], duration=self.durations,
                            loop=0, quality=self.quality, method=6)


def offset(page, p) -> tuple[int, int]:
    """Where the model's point ``p`` is on the screen, from the canvas's centre."""
    x, y = page.execute_script(f"return window.studio.toScreen({[float(v) for v in p]})")
    r = page.execute_script("const r = document.querySelector('#view canvas').getBoundingClientRect();"
                            "return [r.left + r.width / 2, r.top + r.height / 2];")
    return int(round(x - r[0])), int(round(y - r[1]))


def nearest_on_screen(page, V, pts):
    """For each point, the vertex of ``V`` nearest the camera among those near the point's line of sight."""
    cam = np.array(page.execute_script("return window.studio.cameraPosition()"))
    out = []
    for p in pts:
        d = (p - cam) / np.linalg.norm(p - cam)
        q = V - cam
        off = np.linalg.norm(q - (q @ d)[:, None] * d, axis=1)
        near = np.flatnonzero(off < 0.02)
        out.append(V[near[np.argmin(q[near] @ d)]])
    return out


def drag(page, film, points, ms=90, hold=()):
    """A pointer stroke through ``points`` (on the model), filmed."""
    from selenium.webdriver.common.action_chains import ActionChains

    canvas = page.find_element("css selector", "#view canvas")
    offs = [offset(page, p) for p in points]
    chain = ActionChains(page)
    for k in hold:
        chain = chain.key_down(k)
    chain.move_to_element_with_offset(canvas, *offs[0]).click_and_hold().perform()
    for o in offs[1:]:
        ActionChains(page).move_to_element_with_offset(canvas, *o).pause(0.05).perform()
        film.shot(ms)
    chain = ActionChains(page).release()
    for k in hold:
        chain = chain.key_up(k)
    chain.perform()
    wait(page, "return window.studio.pending === 0 && !window.studio.stroking")


def walk(page, film, lams, ms=110):
    for lam in lams:
        set_control(page, "lam", str(lam), event="input")
        wait(page, f"return window.studio.pending === 0 && window.studio.lam === {lam}")
        film.shot(ms)


def main() -> int:  # long: the recording's script, scene by scene
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "img" / "studio.webp")
    ap.add_argument("--still", type=Path, default=ROOT / "docs" / "img" / "studio.png")
    ap.add_argument("--levels", type=int, default=1)
    ap.add_argument("--width", type=int, default=SIZE[0], help="of the recording (default: the page's, 1280)")
    ap.add_argument("--quality", type=int, default=80, help="WebP quality of the recording, 0-100")
    a = ap.parse_args()
    from PIL import Image
    from selenium.webdriver.common.keys import Keys

    spot = sf.load_example("spot")
    mesh = sf.subdivide(spot, a.levels) if a.levels else spot
    with StudioServer(mesh, name="spot") as srv, chromium_page(srv.url, size=SIZE) as page:
        film = Film(page, a.width, a.quality)
        V = srv.session.vertices
        film.shot(900)                                                         # the front, as opened
        set_control(page, "colours", "curvature")
        walk(page, film, [*range(10, 61, 10), *range(50, -161, -10)])          # smoothing, then enhancement
        film.shot(600)
        walk(page, film, [0], 300)
        set_control(page, "colours", "weights")
        set_control(page, "mode", "erase")
        page.find_element("tag name", "body").send_keys("x")                  # Mirror X
        for _ in range(7):                                                     # "[": a smaller brush
            page.find_element("tag name", "body").send_keys("[")
        horn = V[(V[:, 1] > 0.8) & (V[:, 0] > 0.05) & (V[:, 0] < 0.3)]          # one horn (not the ear), base to tip
        horn = horn[np.argsort(horn[:, 1])]
        path = nearest_on_screen(page, V, horn[np.linspace(0, len(horn) - 1, 10).astype(int)])
        drag(page, film, path)
        film.shot(700)
        for _ in range(7):                                                     # "]": back to the default
            page.find_element("tag name", "body").send_keys("]")
        walk(page, film, range(-20, -161, -20))                                # the horns keep their shape
        film.shot(500)
        walk(page, film, [-120], 300)
        set_control(page, "mode", "inflate")
        cheek = V[(np.abs(V[:, 1] - 0.35) < 0.08) & (V[:, 0] > 0.18) & (V[:, 2] < -0.35)]
        cheek = cheek[np.argsort(cheek[:, 2])]
        shown = srv.session.shape_at(-120.0)
        pts = nearest_on_screen(page, shown, [shown[np.argmin(np.linalg.norm(V - c, axis=1))] for c in
                                              cheek[np.linspace(0, len(cheek) - 1, 8).astype(int)]])
        drag(page, film, pts)                                                  # applies the preview: λ back to 0
        film.shot(900)
        for _ in range(2):                                                     # Ctrl+Z: the stroke, the preview
            page.find_element("tag name", "body").send_keys(Keys.CONTROL, "z")
            wait(page, "return window.studio.pending === 0")
            film.shot(700)
        walk(page, film, [-120], 300)
        # the still: the preview at −120, the horns erased, both brush circles over a cheek
        from selenium.webdriver.common.action_chains import ActionChains

        page.execute_script("window.studio.ring = null;")
        canvas = page.find_element("css selector", "#view canvas")
        x, y = offset(page, pts[3])
        ActionChains(page).move_to_element_with_offset(canvas, x - 2, y).move_to_element_with_offset(canvas, x, y)\
            .perform()
        wait(page, "return window.studio.ring && window.studio.ring.visible && window.studio.ring.twin !== null")
        film.shot(600)
        still = Image.open(io.BytesIO(page.get_screenshot_as_png())).convert("RGB")
        set_control(page, "mode", "view")
        set_control(page, "split", checked=True)                               # before | after
        film.shot(1400)
        set_control(page, "split", checked=False)
        set_control(page, "colours", "none")
        set_control(page, "turntable", checked=True)
        for _ in range(24):
            film.shot(90)
    a.out.parent.mkdir(parents=True, exist_ok=True)
    film.save(a.out)
    still.save(a.still, optimize=True)
    print(f"{a.out}: {len(film.frames)} frames, {sum(film.durations) / 1000:.1f} s, "
          f"{a.out.stat().st_size / 1024:.0f} KiB, {mesh.n_vertices:,} vertices; {a.still}: "
          f"{a.still.stat().st_size / 1024:.0f} KiB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
