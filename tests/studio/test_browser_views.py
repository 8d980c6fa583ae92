"""The studio's family options, views and files, driven in headless Chromium: Blender mode and the
other options reach the family solve, colour fields follow the slider's preview, the split view
shows the input left of the divider, the turntable turns, files open from the page's dialog,
weights load from a PLY attribute, and oversized or wrong uploads are refused with a message."""

from __future__ import annotations

import glob
import os
import tempfile
import time
import urllib.error
import urllib.request

import numpy as np
import pytest
from conftest import need
from meshgen import cube_sphere

import shapeflow as sf

need("aiohttp", "aiohttp (the 'studio' extra)")
need("selenium.webdriver", "selenium (a test dependency)")
from browser import CHROMIUM, DRIVER, chromium_page, confirm, pixels, settled, shown, wait  # noqa: E402

from shapeflow.studio.headless import set_control  # noqa: E402

pytestmark = pytest.mark.skipif(not (CHROMIUM and DRIVER), reason="chromium and chromedriver are not installed")

LAMS = [0.0, -20.0, -40.0, -60.0, -80.0]
LIMIT = 300_000          # bytes: the uploads below are 20–30 KB, the oversized one over 1 MB


@pytest.fixture(scope="module")
def server():
    from shapeflow.studio import StudioServer

    with StudioServer(sf.load_example("spot"), lams=LAMS, max_upload=LIMIT, name="spot") as srv:
        yield srv


@pytest.fixture(scope="module")
def page(server):
    with chromium_page(server.url) as d:
        yield d


def leftovers() -> list:
    return glob.glob(os.path.join(tempfile.gettempdir(), "shapeflow-studio-*"))


def slide(d, lam):
    set_control(d, "lam", lam, event="input")


def test_blender_mode_and_the_options_reach_the_family(page, server):
    mesh = server.session.mesh
    paper = sf.flow(mesh, -20.0).vertices
    scale = np.abs(paper - mesh.vertices).max()
    set_control(page, "compat", "blender")
    set_control(page, "area", checked=True)
    wait(page, "return window.studio.family.state === 'done' && window.studio.pending === 0 && "
               "window.studio.options.normalized === false")
    ref = sf.flow(mesh, -20.0, compat="blender", normalized=False).vertices   # the library's own flow
    assert np.abs(server.session.shape_at(-20.0) - ref).max() < 1e-5 * scale
    assert np.abs(paper - ref).max() > 0.5 * scale                   # not what the defaults give
    set_control(page, "area", checked=False)
    set_control(page, "iterations", "2")
    set_control(page, "volume", checked=True)
    wait(page, "return window.studio.family.state === 'done' && window.studio.pending === 0 && "
               "window.studio.options.iterations === 2 && window.studio.options.preserve_volume")
    ref = sf.flow(mesh, -20.0, compat="blender", iterations=2, preserve_volume=True).vertices
    assert np.abs(server.session.shape_at(-20.0) - ref).max() < 1e-5 * scale
    set_control(page, "iterations", "0")                                   # refused with the parameter's name
    wait(page, "return window.studio.error !== null && window.studio.error.includes('iterations')")
    for eid, value, checked in (("iterations", "1", None), ("volume", None, False), ("compat", "paper", None)):
        set_control(page, eid, value, checked=checked)
    wait(page, "return window.studio.family.state === 'done' && window.studio.pending === 0 && "
               "window.studio.options.compat === 'paper' && !window.studio.options.preserve_volume")
    assert np.abs(server.session.shape_at(-20.0) - paper).max() < 1e-5 * scale


def test_colours_follow_the_slider(page, server):
    settled(page, server)
    set_control(page, "colours", "curvature")
    slide(page, -40)
    wait(page, "return window.studio.field && window.studio.field.lam === -40 && window.studio.pending === 0")
    values = np.array(page.execute_script("return Array.from(window.studio.field.values)"), np.float32)
    ref = sf.mean_curvature(server.session.mesh.with_vertices(server.session.shape_at(-40.0)), area="barycentric")
    np.testing.assert_allclose(values, ref, rtol=1e-6, atol=1e-6 * np.abs(ref).max())
    at0 = sf.mean_curvature(server.session.mesh, area="barycentric")
    assert np.abs(ref - at0).max() > 0.1 * np.abs(at0).max()         # the preview's colours are not the input's
    slide(page, 0)
    set_control(page, "colours", "weights")
    wait(page, "return window.studio.pending === 0")


