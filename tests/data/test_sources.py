"""tests/data/SOURCES.md names every data file of this folder with its size and SHA-256, and the
folder stays small."""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

HERE = Path(__file__).resolve().parent
DATA_SUFFIXES = {".obj", ".npz", ".json", ".txt"}
MAX_BYTES = 6_000_000


def data_files() -> dict[str, Path]:
    return {p.relative_to(HERE).as_posix(): p for p in sorted(HERE.rglob("*"))
            if p.is_file() and p.suffix in DATA_SUFFIXES and "__pycache__" not in p.parts}


def checksum_rows() -> dict[str, tuple[int, str]]:
    text = (HERE / "SOURCES.md").read_text(encoding="utf-8").split("## Checksums", 1)[1]
    rows = re.findall(r"^\| `([^`]+)` \| (\d+) \| `([0-9a-f]{64})` \|$", text, flags=re.M)
    return {name: (int(size), digest) for name, size, digest in rows}


def test_every_data_file_has_its_checksum():
    files, rows = data_files(), checksum_rows()
    assert sorted(rows) == sorted(files)
    for name, path in files.items():
        data = path.read_bytes()
        assert (len(data), hashlib.sha256(data).hexdigest()) == rows[name], name


def test_meshes_and_licences_are_named_in_the_sources():
    text = (HERE / "SOURCES.md").read_text(encoding="utf-8").split("## Checksums", 1)[0]
    for name in data_files():
        if name.startswith(("meshes/", "licenses/")):
            assert f"`{Path(name).name}`" in text or f"`{name}`" in text, name


def test_the_folder_stays_small():
    """Links to the package's own data (the bundled examples) add nothing."""
    added = [p for p in HERE.rglob("*") if p.is_file() and not p.is_symlink() and "__pycache__" not in p.parts]
    assert sum(p.stat().st_size for p in added) < MAX_BYTES
