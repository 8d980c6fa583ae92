"""A generated dataset for the batch tests: good meshes in mixed formats and folders, and bad files."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
from meshgen import cube_sphere, grid, icosphere, ngon_disk

import shapeflow as sf

FORMATS = (".obj", ".ply", ".off", ".stl")


def good_meshes(n: int):
    for i in range(n):
        kind = i % 4
        if kind == 0:
            yield cube_sphere(3 + i % 5, mix=0.3 * (i % 3) / 2, seed=i)
        elif kind == 1:
            yield icosphere(1 + i % 2)
        elif kind == 2:
            yield grid(5 + i % 4, jitter=0.1, seed=i, mix=0.5, z=lambda x, y: 0.1 * np.sin(x) * np.cos(y))
        else:
            yield ngon_disk(5 + i % 4, rings=2 + i % 2)


def make_dataset(root: Path, n_good: int = 42) -> tuple[list[Path], dict[Path, str]]:
    """``(good files, {bad file: a word its error must contain})`` under ``root``."""
    good = []
    for i, mesh in enumerate(good_meshes(n_good)):
        folder = root / ("a" if i % 3 == 0 else "b/c" if i % 3 == 1 else "")
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / f"m{i:02d}{FORMATS[i % len(FORMATS)]}"
        sf.save(path, mesh)
        good.append(path)
    bad = {}
    (root / "bad").mkdir(exist_ok=True)
    p = root / "bad" / "empty.obj"
    p.write_bytes(b"")
    bad[p] = "empty"
    p = root / "bad" / "corrupt.ply"
    p.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                  b"property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                  + struct.pack("<9f", *range(9)) + b"\x03" + struct.pack("<3i", 0, 1, 7))
    bad[p] = "7"           # the face's index out of range is named
    p = root / "bad" / "huge.ply"
    p.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000\nproperty float x\n"
                  b"property float y\nproperty float z\nend_header\n" + b"\0" * 24)
    bad[p] = "1000000000000"
    p = root / "bad" / "noise.off"
    p.write_bytes(np.random.default_rng(0).bytes(300))
    bad[p] = "noise.off"
    p = root / "bad" / "points.ply"
    sf.save(p, sf.Mesh(np.random.default_rng(1).random((5, 3)), []))
    bad[p] = "no faces"
    (root / "README.txt").write_text("not a mesh: a folder run leaves it out\n")
    return good, bad
