"""The Blender extension of shapeflow: its add-on sources and the build command.

``python -m shapeflow.blender build --output DIR`` writes one Blender 4.2+
extension zip per platform (see :mod:`shapeflow.blender.build`), which users
install with *Edit ▸ Preferences ▸ Get Extensions ▸ ⌄ ▸ Install from Disk*.

The add-on itself lives in ``addon/`` and imports ``bpy``; it runs only inside
Blender, as the extension module ``bl_ext.<repository>.shapeflow``.  Nothing in
this package (nor in the rest of shapeflow) imports ``bpy``.
"""

from .build import PLATFORMS, SCIPY_VERSION, BuildError, build  # noqa: F401

__all__ = ["build", "BuildError", "PLATFORMS", "SCIPY_VERSION"]
