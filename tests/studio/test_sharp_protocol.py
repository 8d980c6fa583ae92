"""The "features" message over a real WebSocket: it sets "Keep sharp edges" in every tab (a
"features" message and the sharp edges as an SHP0 frame of vertex pairs), solves the family again
with them (flat sides stay flat), is no edit, and every malformed one is answered by the protocol's
one-line error and changes nothing; a file that marks edges offers them and they can be kept."""

from __future__ import annotations

import asyncio
import json
import urllib.request

import numpy as np
import pytest

pytest.importorskip("aiohttp", reason="aiohttp (the 'studio' extra) is not installed")

import aiohttp  # noqa: E402
from test_hostile_clients import ws_url  # noqa: E402
from test_session_sharp import HALF, K, box_parts, flatness, obj_with_groups  # noqa: E402

from shapeflow.studio import StudioServer  # noqa: E402

DIAG = float(np.linalg.norm(2 * HALF))


@pytest.fixture
def server():
    box, _ = box_parts()
    with StudioServer(box, lams=[0.0, -60.0, -120.0], name="box") as srv:
        srv.session.wait_family(120)
        yield srv


async def collect(ws, rid):
    """Texts (parsed) and SHP0 frames (as (k, 2) pairs) up to this tab's answer to request ``rid``."""
    texts, pairs = [], []
    while True:
        m = await ws.receive(timeout=60)
        if m.type == aiohttp.WSMsgType.BINARY:
            if m.data[:4] == b"SHP0":
                pairs.append(np.frombuffer(m.data[4:], "<u4").reshape(-1, 2))
            continue
        msg = json.loads(m.data)
        texts.append(msg)
        if msg["type"] in ("done", "error") and msg.get("id") == rid:
            return texts, pairs


def features_of(texts):
    return [t for t in texts if t["type"] == "features"]


def run(srv, script):
    async def go():
        async with aiohttp.ClientSession() as cs:
            async with cs.ws_connect(ws_url(srv), max_msg_size=0) as ws, \
                    cs.ws_connect(ws_url(srv), max_msg_size=0) as other:
                return await script(ws, other)
    return asyncio.run(go())


def test_the_toggle_solves_the_family_with_sharp_edges_in_every_tab_and_is_no_edit(server):
    s = server.session
    _, sides = box_parts()
    assert flatness(s.shape_at(-120.0), sides) > 1e-2 * DIAG          # solved without: the sides bend

    async def script(ws, other):
        await ws.send_str('{"op": "lam", "value": 0, "id": 1}')
        texts, pairs = await collect(ws, 1)
        opened = features_of(texts)        # a tab gets the setting with the mesh: off, no edges
        assert opened and opened[0]["on"] is False and opened[0]["count"] == 0 and len(pairs[0]) == 0
        version, undo = s.version, s.can_undo
        await ws.send_str('{"op": "features", "on": true, "angle": 30, "id": 2}')
        texts, pairs = await collect(ws, 2)
        assert texts[-1]["type"] == "done"
        f = features_of(texts)[-1]
        assert (f["on"], f["angle"], f["marked"], f["marked_count"], f["count"]) == (True, 30.0, False, 0, 12 * K)
        assert np.array_equal(pairs[-1], s.sharp_edges()) and len(pairs[-1]) == 12 * K
        assert s.features == {"on": True, "angle": 30.0, "marked": False}
        assert (s.version, s.can_undo) == (version, undo)                # not an edit
        while True:                        # the other tab is told too
            m = await other.receive(timeout=60)
            if m.type == aiohttp.WSMsgType.TEXT and json.loads(m.data)["type"] == "features" \
                    and json.loads(m.data)["on"]:
                break

    run(server, script)
    assert s.wait_family(120).state == "done"
    assert flatness(s.shape_at(-120.0), sides) <= 1e-9 * DIAG
    assert flatness(s.shape_at(-90.0), sides) <= 1e-9 * DIAG

    async def off(ws, other):
        await ws.send_str('{"op": "features", "on": false, "id": 3}')
        texts, pairs = await collect(ws, 3)
        assert features_of(texts)[-1]["count"] == 0 and len(pairs[-1]) == 0

    run(server, off)
    assert s.wait_family(120).state == "done"
    assert flatness(s.shape_at(-120.0), sides) > 1e-2 * DIAG


