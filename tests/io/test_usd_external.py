"""USD files that refer to other files: with external_files=False every reference is refused by
name; with True, layers are composed only from USD files inside the file's own folder.  The hostile
files are written here as text (and one as crate, through pxr)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import shapeflow as sf
from shapeflow.errors import MeshError, ParameterError

pytest.importorskip("pxr", reason="usd-core (the 'usd' extra) is not installed")
from pxr import Sdf, Usd, UsdGeom  # noqa: E402

TRI = "point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]\n int[] faceVertexCounts = [3]\n" \
      " int[] faceVertexIndices = [0, 1, 2]"


def usda(head: str = "", prim_meta: str = "", body: str = "", name: str = "M", extra: str = "") -> str:
    head = f"(\n{head}\n)\n" if head else ""
    meta = f" (\n{prim_meta}\n)" if prim_meta else ""
    return f"#usda 1.0\n{head}def Mesh \"{name}\"{meta}\n{{\n {TRI}\n {body}\n}}\n{extra}"


def lib_layer(points="(0, 0, 5), (1, 0, 5), (0, 1, 5)") -> str:
    return (f"#usda 1.0\ndef Mesh \"R\"\n{{\n point3f[] points = [{points}]\n int[] faceVertexCounts = [3]\n"
            " int[] faceVertexIndices = [0, 1, 2]\n}\n")


REFUSED = {   # name -> (root text, files beside it, what the message names)
    "sublayer": (usda(head="subLayers = [@./lib.usda@]"), {"lib.usda": lib_layer()}, "@./lib.usda@"),
    "reference": (usda(extra='def "X" (references = @./lib.usda@</R>) {}\n'), {"lib.usda": lib_layer()},
                  "</X> refers to the file @./lib.usda@ (reference)"),
    "payload": (usda(extra='def "X" (payload = @./lib.usda@</R>) {}\n'), {"lib.usda": lib_layer()},
                "@./lib.usda@ (payload)"),
    "variant reference": (usda(prim_meta='variantSets = "v"\n variants = { string v = "a" }',
                               body='variantSet "v" = { "a" (references = @./lib.usda@</R>) { } }'),
                          {"lib.usda": lib_layer()}, "@./lib.usda@ (reference)"),
    "clip": (usda(prim_meta="clips = { dictionary default = { asset[] assetPaths = [@./clip.usda@] } }"),
             {"clip.usda": lib_layer()}, "@./clip.usda@ (clip)"),
    "clip template": (usda(prim_meta='clips = { dictionary default = { string templateAssetPath = "./c.#.usda" } }'),
                      {}, "@./c.#.usda@ (clip template)"),
    "texture": (usda(body="asset inputs:file = @./wood.png@"), {"wood.png": "png"}, "@./wood.png@ (asset)"),
    "asset array samples": (usda(body="asset[] frames.timeSamples = { 1: [@./f1.png@] }"), {},
                            "@./f1.png@ (asset)"),
    "asset in customData": (usda(prim_meta="customData = { dictionary d = { asset a = @/etc/passwd@ } }"), {},
                            "metadata 'customData' refers to the file @/etc/passwd@"),
    "asset in layer metadata": (usda(head="customLayerData = { asset a = @../../secret.png@ }"), {},
                                "@../../secret.png@"),
    "asset on a property's metadata": (usda(body="float q = 1 (customData = { asset a = @./q.png@ })"), {},
                                       "@./q.png@"),
}


def write(folder, files: dict) -> None:
    for rel, text in files.items():
        p = folder / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)


@pytest.mark.parametrize("case", sorted(REFUSED))
def test_uploads_that_refer_to_files_are_refused_by_name(tmp_path, case):
    root, files, named = REFUSED[case]
    write(tmp_path, files)
    p = tmp_path / "upload.usda"
    p.write_text(root)
    Sdf.Layer.FindOrOpen(str(p))          # pxr itself reads the file: the case is well-formed USD
    with pytest.raises(MeshError) as err:
        sf.load(p, external_files=False)
    msg = str(err.value)
    assert msg.startswith(str(p)) and named in msg and "not accepted" in msg, msg


def test_a_crate_upload_with_a_reference_is_refused(tmp_path):
    write(tmp_path, {"lib.usda": lib_layer()})
    text = tmp_path / "t.usda"
    text.write_text(usda(head="subLayers = [@./lib.usda@]"))
    crate = tmp_path / "upload.usdc"
    Sdf.Layer.FindOrOpen(str(text)).Export(str(crate))
    with pytest.raises(MeshError, match=r"upload\.usdc: .*@\./lib\.usda@ \(sublayer\)"):
        sf.load(crate, external_files=False)


@pytest.mark.parametrize("ext", [".usda", ".usdc"])
def test_a_self_contained_upload_is_read(tmp_path, ext):
    src = tmp_path / "t.usda"
    src.write_text(usda(extra='def Mesh "Y" (references = </M>) {}\n'))     # an internal reference
    p = tmp_path / f"upload{ext}"
    Sdf.Layer.FindOrOpen(str(src)).Export(str(p))
    m = sf.load(p, external_files=False)
    assert m.n_faces == 2 and m.face_attributes["object"].tolist() == [0, 1]


def test_external_files_is_a_flag(tmp_path):
    p = tmp_path / "m.usda"
    p.write_text(usda())
    with pytest.raises(ParameterError, match="external_files"):
        sf.load(p, external_files="no")


def test_formats_that_refer_to_files_are_marked():
    from shapeflow.io import FORMATS

    assert {e for e, f in FORMATS.items() if f.external} == {".gltf", ".glb", ".usd", ".usda", ".usdc"}


# --- external_files=True: composition inside the folder only ----------------------------------------

def test_layers_inside_the_folder_are_composed(tmp_path):
    write(tmp_path, {"parts/lib.usda": lib_layer(), "parts/more.usda": usda(name="S", head="subLayers = [@../c.usda@]"),
                     "c.usda": lib_layer("(0, 0, 9), (1, 0, 9), (0, 1, 9)").replace('"R"', '"C"')})
    p = tmp_path / "scene.usda"
    p.write_text(usda(head="subLayers = [@parts/more.usda@]",
                      extra='def "X" (references = @./parts/lib.usda@</R>) {}\n'))
    m = sf.load(p)
    stage = Usd.Stage.Open(str(p))       # pxr's own composition of the same files
    want = np.concatenate([np.asarray(UsdGeom.Mesh(q).GetPointsAttr().Get(), np.float64)
                           for q in stage.Traverse() if q.IsA(UsdGeom.Mesh)])
    np.testing.assert_array_equal(m.vertices, want)
    assert {5.0, 9.0} <= set(m.vertices[:, 2].tolist())


def test_sublayer_cycles_terminate(tmp_path):
    """Each layer is opened once; pxr's report of the cycle is a MeshError (tests/io/test_usd_diagnostics)."""
    write(tmp_path, {"b.usda": usda(name="B", head="subLayers = [@./a.usda@]")})
    p = tmp_path / "a.usda"
    p.write_text(usda(head="subLayers = [@./b.usda@]"))
    with pytest.raises(MeshError, match=r"composition has a cycle: Sublayer hierarchy with root layer @b.usda@ has "
                                        r"cycles"):
        sf.load(p)


