"""Meshes bundled with shapeflow (``example:NAME`` on the command line)."""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

from .errors import MeshError

if TYPE_CHECKING:
    from .mesh import Mesh

#: name -> (file, description)
EXAMPLES = {
    "spot": ("spot_quad.obj", "Keenan Crane's Spot, 2930 vertices, all quads (public domain)"),
    "spot_cage": ("spot_control_hybrid.obj", "Spot's Catmull-Clark cage: triangles, quads, pentagons (public domain)"),
}


def example_path(name: str) -> Path:
    """Path of a bundled example mesh."""
    if name not in EXAMPLES:
        raise MeshError(f"no bundled example '{name}'; choose from {', '.join(sorted(EXAMPLES))}")
    return Path(str(resources.files("shapeflow") / "data" / EXAMPLES[name][0]))


#: the axis each bundled example faces (Keenan Crane's Spot looks along -z, y up): the renderer's front
FRONT = {"spot": "-z", "spot_cage": "-z"}


def load_example(name: str) -> Mesh:
    """Load a bundled example mesh (``metadata["front"]``: the axis it faces, for the renderer)."""
    from .io import load

    return load(example_path(name)).with_metadata(front=FRONT[name])
