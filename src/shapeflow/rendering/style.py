"""The look of the pictures: named views, camera, colours."""

from __future__ import annotations

import numpy as np

__all__ = ["VIEWS", "FRAMES", "FRONTS", "DEFAULT_FRONT", "frame", "VIEW_ANGLE", "MARGIN", "CLAY", "EDGE_COLOR",
           "FEATURE_COLOR", "BACKGROUND", "MSAA_MAX_FACES"]

# The view convention is Blender's.  In Blender's frame (z up) a model faces -y, and the front view looks
# at it along +y from -y; "right" looks from +x, "top" from +z (Blender's numpad 1, 3, 7; ctrl for the
# opposite ones).  Views are angles from the model's front: azimuth turns the camera about the up axis
# from the front towards the right, elevation raises it towards the top.  A y-up model (OBJ, PLY, OFF,
# glTF) is seen as Blender's importers turn it (their default forward -Z, up Y: file (x, y, z) is
# Blender's (x, -z, y)), so its front faces +z: glTF's convention and Blender's exporters'.  A mesh
# that faces another way says so with ``metadata["front"]`` (the bundled Spot faces -z) or the
# ``front=`` argument of the renderer.

#: named views: (azimuth, elevation) in degrees from the model's front
VIEWS = {"front": (0.0, 0.0), "right": (90.0, 0.0), "back": (180.0, 0.0), "left": (-90.0, 0.0),
         "top": (0.0, 90.0), "bottom": (0.0, -90.0), "iso": (35.0, 25.0), "side": (90.0, 0.0)}

#: the axis a model faces (the side the front view shows), in the model's own coordinates
FRONTS = {"+x": (1.0, 0, 0), "-x": (-1.0, 0, 0), "+y": (0, 1.0, 0), "-y": (0, -1.0, 0), "+z": (0, 0, 1.0),
          "-z": (0, 0, -1.0)}

#: the front of a model that names none, by its up axis
DEFAULT_FRONT = {"y": "+z", "z": "-y"}


def frame(up: str, front: str | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(right, up, front) unit axes of the model; ``front`` one of :data:`FRONTS` (None: by ``up``)."""
    from ..errors import ParameterError

    if up not in DEFAULT_FRONT:
        raise ParameterError(f"up must be 'y' or 'z', got {up!r}")
    key = DEFAULT_FRONT[up] if front is None else str(front).strip().lower()
    if key not in FRONTS:
        raise ParameterError(f"front must be one of {', '.join(FRONTS)} (the axis the model faces), got {front!r}")
    U = np.array(FRONTS["+" + up])
    F = np.array(FRONTS[key])
    if abs(float(U @ F)) > 0.5:
        raise ParameterError(f"front {key} lies along the up axis {up}; a model faces across it")
    return np.cross(U, F), U, F


#: (right, up, front) axes of the model for each ``up`` choice, when the model names no front
FRAMES = {up: frame(up) for up in DEFAULT_FRONT}

VIEW_ANGLE = 20.0   # vertical field of view of the camera, degrees
MARGIN = 0.04       # free border around the framed model, fraction of the panel
CLAY = (0.80, 0.78, 0.74)
EDGE_COLOR = (0.12, 0.12, 0.14)
FEATURE_COLOR = (0.0, 0.0, 0.0)      # feature lines: black, which stands out on the clay and on every colour map
BACKGROUND = (1.0, 1.0, 1.0)
MSAA_MAX_FACES = 300_000  # larger meshes: FXAA instead of 8x multisampling (speed)
