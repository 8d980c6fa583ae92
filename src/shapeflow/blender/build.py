"""Build the Blender extension zip(s): add-on code, manifest and bundled wheels.

Runs on any Python >= 3.11 with pip; it never imports ``bpy``.

What goes into one zip (the Blender 4.2+ extension layout)::

    blender_manifest.toml          rendered from addon/blender_manifest.toml
    __init__.py, *.py              the add-on (src/shapeflow/blender/addon/)
    wheels/shapeflow-X-py3-none-any.whl
    wheels/scipy-X-cp311-cp311-PLATFORM.whl

* **No numpy wheel**: Blender 4.2–5.0 ship numpy themselves (4.2: 1.24.3,
  5.0: 1.26.4; ``bpy==5.0.1`` requires ``numpy>=1.26,<2``).  A second numpy
  in the extension's site-packages would shadow Blender's own and break every
  other add-on compiled against it, so the extension relies on Blender's.
* **scipy** is pinned to :data:`SCIPY_VERSION`: the newest release whose wheels
  accept numpy 1.24 at run time (scipy 1.16+ needs numpy >= 1.25.2, which
  Blender 4.2 lacks), with cp311 wheels for every platform Blender 4.2–5.0
  runs on (all of them use Python 3.11).
* **shapeflow** itself is packed as a pure-Python wheel straight from the
  installed package directory (``shapeflow.__file__``), minus this
  ``blender`` subpackage, with the installed distribution's metadata.  This is
  what ``pip wheel --no-deps .`` produces, but needs no build backend, no
  network and no source checkout, and is byte-for-byte reproducible (fixed
  timestamps, sorted entries).

One zip per platform (``shapeflow-VERSION-linux_x64.zip`` ...), each
declaring its ``platforms``, exactly as Blender's own ``extension build
--split-platforms`` does: a scipy wheel is ~35–40 MB, so a universal zip would
be four times the download for every user.

scipy wheels are fetched with ``pip download --only-binary=:all: --platform
... --python-version 3.11`` into a cache directory (default
``~/.cache/shapeflow/blender-wheels``, or ``$SHAPEFLOW_WHEEL_CACHE``) and
reused from there, so repeated builds are offline; ``wheel_dirs`` (CLI
``--wheel-dir``) lets a build use wheels downloaded elsewhere.
"""

from __future__ import annotations

import base64
import csv
import hashlib
import io
import os
import re
import subprocess
import sys
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["PLATFORMS", "SCIPY_VERSION", "PYTHON_TAG", "BuildResult", "build", "build_shapeflow_wheel",
           "fetch_scipy_wheel", "addon_source_dir", "render_manifest", "default_cache_dir"]

#: scipy bundled in the extension (see the module docstring for why this one)
SCIPY_VERSION = "1.15.3"
#: Blender 4.2–5.0 embed CPython 3.11
PYTHON_VERSION = "3.11"
PYTHON_TAG = "cp311"

#: Blender platform name -> (pip --platform tags, suffix the wheel's platform tag must end with)
PLATFORMS: dict[str, tuple[tuple[str, ...], str]] = {
    "linux-x64": (("manylinux_2_17_x86_64", "manylinux2014_x86_64"), "_x86_64"),
    "windows-x64": (("win_amd64",), "win_amd64"),
    "macos-arm64": (("macosx_12_0_arm64",), "_arm64"),
    "macos-x64": (("macosx_10_13_x86_64",), "_x86_64"),
}

#: fixed timestamp of every zip entry, for reproducible zips
_ZIP_DATE = (2024, 1, 1, 0, 0, 0)
_EXTENSION_ID = "shapeflow"


class BuildError(RuntimeError):
    """A build step failed (message says which and why)."""


def addon_source_dir() -> Path:
    """Directory of the add-on sources (``shapeflow/blender/addon``)."""
    return Path(__file__).resolve().parent / "addon"


