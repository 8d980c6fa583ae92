"""OpenUSD layers, opened and checked before a stage is composed from them (see :mod:`.usd`).

Files that refer to other files: the file's own layer is opened first (``Sdf.Layer``, no
composition) and every path it refers to is checked before any stage is composed.  With
``external_files=False`` any such path is refused (sublayers, references, payloads, value clips,
asset-valued attributes and metadata).  With ``True`` the layers it composes (sublayers,
references, payloads, clips' ``assetPaths`` and ``manifestAssetPath``) must be USD files inside
the file's own folder, after following symbolic links: absolute paths, ``..`` leaving the folder,
links out of it, devices, URIs, format arguments, variable expressions and clip templates are
refused, naming the path; those layers are checked the same way, then the stage is composed from
the very layers that were checked.
"""

from __future__ import annotations

import contextlib
import os
import re
import stat
import subprocess
import sys
import threading
import warnings

from ..errors import DataLossWarning, MeshError, OptionalDependencyError

__all__ = ["pxr_modules", "pxr_error", "pxr_diagnostics", "open_stage", "LAYER_EXTENSIONS", "MAX_LAYERS"]

#: the layers a USD file may compose (other formats could refer to files that are not checked)
LAYER_EXTENSIONS = (".usd", ".usda", ".usdc")
#: at most this many layers are opened for one file
MAX_LAYERS = 1000


def pxr_modules():
    try:
        from pxr import Gf, Sdf, Usd, UsdGeom, Vt
    except Exception as exc:   # not installed, or installed and broken
        raise OptionalDependencyError("usd-core", "usd", "reading and writing USD", exc) from exc
    return Usd, UsdGeom, Sdf, Gf, Vt


def pxr_error(exc: Exception) -> str:
    try:
        text = " ".join(str(exc).split())
    except UnicodeError:      # pxr's message quotes bytes of the file that are not UTF-8
        text = "a message quoting bytes that are not UTF-8"
    return f"{type(exc).__name__}: {text[:200]}"


_DIAGNOSING = threading.local()
_DIAGNOSTICS_LOCK = threading.RLock()
_LAYER_IDS = re.compile(r"@[^@\n]*@(?:,@[^@\n]*@)*(?=<)")      # a layer stack's ids before a prim path
_LAYER_PATH = re.compile(r"@([^@\n]*)@")
_INSTANTIATING = re.compile(r"\s*\(instantiating stage on stage .*\)\s*$", re.S)


def _tidy(commentary: str) -> str:
    """A pxr diagnostic in one line: layer stacks before prim paths dropped, layers by their file
    names, whitespace joined."""
    text = _INSTANTIATING.sub("", _LAYER_IDS.sub("", str(commentary)))
    text = _LAYER_PATH.sub(lambda m: f"@{os.path.basename(m.group(1))}@", text)
    text = " ".join(text.replace(":\n", ": ").split())
    return text if len(text) <= 300 else text[:297] + "..."


@contextlib.contextmanager
def pxr_diagnostics(name: str, doing: str):
    """Within the block, pxr's warnings and errors (which it prints on stderr otherwise, many lines
    each) are collected by a ``UsdUtils.CoalescingDiagnosticDelegate``; on leaving it a composition
    cycle is a MeshError naming the prims, and anything else reported is one DataLossWarning
    (``doing``: "reading", "writing"; ``name`` starts the messages unless empty).  A delegate sees
    every thread's diagnostics: one block at a time in the process, and a block inside another
    leaves them to the outer one."""
    if getattr(_DIAGNOSING, "active", False):
        yield
        return
    from pxr import UsdUtils

    with _DIAGNOSTICS_LOCK:
        _DIAGNOSING.active = True
        delegate = UsdUtils.CoalescingDiagnosticDelegate()
        try:
            yield
            found = delegate.TakeUncoalescedDiagnostics()
        finally:
            delegate = None          # unregistered when destroyed: pxr prints on stderr again
            _DIAGNOSING.active = False
    said = [_tidy(d.commentary) for d in found if "STATUS" not in str(d.diagnosticCodeString)]
    name = f"{name}: " if name else ""
    cycles = [t for t in said if "cycle" in t.lower()]       # "Cycle detected", "has cycles" (sublayers)
    if cycles:
        more = f" ({len(cycles)} cycles)" if len(cycles) > 1 else ""
        raise MeshError(f"{name}the USD stage's composition has a cycle{more}: {cycles[0]}")
    if said:
        more = f" (and {len(said) - 1} more)" if len(said) > 1 else ""
        warnings.warn(DataLossWarning(f"{name}the USD library (pxr) reported a problem {doing} the stage: "
                                      f"{said[0]}{more}"), stacklevel=4)