HOSTILE = [
    ('{"op": "features"}', "missing"),
    ('{"op": "features", "angle": 30}', "missing"),
    ('{"op": "features", "on": 1}', "true or false"),
    ('{"op": "features", "on": "true"}', "true or false"),
    ('{"op": "features", "on": null}', "true or false"),
    ('{"op": "features", "on": [true]}', "true or false"),
    ('{"op": "features", "on": true, "angle": -0.5}', "angle"),
    ('{"op": "features", "on": true, "angle": 180.001}', "angle"),
    ('{"op": "features", "on": true, "angle": -1e308}', "angle"),
    ('{"op": "features", "on": true, "angle": NaN}', "finite"),
    ('{"op": "features", "on": true, "angle": Infinity}', "finite"),
    ('{"op": "features", "on": true, "angle": -Infinity}', "finite"),
    ('{"op": "features", "on": true, "angle": 1e400}', "finite"),
    ('{"op": "features", "on": true, "angle": ' + "9" * 400 + "}", "angle"),
    ('{"op": "features", "on": true, "angle": ' + "9" * 5000 + "}", "JSON"),
    ('{"op": "features", "on": true, "angle": "30"}', "angle must be a number"),
    ('{"op": "features", "on": true, "angle": true}', "angle must be a number"),
    ('{"op": "features", "on": true, "angle": null}', "angle must be a number"),
    ('{"op": "features", "on": true, "angle": [30]}', "angle must be a number"),
    ('{"op": "features", "on": true, "angle": {"deg": 30}}', "angle must be a number"),
    ('{"op": "features", "on": true, "marked": "yes"}', "true or false"),
    ('{"op": "features", "on": true, "marked": 0}', "true or false"),
    ('{"op": "features", "on": true, "feature_angle": 30}', "unknown field"),
    ('{"op": "features", "on": true, "sharp_edges": [[0, 1]]}', "unknown field"),
    ('{"op": "features", "on": true, "marked": true}', "marks no sharp edge"),   # this box marks none
    ('{"op": "features", "on": true, "id": -3}', "id"),
]


def test_malformed_feature_messages_are_one_line_errors_and_change_nothing(server):
    s = server.session
    s.set_features(True, 45.0)

    async def script(ws, other):
        before = (s.features, s.version, s.family_status().lams, s.vertices)
        for i, (text, words) in enumerate(HOSTILE, start=100):
            await ws.send_str(text)
            while True:
                m = await ws.receive(timeout=60)
                if m.type == aiohttp.WSMsgType.TEXT and json.loads(m.data)["type"] == "error":
                    err = json.loads(m.data)["message"]
                    break
                assert m.type == aiohttp.WSMsgType.BINARY or json.loads(m.data)["type"] in ("mesh", "state",
                                                                                          "features")
            assert words.lower() in err.lower() and "\n" not in err and len(err) < 300, (text[:60], err)
            assert "Traceback" not in err
        assert s.features == before[0] and s.version == before[1] and s.family_status().lams == before[2]
        assert np.array_equal(s.vertices, before[3])
        await ws.send_str('{"op": "features", "on": true, "angle": 60, "id": 7}')      # the tab still works
        texts, _ = await collect(ws, 7)
        assert texts[-1]["type"] == "done" and features_of(texts)[-1]["angle"] == 60.0

    run(server, script)


def test_a_file_that_marks_edges_offers_them_and_the_setting_carries_over(server, tmp_path):
    box, sides = box_parts()
    body = obj_with_groups(box, sides, tmp_path / "groups.obj").read_bytes()
    server.session.set_features(True, 50.0)

    async def script(ws, other):
        await ws.send_str('{"op": "lam", "value": 0, "id": 1}')
        await collect(ws, 1)
        req = urllib.request.Request(server.link("open", name="groups.obj"), data=body)
        await asyncio.get_running_loop().run_in_executor(None, lambda: urllib.request.urlopen(req, timeout=60))
        while True:
            m = await ws.receive(timeout=60)
            if m.type == aiohttp.WSMsgType.TEXT and json.loads(m.data)["type"] == "features":
                opened = json.loads(m.data)
                break
        # the new file: "on" and the angle carried over, its marks offered, not kept unasked
        assert (opened["on"], opened["angle"], opened["marked"], opened["marked_count"]) == (True, 50.0, False, 12 * K)
        await ws.send_str('{"op": "features", "on": true, "angle": 180, "marked": true, "id": 2}')
        texts, pairs = await collect(ws, 2)
        assert texts[-1]["type"] == "done" and len(pairs[-1]) == 12 * K

    run(server, script)
    s = server.session
    assert s.marked_count == 12 * K and s.features == {"on": True, "angle": 180.0, "marked": True}
    assert s.wait_family(120).state == "done"
    assert flatness(s.shape_at(-120.0), sides) <= 1e-9 * DIAG
