"""Reading a file a page uploaded, in a child process bounded in time and memory.

An upload comes from a browser, so from anywhere: it is read by a separate Python process
(``python -m shapeflow.studio.upload``) whose address space is limited once its libraries are
imported (``RLIMIT_AS``, Linux: :func:`memory_limit` more) and which is killed after a time limit
(:func:`time_limit`).  A file that makes a reader run away, or
crash, costs that child, never the studio and its unsaved edits.  The child reads with
``external_files=False``: an uploaded glTF or USD file has no folder of its own, so a reference to
any other file is refused.  What it read comes back pickled through a file in the upload's own
temporary folder; its errors come back as one line.  No message names a temporary path: the file
is called by the name the page gave.
"""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import threading

from ..errors import MeshError

__all__ = ["read_upload", "memory_limit", "time_limit", "stop_readers", "readers_under_way"]

#: the reading children under way (every studio of this process), so that a studio ending kills them
_CHILDREN: set = set()
_LOCK = threading.Lock()


def readers_under_way() -> int:
    """How many reading children are running now."""
    with _LOCK:
        return len(_CHILDREN)


def stop_readers() -> None:
    """Kill every reading child under way (the studio is ending: Ctrl-C must not wait for them)."""
    with _LOCK:
        children = list(_CHILDREN)
    for p in children:
        try:
            p.kill()
        except OSError:
            pass


def memory_limit(size: int, name: str = "") -> int:
    """Memory the child may take for reading a file of ``size`` bytes, beyond what its interpreter and
    libraries hold once imported: 256 MiB (1 GiB for USD, whose library maps its plugins and thread
    pools when it first opens a stage: 512 MiB more than that were measured for a 3 K-vertex stage)
    plus 24 × the file (a text mesh's arrays and their temporaries), at most what the machine has free."""
    from ..budget import available_bytes

    base = (1 << 30) if os.path.splitext(name)[1].lower() in (".usd", ".usda", ".usdc") else (256 << 20)
    want = base + 24 * int(size)
    room = available_bytes()
    return want if room is None else max(min(want, room), 64 << 20)


def time_limit(size: int) -> float:
    """Seconds the child may take: 60 plus 1 per MiB (text formats read at 20–100 MiB/s here)."""
    return 60.0 + size / float(1 << 20)


def read_upload(path: str, name: str, *, kind: str = "mesh", n_vertices: int = 0,
                memory: int | None = None, seconds: float | None = None):
    """The mesh (``kind="mesh"``) or weights (``kind="weights"``: a ``.npy``/``.txt`` file or a mesh's
    ``weight`` attribute, ``n_vertices`` of them) in the uploaded file ``path``, read by a bounded
    child process.  Every failure is a :class:`~shapeflow.errors.MeshError` naming ``name``."""
    size = os.path.getsize(path)
    memory = memory_limit(size, name) if memory is None else int(memory)
    seconds = time_limit(size) if seconds is None else float(seconds)
    out = path + ".result"
    cmd = [sys.executable, "-m", "shapeflow.studio.upload", kind, str(int(n_vertices)), str(memory), path, out]
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
           "NUMBA_NUM_THREADS": "1", "PYTHONWARNINGS": "ignore"}
    proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    with _LOCK:
        _CHILDREN.add(proc)
    try:
        _, err = proc.communicate(timeout=seconds)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
        raise MeshError(f"{name}: reading it took longer than the studio allows ({seconds:.0f} s)") from None
    finally:
        with _LOCK:
            _CHILDREN.discard(proc)
    try:
        if proc.returncode == 0:
            with open(out, "rb") as f:
                return pickle.load(f)
    finally:
        if os.path.exists(out):
            os.unlink(out)
    err = err.decode("utf-8", "replace").strip().splitlines()
    line = err[-1] if err else ""
    if proc.returncode == 3 and line:         # the reader's own refusal
        return _refusal(line, path, name)
    if proc.returncode == 5:
        raise MeshError(f"{name}: no room to read it: the temporary folder is full ({line or 'no space left'})")
    if proc.returncode == 4:
        raise MeshError(f"{name}: reading it needs more memory than the studio allows "
                        f"({memory / 2**20:,.0f} MiB for this file)")
    how = f"signal {-proc.returncode}" if proc.returncode < 0 else f"status {proc.returncode}"
    raise MeshError(f"{name}: the reader failed on this file ({how})")