def default_cache_dir() -> Path:
    env = os.environ.get("SHAPEFLOW_WHEEL_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "shapeflow" / "blender-wheels"


# --------------------------------------------------------------------------
# deterministic zip writing
# --------------------------------------------------------------------------

def _zinfo(name: str, compress: bool, mode: int = 0o644) -> zipfile.ZipInfo:
    zi = zipfile.ZipInfo(name, date_time=_ZIP_DATE)
    zi.compress_type = zipfile.ZIP_DEFLATED if compress else zipfile.ZIP_STORED
    zi.external_attr = (0o100000 | mode) << 16
    zi.create_system = 3
    return zi


def _record_hash(data: bytes) -> str:
    return "sha256=" + base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()


# --------------------------------------------------------------------------
# the shapeflow wheel
# --------------------------------------------------------------------------

def _package_dir() -> Path:
    import shapeflow

    return Path(shapeflow.__file__).resolve().parent


def _package_files(pkg: Path) -> list[tuple[str, Path]]:
    """(archive name, path) of every file of the package, minus blender/ and caches."""
    out = []
    for p in sorted(pkg.rglob("*")):
        if not p.is_file():
            continue
        rel = p.relative_to(pkg)
        parts = rel.parts
        if parts[0] == "blender" or "__pycache__" in parts or p.suffix in (".pyc", ".pyo"):
            continue
        out.append(("shapeflow/" + rel.as_posix(), p))
    return out


def _metadata(version: str) -> str:
    """METADATA of the installed distribution (core fields), or a minimal one."""
    summary, requires, requires_python = "", ["numpy>=1.24", "scipy>=1.10"], ">=3.11"
    try:
        from importlib.metadata import metadata

        md = metadata("shapeflow")
        summary = md.get("Summary") or ""
        requires = [r for r in (md.get_all("Requires-Dist") or []) if "extra ==" not in r] or requires
        requires_python = md.get("Requires-Python") or requires_python
    except Exception:  # PackageNotFoundError or a broken install: use the defaults
        pass
    lines = ["Metadata-Version: 2.1", "Name: shapeflow", f"Version: {version}"]
    if summary:
        lines.append(f"Summary: {summary}")
    lines.append("License: MIT")
    lines.append(f"Requires-Python: {requires_python}")
    lines += [f"Requires-Dist: {r}" for r in requires]
    return "\n".join(lines) + "\n\n"


def build_shapeflow_wheel(out_dir: Path) -> Path:
    """Pack the installed shapeflow package as ``shapeflow-VERSION-py3-none-any.whl``."""
    import shapeflow

    version = shapeflow.__version__
    pkg = _package_dir()
    files = _package_files(pkg)
    if not any(name == "shapeflow/__init__.py" for name, _ in files):
        raise BuildError(f"{pkg} does not look like the shapeflow package")
    dist_info = f"shapeflow-{version}.dist-info"
    meta = {
        f"{dist_info}/METADATA": _metadata(version).encode(),
        f"{dist_info}/WHEEL": (
            "Wheel-Version: 1.0\nGenerator: shapeflow.blender.build\nRoot-Is-Purelib: true\nTag: py3-none-any\n\n"
        ).encode(),
        f"{dist_info}/top_level.txt": b"shapeflow\n",
    }
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / f"shapeflow-{version}-py3-none-any.whl"
    tmp = path.with_suffix(".tmp")
    record = []
    with zipfile.ZipFile(tmp, "w") as zf:
        for name, p in files:
            data = p.read_bytes()
            zf.writestr(_zinfo(name, True), data)
            record.append((name, _record_hash(data), str(len(data))))
        for name, data in meta.items():
            zf.writestr(_zinfo(name, True), data)
            record.append((name, _record_hash(data), str(len(data))))
        record.append((f"{dist_info}/RECORD", "", ""))
        buf = io.StringIO()
        csv.writer(buf, lineterminator="\n").writerows(record)
        zf.writestr(_zinfo(f"{dist_info}/RECORD", True), buf.getvalue().encode())
    os.replace(tmp, path)
    return path


# --------------------------------------------------------------------------
# scipy wheels
# --------------------------------------------------------------------------

def _wheel_matches(name: str, version: str, platform: str) -> bool:
    tags, suffix = PLATFORMS[platform]
    m = re.fullmatch(r"scipy-([^-]+)-(cp\d+)-(cp\d+)-(.+)\.whl", name)
    if not m or m.group(1) != version or m.group(2) != PYTHON_TAG or m.group(3) != PYTHON_TAG:
        return False
    plat_tags = m.group(4).split(".")
    if platform.startswith("linux"):
        return any(t.startswith("manylinux") and t.endswith(suffix) for t in plat_tags)
    if platform.startswith("windows"):
        return any(t == suffix for t in plat_tags)
    # macOS: never accept a wheel that needs a newer macOS than the one asked for
    want = tags[0]
    want_ver = tuple(int(x) for x in want.split("_")[1:3])
    for t in plat_tags:
        mm = re.fullmatch(r"macosx_(\d+)_(\d+)_(\w+)", t)
        if mm and t.endswith(suffix) and (int(mm.group(1)), int(mm.group(2))) <= want_ver:
            return True
    return False


def _find_wheel(dirs, version: str, platform: str) -> Path | None:
    for d in dirs:
        d = Path(d)
        if not d.is_dir():
            continue
        for p in sorted(d.glob(f"scipy-{version}-*.whl")):
            if _wheel_matches(p.name, version, platform):
                return p
    return None


def fetch_scipy_wheel(platform: str, *, version: str = SCIPY_VERSION, cache_dir: Path | None = None,
                      wheel_dirs=(), offline: bool = False, log=print) -> Path:
    """Path of the scipy wheel for a Blender platform: from ``wheel_dirs``, the cache, or pip."""
    if platform not in PLATFORMS:
        raise BuildError(f"unknown platform {platform!r}; choose from {', '.join(PLATFORMS)}")
    cache = Path(cache_dir) if cache_dir else default_cache_dir()
    found = _find_wheel([*wheel_dirs, cache], version, platform)
    if found is not None:
        return found
    if offline:
        where = ", ".join(str(d) for d in [*wheel_dirs, cache])
        raise BuildError(f"no scipy {version} wheel for {platform} in {where} (and --offline was given)")
    cache.mkdir(parents=True, exist_ok=True)
    tags, _ = PLATFORMS[platform]
    cmd = [sys.executable, "-m", "pip", "download", "--disable-pip-version-check", "--no-deps",
           "--only-binary=:all:", "--python-version", PYTHON_VERSION, "--implementation", "cp",
           "--abi", PYTHON_TAG, "-d", str(cache)]
    for t in tags:
        cmd += ["--platform", t]
    cmd.append(f"scipy=={version}")
    log(f"downloading scipy {version} for {platform} ...")
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        tail = "\n".join((proc.stderr or proc.stdout).strip().splitlines()[-5:])
        raise BuildError(f"pip download of scipy=={version} for {platform} failed:\n{tail}")
    found = _find_wheel([cache], version, platform)
    if found is None:
        raise BuildError(f"pip downloaded no matching scipy {version} wheel for {platform} into {cache}")
    return found


# --------------------------------------------------------------------------
# manifest and zip
# --------------------------------------------------------------------------

def _toml_list(items) -> str:
    return "[" + ", ".join(f'"{x}"' for x in items) + "]"


def render_manifest(version: str, platforms, wheels) -> str:
    """The manifest template with version, platforms and wheels filled in."""
    template = (addon_source_dir() / "blender_manifest.toml").read_text(encoding="utf-8")
    out = (template.replace("@VERSION@", version)
           .replace("@PLATFORMS@", _toml_list(platforms))
           .replace("@WHEELS@", _toml_list(f"./wheels/{w}" for w in wheels)))
    left = re.findall(r"@[A-Z_]+@", out)
    if left:
        raise BuildError(f"blender_manifest.toml template has unfilled fields: {', '.join(left)}")
    return out


def _addon_files() -> list[tuple[str, Path]]:
    src = addon_source_dir()
    if not (src / "__init__.py").is_file():
        raise BuildError(f"add-on sources not found in {src}")
    out = []
    for p in sorted(src.rglob("*")):
        rel = p.relative_to(src)
        if not p.is_file() or "__pycache__" in rel.parts or p.suffix in (".pyc", ".pyo"):
            continue
        if rel.as_posix() == "blender_manifest.toml":
            continue
        out.append((rel.as_posix(), p))
    return out


@dataclass
class BuildResult:
    """One built zip."""

    platform: str
    path: Path
    size: int
    wheels: list = field(default_factory=list)   # (name, size)


def build(output, platforms=("all",), *, scipy_version: str = SCIPY_VERSION, cache_dir=None,
          wheel_dirs=(), offline: bool = False, log=print) -> list[BuildResult]:
    """Build one extension zip per platform into ``output``; returns what was written."""
    import shapeflow

    plats = list(platforms)
    if not plats or "all" in plats:
        plats = list(PLATFORMS)
    bad = [p for p in plats if p not in PLATFORMS]
    if bad:
        raise BuildError(f"unknown platform(s) {', '.join(bad)}; choose from {', '.join(PLATFORMS)} or all")
    out_dir = Path(output)
    out_dir.mkdir(parents=True, exist_ok=True)
    version = shapeflow.__version__
    stage = out_dir / ".shapeflow-build"
    sf_wheel = build_shapeflow_wheel(stage)
    addon = _addon_files()
    results = []
    try:
        for plat in dict.fromkeys(plats):
            scipy_wheel = fetch_scipy_wheel(plat, version=scipy_version, cache_dir=cache_dir,
                                            wheel_dirs=wheel_dirs, offline=offline, log=log)
            wheels = [sf_wheel, scipy_wheel]
            manifest = render_manifest(version, [plat], [w.name for w in wheels])
            path = out_dir / f"{_EXTENSION_ID}-{version}-{plat.replace('-', '_')}.zip"
            tmp = path.with_suffix(".zip.tmp")
            with zipfile.ZipFile(tmp, "w") as zf:
                zf.writestr(_zinfo("blender_manifest.toml", True), manifest.encode())
                for name, p in addon:
                    zf.writestr(_zinfo(name, True), p.read_bytes())
                for w in wheels:  # wheels are zips already: store, do not recompress
                    zf.writestr(_zinfo(f"wheels/{w.name}", False), w.read_bytes())
            os.replace(tmp, path)
            res = BuildResult(plat, path, path.stat().st_size, [(w.name, w.stat().st_size) for w in wheels])
            results.append(res)
            log(f"{path}  ({res.size / 2**20:.1f} MiB: add-on + {', '.join(w.name for w in wheels)})")
    finally:
        for p in stage.glob("*"):
            p.unlink()
        stage.rmdir()
    return results