# --------------------------------------------------------------------------
# the files a layer refers to, checked before anything is composed
# --------------------------------------------------------------------------

#: seconds a crate file's trial opening may take
PROBE_SECONDS = 120.0
_PROBE = """import sys
try:
    import resource
except ImportError:          # no address-space limits here (Windows): only the time limit holds
    resource = None
if resource is not None:
    limit = int(sys.argv[2])
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    for bound in (soft, hard):
        if bound != resource.RLIM_INFINITY:
            limit = min(limit, bound) if limit else bound
    if limit:
        resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
from pxr import Sdf
try:
    Sdf.Layer.FindOrOpen(sys.argv[1])
except Exception:
    pass                    # an error pxr reports: the opening in the parent names it
"""


def _is_crate(path: str) -> bool:
    try:
        with open(path, "rb") as f:
            return f.read(8) == b"PXR-USDC"
    except OSError:
        return False


def _probe_crate(path: str, name: str, what: str) -> None:
    """Open a binary crate file once in a child process first, its address space limited to the
    memory this machine has available: some damaged crates make usd-core allocate without bound
    (~20 GB for a 3 KB file) or end the whole process (an uncaught ``std::bad_alloc`` in one of its
    threads: abort, segfault or exit 127 from its crash handler; usd-core 26.11), which no check in
    this process could catch.  A child that does not end normally, or runs past
    :data:`PROBE_SECONDS`, is a :class:`MeshError`.  Costs one interpreter start and pxr's import
    (~0.3 s)."""
    from ..budget import available_bytes

    room = available_bytes() or 0
    try:
        proc = subprocess.run([sys.executable, "-c", _PROBE, path, str(room)], stdin=subprocess.DEVNULL,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=PROBE_SECONDS)
    except subprocess.TimeoutExpired:
        raise MeshError(f"{name}: {what} takes the USD library (pxr) over {PROBE_SECONDS:.0f} s to open") from None
    if proc.returncode != 0:
        how = f"signal {-proc.returncode}" if proc.returncode < 0 else f"exit status {proc.returncode}"
        raise MeshError(f"{name}: {what} makes the USD library (pxr) crash or run out of memory ({how}): "
                        "a damaged crate file")


def _open_layer(Sdf, path: str, name: str, what: str):
    if _is_crate(path):
        _probe_crate(path, name, what)
    try:
        layer = Sdf.Layer.FindOrOpen(path)
    except Exception as exc:   # pxr raises Tf.ErrorException on a malformed file
        raise MeshError(f"{name}: {what} is not a readable USD file ({pxr_error(exc)})") from exc
    if layer is None:
        raise MeshError(f"{name}: {what} is not a readable USD file")
    return layer


def _asset_paths(value, Sdf):
    """The asset paths held in a metadata or attribute value (dictionaries and arrays walked)."""
    stack = [value]
    while stack:
        v = stack.pop()
        if isinstance(v, _Opaque):
            yield "(a value that cannot be inspected)"
        elif isinstance(v, Sdf.AssetPath):
            if v.path:
                yield v.path
        elif isinstance(v, dict):
            stack.extend(v.values())
        elif isinstance(v, (list, tuple, Sdf.AssetPathArray)):
            stack.extend(v)