@pytest.fixture
def outside(tmp_path):
    d = tmp_path / "elsewhere"
    d.mkdir()
    (d / "lib.usda").write_text(lib_layer())
    return d / "lib.usda"


ESCAPES = {   # name -> (arc text in the root, set-up, what the message says)
    "absolute": ("@{outside}@", None, "is an absolute path"),
    "dot-dot": ("@../elsewhere/lib.usda@", None, "leaves the folder"),
    "symlink out": ("@./link.usda@", lambda d, o: (d / "link.usda").symlink_to(o),
                    "leaves the folder (a symbolic link)"),
    "symlinked folder": ("@./sub/lib.usda@", lambda d, o: (d / "sub").symlink_to(o.parent), "a symbolic link"),
    "proc": ("@/proc/self/environ@", None, "is an absolute path"),
    "device link": ("@./zero.usda@", lambda d, o: (d / "zero.usda").symlink_to("/dev/zero"), "leaves the folder"),
    "fifo": ("@./pipe.usda@", lambda d, o: os.mkfifo(d / "pipe.usda"), "is not a regular file"),
    "missing": ("@./nothing.usda@", None, "cannot be read"),
    "not a layer": ("@./mesh.obj@", lambda d, o: (d / "mesh.obj").write_text("v 0 0 0\n"), "is not a USD layer"),
    "uri": ("@http://example.com/lib.usda@", None, "not a plain relative file path"),
    "format args": ("@./in.usda:SDF_FORMAT_ARGS:a=b@", lambda d, o: (d / "in.usda").write_text(lib_layer()),
                    "not a plain relative file path"),
    "expression": ('@`"./${X}.usda"`@', None, "is a variable expression"),
}