def test_a_fast_slider_ends_on_its_last_value(page, server):
    """Input events faster than the answers, while the family is solved again after an edit and its
    progress goes to the page at the same time: one request in flight, the newest value queued,
    and the page ends on the shape of the last value."""
    settled(page, server)
    c = server.session.vertices[200].tolist()        # an edit: the family is solved again while the slider runs,
    page.execute_script(f"window.studio.send({{op: 'dab', center: {c}, radius: 0.1, lam: -20}});")   # its progress
    settled(page, server)                                                                      # sent meanwhile
    page.execute_script("const s = document.getElementById('lam');"
                        "for (let v = 0; v >= -75; v -= 3) { s.value = v; s.dispatchEvent(new Event('input')); }")
    wait(page, "return window.studio.pending === 0 && window.studio.family.state === 'done'")
    slide(page, -75)
    wait(page, "return window.studio.pending === 0")
    assert page.execute_script("return window.studio.lam") == -75
    np.testing.assert_array_equal(shown(page), server.session.shape_at(-75.0).astype(np.float32))
    slide(page, 0)
    wait(page, "return window.studio.pending === 0")
    page.execute_script("window.studio.send({op: 'undo'});")          # the input again, for the split view
    wait(page, "return window.studio.pending === 0")
    np.testing.assert_array_equal(server.session.vertices, server.session.input_vertices)


def test_split_view_shows_the_input_left_of_the_divider_and_the_turntable_turns(page, server):
    settled(page, server)
    set_control(page, "wire", checked=False)
    background = np.array([0x26, 0x27, 0x2b])

    def silhouette():
        frames = page.execute_script("window.studio.redraw(); return window.studio.frames")
        wait(page, f"return window.studio.frames > {frames}")
        return np.abs(pixels(page) - background).sum(axis=2) > 12

    slide(page, -80)                                                 # after the undo above: solved again, and
    wait(page, "return window.studio.pending === 0 && window.studio.previewing")     # the preview follows
    settled(page, server)                                            # (the camera backs off if it outgrew
    slide(page, 0)                                                   # the frame: both pictures after that)
    wait(page, "return window.studio.pending === 0")
    before = silhouette()
    slide(page, -80)
    wait(page, "return window.studio.pending === 0 && window.studio.previewing")
    after = silhouette()
    set_control(page, "split", checked=True)
    split = silhouette()
    box = page.execute_script("const r = document.querySelector('#view canvas').getBoundingClientRect();"
                              "return [r.left, r.width];")
    x = int(round(box[0] + 0.5 * box[1]))
    left, right = slice(int(box[0]) + 2, x - 6), slice(x + 6, int(box[0] + box[1]) - 2)
    assert (before[:, left] != after[:, left]).sum() > 100           # the shapes differ on both sides
    assert (before[:, right] != after[:, right]).sum() > 100
    rows = slice(30, None)                                           # below the divider's label
    assert (split[rows, left] != before[rows, left]).sum() < 20      # left: the input
    assert (split[rows, right] != after[rows, right]).sum() < 20     # right: the shape shown
    set_control(page, "split", checked=False)
    slide(page, 0)
    set_control(page, "wire", checked=True)

    p0 = np.array(page.execute_script("return window.studio.cameraPosition()"))
    set_control(page, "turntable", checked=True)
    frames = page.execute_script("return window.studio.frames")
    wait(page, f"return window.studio.frames > {frames + 5}")
    p1 = np.array(page.execute_script("return window.studio.cameraPosition()"))
    set_control(page, "turntable", checked=False)
    assert np.linalg.norm(p1 - p0) > 1e-3 * np.linalg.norm(p0)
    settled(page, server)                                            # then nothing changes: no frame is drawn
    frames = page.execute_script("return window.studio.frames")
    time.sleep(0.5)
    assert page.execute_script("return window.studio.frames") == frames
    target = server.session.vertices.mean(axis=0)
    assert abs(np.linalg.norm(p1 - target) - np.linalg.norm(p0 - target)) < 1e-3 * np.linalg.norm(p0 - target)