def _prim_specs(layer):
    """Every prim spec of the layer, variants' included (an explicit stack: no recursion limit); None
    stands for a child whose spec cannot be found (a damaged file)."""
    stack = [layer.pseudoRoot]
    while stack:
        spec = stack.pop()
        yield spec
        if spec is None:
            return
        stack.extend(spec.nameChildren.values())
        variants = [v for vset in spec.variantSets.values() for v in (vset.variants.values() if vset else [None])]
        stack.extend(v.primSpec if v is not None else None for v in variants)


_COMPOSITION_KEYS = {"references", "payload", "clips", "subLayers", "subLayerOffsets"}


class _Opaque:
    """A metadata value pxr has no Python form of: it cannot be searched for asset paths."""


def _info(spec, key: str):
    try:
        return spec.GetInfo(key)
    except TypeError:
        return _Opaque()


def _references(layer, Sdf, every: bool):
    """(kind, where, path) for the files the layer refers to: composition arcs and clips; with
    ``every`` also asset-valued attributes and metadata."""
    for p in layer.subLayerPaths:
        yield "sublayer", "the layer's subLayers", p
    asset_types = (Sdf.ValueTypeNames.Asset, Sdf.ValueTypeNames.AssetArray)
    for spec in _prim_specs(layer):
        props = [] if spec is None else list(spec.properties)
        if spec is None or any(prop is None for prop in props):   # pxr would abort on it later
            yield "damaged", "" if spec is None else f"<{spec.path}>", ""
            return
        where = f"<{spec.path}>"
        if spec.path != Sdf.Path.absoluteRootPath:
            arcs = ([("reference", spec.referenceList)] if spec.hasReferences else []) + (
                [("payload", spec.payloadList)] if spec.hasPayloads else [])
            for kind, proxy in arcs:
                items = (*proxy.explicitItems, *proxy.addedItems, *proxy.prependedItems, *proxy.appendedItems,
                         *proxy.orderedItems)
                for item in items:
                    if item.assetPath:
                        yield kind, where, item.assetPath
            clips = _info(spec, "clips") if spec.HasInfo("clips") else {}
            if isinstance(clips, _Opaque):
                yield "clip template", where, "(a value that cannot be inspected)"
            for set_name, clip in (clips.items() if isinstance(clips, dict) else ()):
                if isinstance(clip, dict) and clip.get("templateAssetPath"):
                    yield "clip template", f"{where} clip set '{set_name}'", str(clip["templateAssetPath"])
                for key in ("assetPaths", "manifestAssetPath"):
                    for p in _asset_paths(clip.get(key) if isinstance(clip, dict) else None, Sdf):
                        yield "clip", f"{where} clip set '{set_name}'", p
        if not every:
            continue
        for key in spec.ListInfoKeys():
            if key not in _COMPOSITION_KEYS:
                for p in _asset_paths(_info(spec, key), Sdf):
                    yield "asset", f"{where} metadata '{key}'", p
        for prop in props:
            pwhere = f"<{prop.path}>"
            for key in prop.ListInfoKeys():
                if key not in ("default", "timeSamples"):
                    for p in _asset_paths(_info(prop, key), Sdf):
                        yield "asset", f"{pwhere} metadata '{key}'", p
            if isinstance(prop, Sdf.AttributeSpec) and prop.typeName in asset_types:
                values = [prop.default] + [layer.QueryTimeSample(prop.path, t)
                                           for t in layer.ListTimeSamplesForPath(prop.path)]
                for p in _asset_paths(values, Sdf):
                    yield "asset", pwhere, p


