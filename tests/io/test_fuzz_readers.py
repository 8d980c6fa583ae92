"""A bounded mutation fuzzer (hypothesis, derandomized) over every reader: OBJ, PLY (ASCII, binary
little- and big-endian), OFF, STL (ASCII, binary), USD (text mutations of .usda, byte mutations of
.usdc).  Each mutated file either loads, with finite positions and face indices in range, or raises
a MeshError naming it: no other exception, no crash, no hang.  USD files are read in a child process
(pxr is C++: a crash there must fail the test, not end it; its memory is limited), the others in this
one under a watchdog.
The seed files are written here (shapeflow's writers, pxr); the mutations are tests/mutation.py's."""

from __future__ import annotations

import io
import json
import select
import signal
import struct
import subprocess
import sys
import textwrap
import warnings
from contextlib import contextmanager

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from meshgen import cube_sphere, grid
from mutation import mutate

import shapeflow as sf
from shapeflow.errors import MeshError
from shapeflow.io import FORMATS
from shapeflow.mesh.attributes import Indexed, Labels

HANG = 30          # seconds one small file may take before it counts as a hang
FUZZ = settings(derandomize=True, database=None, deadline=None, print_blob=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                       HealthCheck.function_scoped_fixture])


def _rich_mesh():
    """Quads, triangles and a hexagon with every kind of attribute the writers store."""
    m = grid(5, jitter=0.2, mix=0.3, seed=4, z=lambda x, y: 0.1 * x * y)
    n, c, f = m.n_vertices, m.n_corners, m.n_faces
    rng = np.random.default_rng(1)
    return m.with_attributes(weight=np.linspace(0, 1, n), color=rng.random((n, 3)),
                             flags=rng.integers(0, 200, n).astype(np.uint8)) \
        .with_corner_attributes(uv=Indexed(rng.random((c, 2)), np.arange(c)), normal=rng.random((c, 3))) \
        .with_face_attributes(material=Labels.from_values(["wood", "steel"] * (f // 2) + ["wood"] * (f % 2)),
                              quality=rng.random(f).astype(np.float32))


def _seed_files() -> dict[str, bytes]:
    from shapeflow.io.ply_write import write_ply

    m = _rich_mesh()
    tri = cube_sphere(2, mix=1.0)
    out = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for key, ext, mesh, kw in (("obj", ".obj", m, {}), ("off", ".off", m, {}),
                                   ("ply-ascii", ".ply", m, {"binary": False}), ("ply-binary", ".ply", m, {}),
                                   ("stl-ascii", ".stl", tri, {"binary": False}), ("stl-binary", ".stl", tri, {})):
            buf = io.BytesIO()
            FORMATS[ext].writer(buf, mesh, binary=kw.get("binary"))
            out[key] = buf.getvalue()
        buf = io.BytesIO()
        write_ply(buf, m, byteorder=">")
        out["ply-big-endian"] = buf.getvalue()
    return out


SEEDS = _seed_files()
EXT = {"obj": ".obj", "off": ".off", "ply-ascii": ".ply", "ply-binary": ".ply", "ply-big-endian": ".ply",
       "stl-ascii": ".stl", "stl-binary": ".stl"}
BINARY = {"ply-binary", "ply-big-endian", "stl-binary"}


@contextmanager
def watchdog(path):
    def hang(signum, frame):
        raise AssertionError(f"{path}: no answer after {HANG} s (a hang)")
    old = signal.signal(signal.SIGALRM, hang)
    signal.alarm(HANG)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def check_outcome(path, load):
    """Loads, with finite positions and faces in range, or a MeshError naming the file."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sf.DataLossWarning)
            m = load(path)
    except MeshError as exc:
        assert str(exc).startswith(str(path)), exc
        return "error"
    assert np.isfinite(m.vertices).all()
    assert m.face_indices.size == 0 or (0 <= m.face_indices.min() and m.face_indices.max() < m.n_vertices)
    return "loaded"


OUTCOMES: dict[str, set] = {}


@pytest.mark.parametrize("kind,examples", [("obj", 300), ("off", 200), ("ply-ascii", 200), ("ply-binary", 250),
                                           ("ply-big-endian", 150), ("stl-ascii", 200), ("stl-binary", 200)])
def test_mutated_files_load_or_raise_a_mesh_error(tmp_path, kind, examples):
    seed = SEEDS[kind]
    path = tmp_path / f"case{EXT[kind]}"
    assert check_outcome(_write(path, seed), sf.load) == "loaded"
    n_ops = 7 if kind in BINARY else 6
    seen = OUTCOMES.setdefault(kind, set())

    @settings(FUZZ, max_examples=examples)
    @given(st.data())
    def run(data):
        path.write_bytes(mutate(seed, lambda lo, hi: data.draw(st.integers(lo, hi - 1)), n_ops))
        with watchdog(path):
            seen.add(check_outcome(path, sf.load))

    run()
    assert seen == {"loaded", "error"}, seen          # the mutations make both valid and invalid files


# --------------------------------------------------------------------------
# USD, in a child process
# --------------------------------------------------------------------------

pxr = pytest.importorskip("pxr", reason="usd-core (the 'usd' extra) is not installed")

#: the child's address space: a file that makes pxr allocate without bound fails there (pxr turns most
#: std::bad_alloc into an error) instead of taking the machine's memory
MEMORY = 4 << 30

WORKER = textwrap.dedent(f"""
    import json, resource, sys, warnings
    resource.setrlimit(resource.RLIMIT_AS, ({MEMORY}, {MEMORY}))
    import numpy as np
    import shapeflow as sf
    warnings.simplefilter("ignore")
    for line in sys.stdin:
        path, external = json.loads(line)
        try:
            m = sf.load(path, external_files=external)
            ok = bool(np.isfinite(m.vertices).all()) and (m.face_indices.size == 0 or (
                m.face_indices.min() >= 0 and m.face_indices.max() < m.n_vertices))
            out = ["loaded" if ok else "bad output", ""]
        except sf.MeshError as exc:
            out = ["error" if str(exc).startswith(path) else "unnamed", str(exc)]
        except BaseException as exc:
            out = ["other", f"{{type(exc).__name__}}: {{exc}}"]
        print(json.dumps(out), flush=True)
""")


class Reader:
    """A child process that loads the files it is sent; a crash or a hang is reported, and the next
    file gets a new child."""

    def __init__(self, script: str = WORKER, timeout: float = HANG + 30):   # + the child's start
        self.proc, self.script, self.timeout = None, script, timeout

    def load(self, path: str, external: bool) -> list:
        if self.proc is None or self.proc.poll() is not None:
            self.proc = subprocess.Popen([sys.executable, "-c", self.script], stdin=subprocess.PIPE,
                                         stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        self.proc.stdin.write(json.dumps([path, external]) + "\n")
        self.proc.stdin.flush()
        ready, _, _ = select.select([self.proc.stdout], [], [], self.timeout)
        if not ready:
            self.proc.kill()
            self.proc.wait()
            return ["hang", f"no answer after {self.timeout:g} s"]
        line = self.proc.stdout.readline()
        if not line:
            code = self.proc.wait()
            return ["crash", f"the reader died: {signal.Signals(-code).name if code < 0 else f'exit {code}'}"]
        return json.loads(line)

    def close(self):
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()


@pytest.fixture(scope="module")
def reader():
    r = Reader()
    yield r
    r.close()


def _usd_seeds(folder) -> dict[str, bytes]:
    """A stage with what the reader handles: transforms, a left-handed and a mirrored mesh, st, normals
    and primvars:normals in several interpolations, time samples, a variant, an internal reference."""
    from pxr import Gf, Sdf, Usd, UsdGeom, Vt

    stage = Usd.Stage.CreateInMemory()
    world = UsdGeom.Xform.Define(stage, "/World")
    world.AddTranslateOp().Set(Gf.Vec3d(1, 2, 3))
    m = grid(4, mix=0.4, seed=2)
    for name, left, scale in (("A", False, 1.0), ("B", True, 1.0), ("C", False, -1.0)):
        p = UsdGeom.Mesh.Define(stage, f"/World/{name}")
        p.AddScaleOp().Set(Gf.Vec3f(scale, 1, 1))
        p.GetFaceVertexCountsAttr().Set(Vt.IntArray(m.face_sizes.tolist()))
        p.GetFaceVertexIndicesAttr().Set(Vt.IntArray(m.face_indices.tolist()))
        pts = Vt.Vec3fArray.FromNumpy(m.vertices.astype(np.float32))
        if name == "A":
            p.GetPointsAttr().Set(pts, 1.0)
            p.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy((m.vertices * 2).astype(np.float32)), 2.0)
        else:
            p.GetPointsAttr().Set(pts)
        if left:
            p.GetOrientationAttr().Set(UsdGeom.Tokens.leftHanded)
        pv = UsdGeom.PrimvarsAPI(p.GetPrim())
        pv.CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying).Set(
            Vt.Vec2fArray.FromNumpy(np.random.default_rng(0).random((m.n_corners, 2)).astype(np.float32)))
        n = pv.CreatePrimvar("normals", Sdf.ValueTypeNames.Normal3fArray, UsdGeom.Tokens.vertex)
        n.Set(Vt.Vec3fArray.FromNumpy(np.tile(np.float32([0, 0, 1]), (m.n_vertices, 1))))
        p.GetNormalsAttr().Set(Vt.Vec3fArray([Gf.Vec3f(0, 0, 1)] * m.n_faces))
        p.SetNormalsInterpolation(UsdGeom.Tokens.uniform)
    vs = stage.GetPrimAtPath("/World/B").GetVariantSets().AddVariantSet("look")
    vs.AddVariant("x")
    stage.DefinePrim("/World/D").GetReferences().AddInternalReference("/World/C")
    text = stage.GetRootLayer().ExportToString()
    crate = folder / "seed.usdc"
    stage.GetRootLayer().Export(str(crate))
    return {"usda": text.encode(), "usdc": crate.read_bytes()}


@pytest.mark.parametrize("kind,examples", [("usda", 250), ("usdc", 250)])
def test_mutated_usd_files_load_or_raise_a_mesh_error(tmp_path, reader, kind, examples):
    seed = _usd_seeds(tmp_path)[kind]
    assert reader.load(str(_write(tmp_path / f"seed.{kind}", seed)), False)[0] == "loaded"
    seen = set()
    failures = []

    @settings(FUZZ, max_examples=examples)
    @given(st.data())
    def run(data):
        path = tmp_path / f"case.{kind}"
        path.write_bytes(mutate(seed, lambda lo, hi: data.draw(st.integers(lo, hi - 1)),
                                6 if kind == "usda" else 7))
        external = data.draw(st.booleans())
        outcome, msg = reader.load(str(path), external)
        if outcome not in ("loaded", "error"):
            keep = tmp_path / f"{outcome}-{len(failures)}.{kind}"       # kept for the report
            keep.write_bytes(path.read_bytes())
            failures.append(f"{outcome}: {msg} ({keep})")
        assert outcome in ("loaded", "error"), (outcome, msg)
        seen.add(outcome)

    run()
    assert seen == {"loaded", "error"}, seen


def _write(path, data: bytes):
    path.write_bytes(data)
    return path


@pytest.mark.parametrize("script,outcome", [
    ("import os, signal, sys; sys.stdin.readline(); os.kill(os.getpid(), signal.SIGSEGV)", "SIGSEGV"),
    ("import sys, time; sys.stdin.readline(); time.sleep(60)", "no answer"),
])
def test_the_child_process_harness_reports_crashes_and_hangs(script, outcome):
    r = Reader(script, timeout=2)
    try:
        got = r.load("any.usda", False)
    finally:
        r.close()
    assert got[0] in ("crash", "hang") and outcome in got[1], got


def _damaged_path_table(seed: bytes) -> bytes:
    """The seed crate with 7 bytes of its PATHS section zeroed, as the fuzzer found it (one of 3,000
    byte mutations of this seed, explored outside the test)."""
    toc = struct.unpack_from("<q", seed, 16)[0]
    sections = {struct.unpack_from("<16s", seed, toc + 8 + 32 * k)[0].rstrip(b"\0"):
                struct.unpack_from("<q", seed, toc + 24 + 32 * k)[0]
                for k in range(struct.unpack_from("<Q", seed, toc)[0])}
    at = sections[b"PATHS"] + 131
    if seed[at:at + 7] != bytes.fromhex("150000150004ff"):
        pytest.skip("this usd-core writes the seed's path table differently")
    return seed[:at] + bytes(7) + seed[at + 7:]


def test_a_crate_with_a_damaged_path_table(tmp_path, reader):
    """usd-core 26.11 throws std::bad_alloc in a worker thread on this damaged path table (the process
    aborts): a crate file is opened once in a child process first, whose death is a MeshError."""
    path = _write(tmp_path / "paths.usdc", _damaged_path_table(_usd_seeds(tmp_path)["usdc"]))
    outcome, msg = reader.load(str(path), False)
    assert outcome in ("loaded", "error"), (outcome, msg)


@pytest.mark.parametrize("external", [True, False])
def test_a_crate_naming_a_property_that_has_no_spec_is_refused(tmp_path, reader, external):
    """One byte of the seed zeroed (found by the fuzzer): a prim lists a property whose spec does not
    exist; pxr aborts (Dereferenced an invalid SdfPropertySpec) when it writes such a layer as text,
    so the reader checks every layer's specs first."""
    seed = _usd_seeds(tmp_path)["usdc"]
    if seed[148] != 0x0F:
        pytest.skip("this usd-core writes the seed differently")
    path = _write(tmp_path / "damaged.usdc", seed[:148] + b"\0" + seed[149:])
    outcome, msg = reader.load(str(path), external)
    assert outcome == "error" and "has a property whose spec cannot be found (a damaged file)" in msg, msg