def test_weights_load_from_a_ply_attribute(page, server, tmp_path):
    settled(page, server)
    n = server.session.mesh.n_vertices
    w = np.linspace(0.0, 1.0, n) ** 2
    path = tmp_path / "painted.ply"
    sf.save(path, server.session.mesh.with_weights(w))
    expected = sf.load(path).weights
    version = server.session.version
    page.find_element("id", "weights-file").send_keys(str(path))
    wait(page, f"return window.studio.version > {version}")
    settled(page, server)
    np.testing.assert_array_equal(server.session.weights, expected)
    np.testing.assert_array_equal(np.array(page.execute_script("return window.studio.weightList()"), np.float32),
                                  expected.astype(np.float32))
    other = tmp_path / "other.ply"
    sf.save(other, cube_sphere(4).with_weights(np.zeros(cube_sphere(4).n_vertices)))
    page.find_element("id", "weights-file").send_keys(str(other))
    wait(page, "return window.studio.error !== null && window.studio.error.includes('vertices')")
    np.testing.assert_array_equal(server.session.weights, expected)   # refused: nothing changed
    assert not leftovers()


def test_oversized_and_unknown_uploads_are_refused(page, server, tmp_path):
    big = tmp_path / "big.obj"
    sf.save(big, cube_sphere(60))
    assert big.stat().st_size > LIMIT
    n = server.session.mesh.n_vertices
    page.execute_script("window.studio.error = null;")
    assert server.session.modified                                     # the weights loaded above
    page.find_element("id", "open-file").send_keys(str(big))
    assert "unsaved changes" in confirm(page)                          # asked first
    wait(page, "return window.studio.error !== null")
    assert "larger than the studio accepts" in page.execute_script("return window.studio.error")
    with pytest.raises(urllib.error.HTTPError) as exc:
        urllib.request.urlopen(urllib.request.Request(server.link("open", name="big.obj"), data=big.read_bytes()))
    assert exc.value.code == 413 and b"--max-upload" in exc.value.read()
    with pytest.raises(urllib.error.HTTPError) as exc:
        urllib.request.urlopen(urllib.request.Request(server.link("open", name="notes.exe"), data=b"MZ"))
    assert exc.value.code == 400 and b".exe" in exc.value.read()
    with pytest.raises(urllib.error.HTTPError) as exc:                # a broken file: the reader's message
        urllib.request.urlopen(urllib.request.Request(server.link("open", name="bad.obj"), data=b"f 1 2 3\n"))
    assert exc.value.code == 400 and b"bad.obj" in exc.value.read()
    assert server.session.mesh.n_vertices == n and not leftovers()


def test_open_a_file_from_the_dialog(page, server, tmp_path):
    mesh = cube_sphere(8, mix=0.3)                                   # quads and triangles
    path = tmp_path / "cubes.obj"
    sf.save(path, mesh)
    page.find_element("id", "open-file").send_keys(str(path))
    confirm(page)                                                       # still unsaved: asked again
    wait(page, "return window.studio.name === 'cubes.obj' && window.studio.ready && "
               "window.studio.family.state === 'done'")
    settled(page, server)
    assert server.session.mesh.n_vertices == mesh.n_vertices
    np.testing.assert_array_equal(shown(page), sf.load(path).vertices.astype(np.float32))
    assert page.execute_script("return window.studio.edgeCount()") == mesh.topology.edges.shape[0]   # polygon edges
    np.testing.assert_allclose(server.session.shape_at(-20.0), sf.flow(sf.load(path), -20.0).vertices,
                               rtol=0, atol=1e-6)
    assert not leftovers()


def test_drop_a_file_on_the_page(page, server, tmp_path):
    mesh = cube_sphere(5)
    path = tmp_path / "dropped.off"
    sf.save(path, mesh)
    page.execute_script("""
        const dt = new DataTransfer();
        dt.items.add(new File([arguments[0]], 'dropped.off'));
        document.getElementById('view').dispatchEvent(new DragEvent('drop', {dataTransfer: dt, bubbles: true,
                                                                              cancelable: true}));""",
                        path.read_text())
    wait(page, "return window.studio.name === 'dropped.off' && window.studio.ready && "
               "window.studio.family.state === 'done'")
    settled(page, server)
    np.testing.assert_array_equal(shown(page), sf.load(path).vertices.astype(np.float32))
    assert server.session.mesh.n_faces == mesh.n_faces and not leftovers()