@pytest.mark.parametrize("arc", ["sublayer", "reference", "payload"])
@pytest.mark.parametrize("case", sorted(ESCAPES))
def test_arcs_leaving_the_folder_are_refused(tmp_path, outside, case, arc):
    path, setup, named = ESCAPES[case]
    d = tmp_path / "in"
    d.mkdir()
    if setup:
        setup(d, outside)
    path = path.replace("{outside}", str(outside))
    text = (usda(head=f"subLayers = [{path}]") if arc == "sublayer" else
            usda(extra=f'def "X" ({"references" if arc == "reference" else "payload"} = {path}</R>) {{}}\n'))
    p = d / "scene.usda"
    p.write_text(text)
    with pytest.raises(MeshError) as err:
        sf.load(p)
    msg = str(err.value)
    assert msg.startswith(str(p)) and named in msg and f"the {arc}" in msg, msg


def test_a_layer_inside_refers_outside(tmp_path, outside):
    d = tmp_path / "in"
    arc = 'def Mesh "R" (references = @../../elsewhere/lib.usda@</R>)'
    write(d, {"ok.usda": lib_layer().replace('def Mesh "R"', arc)})
    p = d / "scene.usda"
    p.write_text(usda(head="subLayers = [@./ok.usda@]"))
    with pytest.raises(MeshError, match=r"scene\.usda: layer 'ok\.usda' </R>: the reference "
                                        r"@\.\./\.\./elsewhere/lib\.usda@ leaves the folder"):
        sf.load(p)


def test_a_clip_template_is_refused_and_clips_inside_are_read(tmp_path):
    d = tmp_path
    clip = "#usda 1.0\ndef Mesh \"M\"\n{\n point3f[] points.timeSamples = { 0: [(0, 0, 2), (1, 0, 2), (0, 1, 2)] }\n}\n"
    write(d, {"clip.usda": clip})
    p = d / "scene.usda"
    p.write_text(usda(prim_meta='clips = { dictionary default = { string templateAssetPath = "./c.#.usda" } }'))
    with pytest.raises(MeshError, match="clip template @./c.#.usda@ names files by a pattern"):
        sf.load(p)
    p.write_text(usda(prim_meta="clips = { dictionary default = { asset[] assetPaths = [@./clip.usda@]\n"
                                " double2[] active = [(0, 0)]\n string primPath = \"/M\" } }")
                 .replace(TRI.split("\n")[0], ""))
    ok = sf.load(p)
    stage = Usd.Stage.Open(str(p))
    want = UsdGeom.Mesh(stage.GetPrimAtPath("/M")).GetPointsAttr().Get(0)
    np.testing.assert_array_equal(ok.vertices, np.asarray(want, np.float64))


DEVICE = textwrap.dedent("""
    import resource, sys
    resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))
    import shapeflow as sf
    try:
        sf.load(sys.argv[1])
    except sf.MeshError as exc:
        print("MeshError:", exc)
""")


def test_a_link_to_an_endless_device_is_never_read(tmp_path):
    (tmp_path / "zero.usda").symlink_to("/dev/zero")
    p = tmp_path / "scene.usda"
    p.write_text(usda(head="subLayers = [@./zero.usda@]"))
    r = subprocess.run([sys.executable, "-c", DEVICE, str(p)], capture_output=True, text=True, timeout=120)
    assert r.stdout.startswith("MeshError:") and "leaves the folder (a symbolic link)" in r.stdout, r.stdout + r.stderr
