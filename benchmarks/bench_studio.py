"""The studio's responsiveness, measured in the browser: dab latency and family scrubbing.

    python benchmarks/bench_studio.py [--levels 2] [--dabs 40]

Spot subdivided ``--levels`` times (2: 46,850 vertices) in ``shapeflow studio``, driven in headless
Chromium (Debian's chromium and chromium-driver; WebGL on SwiftShader, the CPU renderer, so the
frame times are an upper bound of a machine with a GPU).  Dab latency: from the pointer event of a
drag over the model (the enhancement brush, radius 5% of the model's size) to the end of the first
frame drawn with the server's answer (``gl.finish()``), per dab sent at its pointer event (a move
while a dab is in flight waits and is sent when the answer arrives: reported apart); each drag is
one stroke (one undo step); drags alternate between the page's default (frames drawn on demand)
and ``?continuous=1`` (every frame drawn).  Scrubbing: the λ slider moved to
the next member at every animation frame for 3 s; frames drawn and position updates received per
second.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np
from common import SHARED, median_time  # noqa: F401,E402  (first: it puts src/ on the path)

import shapeflow as sf  # noqa: E402

#: the λ slider moved to the next member at every animation frame for 3 s: [frames/s, shapes received/s]
SCRUB = """
    const done = arguments[0], s = document.getElementById('lam'), lams = window.studio.lams;
    const f0 = window.studio.frames, t0 = performance.now(); let k = 0, updates = 0, last = null;
    const w0 = window.studio.work.ms;
    function step() {
      if (window.studio.positionsAt !== last) { updates++; last = window.studio.positionsAt; }
      if (performance.now() - t0 > 3000) {
        const dt = (performance.now() - t0) / 1000;
        done([(window.studio.frames - f0) / dt, updates / dt, (window.studio.work.ms - w0) / Math.max(updates, 1)]);
        return;
      }
      s.value = lams[k++ % lams.length]; s.dispatchEvent(new Event('input'));
      requestAnimationFrame(step);
    }
    requestAnimationFrame(step);"""


def across(d, V: np.ndarray, n: int) -> list:
    """``n`` screen offsets (from the canvas's centre) of a horizontal drag over the model as the page
    shows it: in each of ``n`` slices across the view at the model's mid-height, the point nearest
    the camera, projected with the page's camera."""
    view = d.execute_script("return window.studio.views().front")
    cam = np.array(d.execute_script("return window.studio.cameraPosition()"))
    up, right = np.array(view["up"]), np.cross(view["up"], view["dir"])
    q = V - 0.5 * (V.min(axis=0) + V.max(axis=0))
    size = float(np.ptp(q @ right))
    band = np.abs(q @ up) < 0.03 * size
    out = []
    for x in np.linspace(-0.12 * size, 0.12 * size, n):
        sl = np.flatnonzero(band & (np.abs(q @ right - x) < 0.02 * size))
        p = V[sl[np.argmin(np.linalg.norm(V[sl] - cam, axis=1))]]
        sx, sy = d.execute_script(f"return window.studio.toScreen({p.tolist()})")
        r = d.execute_script("const r = document.querySelector('#view canvas').getBoundingClientRect();"
                             "return [r.left + r.width / 2, r.top + r.height / 2];")
        out.append((int(round(sx - r[0])), int(round(sy - r[1]))))
    return out


def dabs(d, V: np.ndarray, n: int, size: float) -> tuple:
    """A drag of ``n`` pointer moves with the enhancement brush over the model (one stroke); the
    latencies the page measured (dabs sent at their pointer event, and moves that waited)."""
    from selenium.webdriver.common.action_chains import ActionChains

    from shapeflow.studio.headless import wait

    d.execute_script(f"window.studio.latencies = []; window.studio.queuedLatencies = [];"
                     f"document.getElementById('mode').value = 'sculpt';"
                     f"document.getElementById('mode').dispatchEvent(new Event('change'));"
                     f"const r = document.getElementById('radius'); r.value = {0.05 * size};")
    canvas = d.find_element("css selector", "#view canvas")
    path = across(d, V, n)
    chain = ActionChains(d).move_to_element_with_offset(canvas, *path[0]).click_and_hold()
    for p in path[1:]:
        chain = chain.move_to_element_with_offset(canvas, *p).pause(0.08)
    chain.release().perform()
    wait(d, "return window.studio.pending === 0 && window.studio.awaitingFrame === null && !window.studio.stroking")
    d.execute_script("document.getElementById('mode').value = 'view';")
    return (list(d.execute_script("return window.studio.latencies")),
            list(d.execute_script("return window.studio.queuedLatencies")))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--levels", type=int, default=2)
    ap.add_argument("--dabs", type=int, default=40)
    ap.add_argument("--rounds", type=int, default=3, help="drags in each drawing mode, interleaved")
    a = ap.parse_args()
    from shapeflow.studio import StudioServer
    from shapeflow.studio.headless import chromium, chromium_page, set_control, wait

    if not all(chromium()):
        print("needs Debian's chromium and chromium-driver", file=sys.stderr)
        return 2

    mesh = sf.subdivide(sf.load_example("spot"), a.levels)
    size = float(np.linalg.norm(np.ptp(mesh.vertices, axis=0)))
    lat = {"": [], "?continuous=1": []}
    queued = {"": [], "?continuous=1": []}
    with StudioServer(mesh) as srv, chromium_page("about:blank", size=(1200, 800), ready=None) as d:
        t0 = time.monotonic()
        d.get(srv.url)
        wait(d, "return window.studio && window.studio.ready", 300)
        t_open = time.monotonic() - t0
        wait(d, "return window.studio.family && window.studio.family.state === 'done'", 300)
        t_family = time.monotonic() - t0
        for r in range(a.rounds):                     # on demand and continuous drawing, interleaved
            for mode in lat:
                if r or mode:
                    d.get(srv.link("", continuous=1) if mode else srv.url)     # the token kept
                    wait(d, "return window.studio && window.studio.ready && window.studio.family.state === 'done'",
                         300)
                now, later = dabs(d, srv.session.vertices, a.dabs, size)
                lat[mode] += now
                queued[mode] += later
        # drawing every frame (the last page): the frame rate is the cost of one frame
        idle = d.execute_async_script("""
            const done = arguments[0], f0 = window.studio.frames, t0 = performance.now();
            setTimeout(() => done((window.studio.frames - f0) / ((performance.now() - t0) / 1000)), 2000);""")
        d.get(srv.url)                                  # scrubbing on the default page
        wait(d, "return window.studio && window.studio.ready && window.studio.family.state === 'done'", 300)
        scrub = [d.execute_async_script(SCRUB)]
        set_control(d, "colours", "curvature")
        wait(d, "return window.studio.field && window.studio.pending === 0")
        scrub.append(d.execute_async_script(SCRUB))      # the colours follow: a field per shape
    # the server's part of one scrubbing step, timed here: the shape (and its field) as float32 bytes
    from shapeflow.studio.server import field_scale

    session, lams = srv.session, srv.session.family_status().lams

    def shapes():
        for x in lams:
            np.ascontiguousarray(session.shape_at(x), "<f4").tobytes()

    def fields():
        for x in lams[:5]:
            v = session.field("curvature", lam=x)
            np.ascontiguousarray(v, "<f4").tobytes()
            field_scale(v)

    t_shape = median_time(shapes, 3) / len(lams)
    t_field = median_time(fields, 3) / 5
    server = {"": t_shape, ", curvature colours following": t_shape + t_field}
    print(f"shapeflow studio, {mesh.n_vertices:,} vertices ({time.strftime('%Y-%m-%d')}, {os.cpu_count()} cores, "
          f"headless Chromium with SwiftShader)")
    print(f"page ready {t_open:.1f} s after opening; family of {len(srv.session.family_status().lams)} shapes "
          f"ready at {t_family:.1f} s")
    for mode, what in (("", "drawn on demand (default)"), ("?continuous=1", "drawing every frame")):
        if lat[mode]:
            q = np.percentile(lat[mode], [50, 95])
            print(f"dab latency, pointer event to drawn frame, {what}: median {q[0]:.0f} ms, 95th percentile "
                  f"{q[1]:.0f} ms ({len(lat[mode])} dabs sent at their pointer event; target 50 ms)")
        if queued[mode]:
            q = np.percentile(queued[mode], [50, 95])
            print(f"  pointer moves that waited for a dab in flight ({len(queued[mode])}, sent when it was answered): "
                  f"median {q[0]:.0f} ms, 95th percentile {q[1]:.0f} ms from the move to its frame")
    if lat[""] and lat["?continuous=1"]:
        print(f"  on demand / continuous: {np.median(lat['']) / np.median(lat['?continuous=1']):.2f}")
    print(f"drawing every frame: {idle:.1f} frames/s ({1000 / max(idle, 1e-9):.0f} ms a frame)")
    for what, (fps, shapes, work) in zip(("", ", curvature colours following"), scrub):
        print(f"scrubbing the family{what}: {fps:.1f} frames/s drawn, {shapes:.1f} shapes/s received (target 30); "
              f"the page's work on messages {work:.1f} ms a shape, server {1e3 * server[what]:.1f} ms a shape")
    return 0


if __name__ == "__main__":
    sys.exit(main())
