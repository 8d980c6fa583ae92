"""The stroke messages and the editing model over a real WebSocket: a stroke (begin … end) is one
undo step, a stroke left open ends at the next other message or when its tab closes, a dab at a
previewed λ applies the preview first, every request is answered to its tab by id, the family's
range from/to/step is the command line's grid with 0, and a download marks the session saved."""

from __future__ import annotations

import asyncio
import json
import urllib.request

import numpy as np
import pytest

import shapeflow as sf

pytest.importorskip("aiohttp", reason="aiohttp (the 'studio' extra) is not installed")

import aiohttp  # noqa: E402
from test_hostile_clients import ws_url  # noqa: E402

from shapeflow.studio import StudioServer  # noqa: E402


@pytest.fixture
def server():
    with StudioServer(sf.load_example("spot"), lams=[0.0, -20.0, -40.0]) as srv:
        srv.session.wait_family(120)
        yield srv


async def answer(ws, rid):
    """The messages up to this tab's answer to request ``rid`` (its ``done`` or ``error``), texts parsed."""
    seen = []
    while True:
        m = await ws.receive(timeout=60)
        if m.type == aiohttp.WSMsgType.TEXT:
            msg = json.loads(m.data)
            seen.append(msg)
            if msg["type"] in ("done", "error") and msg.get("id") == rid:
                return seen
        else:
            seen.append(m.data[:4])


def run(srv, script):
    async def go():
        async with aiohttp.ClientSession() as cs:
            async with cs.ws_connect(ws_url(srv), max_msg_size=0) as ws:
                return await script(ws)
    return asyncio.run(go())


def spot_points(k):
    V = sf.load_example("spot").vertices
    return [V[i].tolist() for i in np.linspace(100, 400, k).astype(int)]


def test_a_stroke_is_one_step_and_every_request_is_answered_by_id(server):
    s = server.session
    start = s.vertices

    async def script(ws):
        msgs = [{"op": "begin"}, *({"op": "dab", "center": c, "radius": 0.2} for c in spot_points(5)), {"op": "end"}]
        for rid, msg in enumerate(msgs, start=7):
            await ws.send_str(json.dumps({**msg, "id": rid}))
        return [[m for m in await answer(ws, rid) if isinstance(m, dict) and m["type"] in ("done", "error")][-1]
                for rid in range(7, 7 + len(msgs))]

    answers = run(server, script)
    assert [(a["type"], a["id"], a["op"]) for a in answers] == [
        ("done", 7, "begin"), *(("done", k, "dab") for k in range(8, 13)), ("done", 13, "end")]
    assert not s.in_stroke and s.modified and not np.array_equal(s.vertices, start)
    assert s.undo() and np.array_equal(s.vertices, start) and not s.can_undo


def test_a_stroke_left_open_ends_at_the_next_other_message_or_when_its_tab_closes(server):
    s = server.session
    start = s.vertices

    async def open_stroke(ws, then=None):
        await ws.send_str(json.dumps({"op": "begin", "id": 1}))
        for k, c in enumerate(spot_points(3), start=2):
            await ws.send_str(json.dumps({"op": "dab", "center": c, "radius": 0.2, "id": k}))
        await answer(ws, 4)
        assert s.in_stroke
        if then is not None:
            await ws.send_str(json.dumps({**then, "id": 5}))
            return await answer(ws, 5)

    got = run(server, lambda ws: open_stroke(ws, {"op": "lam", "value": -20}))
    state = [m for m in got if isinstance(m, dict) and m["type"] == "state"][-1]
    assert not s.in_stroke and not state["stroke"]
    assert s.undo() and np.array_equal(s.vertices, start) and not s.can_undo
    run(server, open_stroke)                                         # the tab closes mid-stroke
    for _ in range(100):
        if not s.in_stroke:
            break
        asyncio.run(asyncio.sleep(0.05))
    assert not s.in_stroke
    assert s.undo() and np.array_equal(s.vertices, start) and not s.can_undo


def test_a_dab_at_a_previewed_lambda_applies_the_preview_first(server):
    s = server.session
    start = s.vertices
    preview = s.shape_at(-40.0)

    async def script(ws):
        await ws.send_str(json.dumps({"op": "lam", "value": -40, "id": 1}))
        await answer(ws, 1)
        await ws.send_str(json.dumps({"op": "dab", "center": preview[200].tolist(), "radius": 0.2, "id": 2}))
        return await answer(ws, 2)

    got = run(server, script)
    state = [m for m in got if isinstance(m, dict) and m["type"] == "state"][-1]
    assert state["lam"] == 0.0 and b"POS0" in got                    # the slider back at 0, every position sent
    moved = np.linalg.norm(s.vertices - preview, axis=1) > 0
    assert 0 < moved.sum() < 200                                      # the dab acted on the preview, near it
    assert s.undo() and np.array_equal(s.vertices, preview)           # the preview applied: a step of its own
    assert s.undo() and np.array_equal(s.vertices, start)


def test_the_family_range_is_the_command_lines_grid_with_zero(server):
    async def script(ws):
        lams = []
        for rid, (a, b, step) in enumerate([(30, -20, -10), (-5, -25, -10), (0, -1, -0.3)], start=1):
            await ws.send_str(json.dumps({"op": "solve", "from": a, "to": b, "step": step, "id": rid}))
            got = await answer(ws, rid)
            lams.append([m for m in got if isinstance(m, dict) and m["type"] == "state"][-1]["lams"])
        return lams

    assert run(server, script) == [[30.0, 20.0, 10.0, 0.0, -10.0, -20.0], [0.0, -5.0, -15.0, -25.0],
                                   [0.0, -0.3, -0.6, -0.9]]


def test_a_download_marks_the_session_saved(server):
    s = server.session
    s.paint(s.vertices[0], 0.3, value=0.0)
    assert s.modified
    body = urllib.request.urlopen(server.link("download/spot.ply")).read()
    assert body.startswith(b"ply") and not s.modified
    s.undo()
    assert s.modified                                                 # the state downloaded had the paint