def _inside(name: str, folder: str, layer, kind: str, where: str, path: str) -> str:
    """The identifier of the layer ``path`` (found in ``layer``) names, if it is a USD file inside
    ``folder``; otherwise a MeshError naming it."""
    def refuse(why):
        return MeshError(f"{name}: {_layer_name(layer, name)} {where}: the {kind} @{path}@ {why}; "
                         "only USD files inside the file's own folder are composed")
    if path.startswith("`"):
        raise refuse("is a variable expression")
    if kind == "clip template":
        raise refuse("names files by a pattern, which cannot be checked")
    if ":" in path:
        raise refuse("is not a plain relative file path (a URI, a drive or format arguments)")
    if os.path.isabs(path):
        raise refuse("is an absolute path")
    anchored = os.path.normpath(os.path.join(os.path.dirname(layer.realPath), path))
    real = os.path.realpath(anchored)
    if os.path.commonpath([real, folder]) != folder:
        raise refuse("leaves the folder" + ("" if real == os.path.normpath(anchored) else " (a symbolic link)"))
    if os.path.splitext(anchored)[1].lower() not in LAYER_EXTENSIONS:
        raise refuse(f"is not a USD layer ({', '.join(LAYER_EXTENSIONS)})")
    try:
        mode = os.stat(real).st_mode
    except OSError as exc:
        raise refuse(f"cannot be read ({exc.strerror or exc})") from None
    if not stat.S_ISREG(mode):
        raise refuse("is not a regular file")
    return anchored


def _layer_name(layer, name: str) -> str:
    real = os.path.realpath(layer.realPath)
    return "the layer" if real == os.path.realpath(name) else f"layer {os.path.basename(real)!r}"


def _checked_layers(name: str, external_files: bool, Sdf):
    """The file's layer and every layer it composes, each opened only after its path was checked,
    and whether any layer names a file it composes (itself included)."""
    root = _open_layer(Sdf, name, name, "the file")
    folder = os.path.realpath(os.path.dirname(os.path.abspath(name)))
    layers = {os.path.realpath(root.realPath): root}
    queue = [root]
    composes = False
    while queue:
        layer = queue.pop()
        try:
            found = list(_references(layer, Sdf, every=not external_files))
        except (RuntimeError, UnicodeError) as exc:   # pxr cannot unpack a value of a damaged file
            raise MeshError(f"{name}: {_layer_name(layer, name)} cannot be read ({pxr_error(exc)})") from exc
        for kind, where, path in found:
            if kind == "damaged":
                what = f"{where} has a property" if where else "has a prim"
                raise MeshError(f"{name}: {_layer_name(layer, name)} {what} whose spec cannot be found "
                                "(a damaged file)")
            if not external_files:
                raise MeshError(f"{name}: {_layer_name(layer, name)} {where} refers to the file @{path}@ ({kind}); "
                                "files that refer to other files are not accepted here")
            if kind == "asset":
                continue
            composes = True
            anchored = _inside(name, folder, layer, kind, where, path)
            real = os.path.realpath(anchored)
            if real in layers:
                continue
            if len(layers) >= MAX_LAYERS:
                raise MeshError(f"{name}: composes more than {MAX_LAYERS} layers")
            dep = _open_layer(Sdf, anchored, name, f"the {kind} @{path}@")
            layers[real] = dep
            queue.append(dep)
    return root, list(layers.values()), composes


def open_stage(name: str, external_files: bool):
    """The composed stage of the file, its root layer, every layer checked and opened for it, and
    whether the stage composes any file (a layer referring to itself does: its text alone, opened
    elsewhere, no longer finds what it refers to)."""
    Usd, _, Sdf, *_ = pxr_modules()
    root, layers, composes = _checked_layers(name, external_files, Sdf)
    try:
        stage = Usd.Stage.Open(root, Usd.Stage.LoadAll)
    except Exception as exc:
        raise MeshError(f"{name}: the USD stage cannot be composed ({pxr_error(exc)})") from exc
    if stage is None:
        raise MeshError(f"{name}: the USD stage cannot be composed")
    checked = {os.path.realpath(x.realPath) for x in layers}
    for used in stage.GetUsedLayers():   # composition opened only what was checked (the session layer aside)
        if not used.anonymous and os.path.realpath(used.realPath) not in checked:
            raise MeshError(f"{name}: composing the stage opened {used.identifier!r}, which was not checked")
    return stage, root, layers, composes
