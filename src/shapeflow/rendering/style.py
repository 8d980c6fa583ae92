"""The look of the pictures: named views, camera, colours."""

from __future__ import annotations

import numpy as np

__all__ = ["VIEWS", "FRAMES", "VIEW_ANGLE", "MARGIN", "CLAY", "EDGE_COLOR", "BACKGROUND", "MSAA_MAX_FACES"]

#: named views: (azimuth, elevation) in degrees about the up axis
VIEWS = {"front": (0.0, 0.0), "side": (90.0, 0.0), "back": (180.0, 0.0), "top": (0.0, 90.0),
         "bottom": (0.0, -90.0), "iso": (35.0, 25.0)}

#: (right, up, front) axes of the model for each ``up`` choice
FRAMES = {
    "y": (np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), np.array([0, 0, 1.0])),
    "z": (np.array([1.0, 0, 0]), np.array([0, 0, 1.0]), np.array([0, -1.0, 0])),
}

VIEW_ANGLE = 20.0   # vertical field of view of the camera, degrees
MARGIN = 0.04       # free border around the framed model, fraction of the panel
CLAY = (0.80, 0.78, 0.74)
EDGE_COLOR = (0.12, 0.12, 0.14)
BACKGROUND = (1.0, 1.0, 1.0)
MSAA_MAX_FACES = 300_000  # larger meshes: FXAA instead of 8x multisampling (speed)
