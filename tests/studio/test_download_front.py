"""What a download drops is told to the page (the writer's DataLossWarning messages in a header, and
GET /losses before downloading), and the axis the model faces is chosen (``front`` message,
``StudioServer(front=)``, ``shapeflow studio --front``): views, mirror plane and ``metadata["front"]``."""

from __future__ import annotations

import json
import urllib.error
import urllib.request

import numpy as np
import pytest
from conftest import run_cli
from meshgen import cube_sphere

import shapeflow as sf

pytest.importorskip("aiohttp", reason="aiohttp (the 'studio' extra) is not installed")

from test_strokes_protocol import answer, run  # noqa: E402

from shapeflow.studio import StudioServer, StudioSession  # noqa: E402
from shapeflow.studio.server import WARNINGS_HEADER  # noqa: E402


@pytest.fixture
def server():
    with StudioServer(sf.load_example("spot"), solve=False) as srv:
        yield srv


def get(srv, path):
    with urllib.request.urlopen(srv.link(path)) as r:
        return r.headers, r.read()


def test_a_download_says_what_its_format_drops_and_losses_says_it_first(server):
    """Spot has quads, UVs and (painted) weights: OFF keeps positions and faces only (a polygon mesh
    format: the quads stay), PLY keeps all three."""
    s = server.session
    s.paint(s.vertices[0], 0.3, value=0.0)
    before = json.loads(get(server, "losses/spot-studio.off")[1])
    headers, body = get(server, "download/spot-studio.off")
    lost = json.loads(headers[WARNINGS_HEADER])
    assert before == {"format": "OFF", "losses": lost} and len(lost) == 1
    assert "not kept" in lost[0] and "'weight'" in lost[0] and "'uv'" in lost[0] and "\n" not in lost[0]
    assert body.startswith(b"OFF") and not s.modified                 # downloaded all the same
    headers, body = get(server, "download/spot-studio.ply")
    assert json.loads(headers[WARNINGS_HEADER]) == [] and body.startswith(b"ply")
    assert json.loads(get(server, "losses/spot-studio.ply")[1]) == {"format": "PLY", "losses": []}
    for bad, code in (("losses/spot.xyz", 400), ("losses/..", 400), ("losses/", 404), ("losses/a%0Ab.ply", 400)):
        with pytest.raises(urllib.error.HTTPError) as e:
            get(server, bad)
        assert e.value.code == code, bad


def test_weights_nobody_painted_are_not_said_lost(server):
    """Nothing painted (every weight the default 1, none in the file): no format is said to drop
    weights and the saved mesh carries none; after painting, OFF says so and PLY keeps them."""
    s = server.session
    lost = json.loads(get(server, "losses/spot-studio.off")[1])["losses"]
    assert lost and not any("'weight'" in m for m in lost) and "'uv'" in lost[0]
    assert s.mesh.weights is None and s.saved_mesh()[0].weights is None
    s.paint(s.vertices[0], 0.3, value=0.25)
    assert any("'weight'" in m for m in json.loads(get(server, "losses/spot-studio.off")[1])["losses"])
    w = s.mesh.weights
    assert w is not None and w.min() == 0.25 and w.max() == 1.0


def test_the_front_message_turns_the_views_and_the_mirror_and_is_kept_in_the_mesh(server):
    s = server.session
    assert s.front == "-z"                                            # the bundled Spot's metadata

    async def script(ws):
        out = []
        for rid, axis in enumerate(["+x", "+y", None], start=1):
            await ws.send_str(json.dumps({"op": "front", "axis": axis, "id": rid}))
            got = await answer(ws, rid)
            out.append([m for m in got if isinstance(m, dict) and m["type"] in ("orientation", "error")])
        return out

    turned, along_up, back = run(server, script)
    o = turned[0]
    assert o["type"] == "orientation" and o["front"] == "+x" and o["up_axis"] == "y"
    np.testing.assert_allclose(o["axes"]["front"], [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(o["axes"]["up"], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(np.abs(o["mirror"]["normal"]), [0, 0, 1], atol=1e-12)   # the plane x·z: across z
    assert o["views"]["front"]["dir"][0] > 0.99                       # the Front view looks from +x
    assert [m["type"] for m in along_up] == ["error"] and "front" in along_up[0]["message"]
    assert back[0]["front"] == "-z" and s.front == "-z"                # null: the file's own again
    assert back[0]["views"]["front"]["dir"][2] < -0.99


def test_the_session_and_server_front():
    spot = sf.load_example("spot")
    s = StudioSession(spot)
    s.front = "+X "                                                    # as the command line would type it
    assert s.front == "+x" and s.mesh.metadata["front"] == "+x"
    np.testing.assert_allclose(s.axes[2], [1, 0, 0], atol=1e-12)
    with pytest.raises(sf.ParameterError, match="front"):
        s.front = "-y"                                                 # along Spot's up axis
    assert s.front == "+x"
    s.front = None
    assert s.front == "-z" and s.mesh.metadata["front"] == "-z"
    bare = cube_sphere(3)                                              # names none: the view rule's default
    assert StudioSession(bare).front is None and "front" not in StudioSession(bare).mesh.metadata
    with StudioServer(bare, solve=False, front="-x") as srv:
        assert srv.session.front == "-x" and srv.result().metadata["front"] == "-x"
    with pytest.raises(sf.ParameterError, match="front"):
        StudioServer(spot, solve=False, front="+y")


@pytest.mark.parametrize("args, match", [
    (["--front", "+y"], "front"),                                     # Spot is y-up
    (["--front", "sideways"], "--front"),
    (["--front", "-z", "--max-upload", "0"], "--max-upload"),          # -z is --front's value: the next error
])
def test_the_command_lines_front_is_checked_before_it_serves(capsys, args, match):
    code, _, err = run_cli(["studio", "example:spot", "--no-browser", *args], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1 and match in err, err


def test_a_downloaded_ply_and_obj_keep_the_front_chosen(server):
    """PLY and OBJ keep metadata["front"] as a comment (read here with plyfile and as text)."""
    import io

    plyfile = pytest.importorskip("plyfile")
    server.session.front = "+x"
    ply = plyfile.PlyData.read(io.BytesIO(get(server, "download/spot-studio.ply")[1]))
    assert "shapeflow front +x" in ply.comments
    obj = get(server, "download/spot-studio.obj")[1].decode()
    assert "# shapeflow front +x" in obj.splitlines()