def _refusal(line: str, path: str, name: str):
    folder = os.path.dirname(path)
    msg = line.replace(path, name).replace(folder + os.sep, "").replace(folder, "")
    if not msg.startswith(name):
        msg = f"{name}: {msg}"
    raise MeshError(msg)


def _limit_memory(extra: int) -> None:
    """Limit this process's address space to what it holds now plus ``extra`` bytes (Linux; elsewhere
    only the time limit holds)."""
    try:
        import resource

        with open("/proc/self/statm") as f:
            now = int(f.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
        resource.setrlimit(resource.RLIMIT_AS, (now + extra, now + extra))
    except (ImportError, ValueError, OSError, IndexError):
        pass


def _import_before_limit(path: str) -> None:
    """Load every library a reader may load lazily (SciPy's BLAS, numba, the format's own library)
    before the address space is limited: OpenBLAS spins, instead of failing, when it cannot map its
    buffers while it loads."""
    import importlib

    names = ["scipy.sparse", "scipy.linalg", "scipy.sparse.linalg", "numba", "numba.np.linalg",
             "shapeflow.io.weights"]
    ext = os.path.splitext(path)[1].lower()
    names += {".gltf": ["pygltflib"], ".glb": ["pygltflib"], ".usd": ["pxr.Usd", "pxr.UsdGeom"],
              ".usda": ["pxr.Usd", "pxr.UsdGeom"], ".usdc": ["pxr.Usd", "pxr.UsdGeom"]}.get(ext, [])
    for name in names:
        try:
            importlib.import_module(name)
        except ImportError:
            pass


def _child(argv: list[str]) -> int:
    kind, n_vertices, memory, path, out = argv
    import warnings

    warnings.simplefilter("ignore")
    from ..io import load

    _import_before_limit(path)
    _limit_memory(int(memory))
    try:
        result = _weights(path, int(n_vertices)) if kind == "weights" else load(path, external_files=False)
        try:
            with open(out, "wb") as f:
                pickle.dump(result, f, protocol=pickle.HIGHEST_PROTOCOL)
        except OSError as exc:             # the temporary folder is full
            print(exc.strerror or exc, file=sys.stderr)
            return 5
        return 0
    except MemoryError:
        return 4
    except ValueError as exc:              # MeshError, ParameterError: the reader's own words
        if isinstance(exc.__cause__, MemoryError):
            return 4
        print(str(exc).replace("\n", " "), file=sys.stderr)
        return 3


def _weights(path: str, n: int):
    """Weights from a ``.npy``/``.txt`` file (``n`` of them) or from a mesh's ``weight`` attribute
    (its vertex count must be ``n``: the session maps them onto its welded vertices)."""
    from ..errors import ParameterError
    from ..io import load
    from ..io.weights import WEIGHT_EXTENSIONS, load_weights

    if os.path.splitext(path)[1].lower() in WEIGHT_EXTENSIONS:
        return load_weights(path, n)
    mesh = load(path, external_files=False)
    name = os.path.basename(path)
    if mesh.weights is None:
        raise ParameterError(f'{name} has no per-vertex "weight" attribute')
    if mesh.n_vertices != n:
        raise ParameterError(f"{name} has {mesh.n_vertices:,} vertices, the studio's mesh {n:,}")
    return mesh.weights


if __name__ == "__main__":
    sys.exit(_child(sys.argv[1:]))
