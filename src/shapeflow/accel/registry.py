"""Kernel families and the backends that implement them: the one seam between shapeflow's
algorithms and the code that runs their hot loops.

A *family* is a class of kernels (one per package with hot loops, plus ``"local"`` for the
brush's small systems); its methods are the NumPy/SciPy reference, in ``<package>/kernels.py``.
An *accelerator* (:class:`Accelerator`) implements some families' kernels another way — the
numba one (:mod:`shapeflow.accel.numba_backend`) every kernel, each in the package's
``compiled`` module, as a subclass of the family that overrides its methods.  Code that runs a
kernel asks :func:`shapeflow.accel.kernels` for the implementation of a problem's size and calls its method::

    accel.kernels("mesh", n).edge_data(topology)

and never branches on the backend: an implementation takes the arguments of its family's
method and returns what the reference returns (for the structural choices some families
make, such as the flow's lean layout, the family says so in an attribute).  An implementation
that declines a case (an index type, a layout) calls ``super()``, the reference.

Which implementation: the first accelerator (in :data:`ACCELERATORS` order) that implements
the family, is available, and takes the size under the current :class:`~shapeflow.accel.Backend`
(``kernels="force"``: any size; ``"auto"``: from the family's ``min_size``, else the
accelerator's, else the backend's; ``"off"``: none); else the reference.  The choice depends
only on the settings and the size, so a given problem always takes the same path.

Families and implementations are named here as ``"module:Class"`` strings and imported on
first use: this layer imports nothing above it, and an accelerator's dependencies (numba, a
GPU library) load only when it runs.
"""

from __future__ import annotations

import dataclasses
import importlib
import threading
from collections.abc import Callable, Mapping
from typing import ClassVar

__all__ = ["Family", "Accelerator", "FAMILIES", "ACCELERATORS", "select", "reference", "accelerators", "load"]


class Family:
    """Base of a kernel family: the reference's methods are the NumPy/SciPy kernels.

    ``family`` names it in :data:`FAMILIES`; ``min_size``: the smallest problem an accelerator
    takes under ``kernels="auto"`` (None: the accelerator's or the backend's ``min_size``; 0 for
    families of small problems, such as a brush dab's); ``backend``: the implementation's name.
    """

    family: ClassVar[str] = ""
    min_size: ClassVar[int | None] = None
    backend: ClassVar[str] = "numpy"


@dataclasses.dataclass(frozen=True)
class Accelerator:
    """A backend other than NumPy/SciPy: its name, whether it can run in this process, the
    families it implements (family -> ``"module:Class"``), from what size it pays (None: the
    backend setting's ``min_size``), and a hook run each time one of its implementations is
    handed out (numba: the thread count of the call under way)."""

    name: str
    available: Callable[[], bool]
    families: Mapping[str, str]
    min_size: int | None = None
    activate: Callable[[], None] | None = None


#: every family: name -> ``"module:Class"`` of its NumPy/SciPy reference
FAMILIES = {
    "mesh": "shapeflow.mesh.kernels:MeshKernels",
    "geometry": "shapeflow.geometry.kernels:GeometryKernels",
    "operators": "shapeflow.operators.kernels:OperatorKernels",
    "linalg": "shapeflow.linalg.kernels:LinalgKernels",
    "local": "shapeflow.linalg.kernels:LocalKernels",
    "flow": "shapeflow.flow.kernels:FlowKernels",
    "sculpt": "shapeflow.sculpt.kernels:SculptKernels",
}

#: the accelerators, the preferred first: ``"module:NAME"`` of each :class:`Accelerator`
ACCELERATORS = ("shapeflow.accel.numba_backend:NUMBA",)


def load(ref: str):
    """The object a ``"module:name"`` string names."""
    module, _, name = ref.partition(":")
    return getattr(importlib.import_module(module), name)


_lock = threading.Lock()
_references: dict[str, Family] = {}
_implementations: dict[tuple[str, str], Family] = {}
_accelerators: dict[tuple[str, ...], tuple[Accelerator, ...]] = {}


def reference(family: str) -> Family:
    """The NumPy/SciPy implementation of ``family`` (one instance, kept)."""
    impl = _references.get(family)
    if impl is None:
        if family not in FAMILIES:
            raise ValueError(f"no kernel family {family!r}; the families are {', '.join(FAMILIES)}")
        new = load(FAMILIES[family])()     # imported outside the lock (an import takes its own)
        with _lock:
            impl = _references.setdefault(family, new)
    return impl


def accelerators() -> tuple[Accelerator, ...]:
    """The accelerators :data:`ACCELERATORS` names, loaded (their own modules only, not their kernels)."""
    names = ACCELERATORS
    accs = _accelerators.get(names)
    if accs is None:
        accs = tuple(load(a) for a in names)
        with _lock:
            accs = _accelerators.setdefault(names, accs)
    return accs


def _implementation(acc: Accelerator, family: str) -> Family:
    impl = _implementations.get((acc.name, family))
    if impl is None:
        cls, ref = load(acc.families[family]), type(reference(family))
        if not issubclass(cls, ref):       # a plain class of the methods it accelerates: the rest from the reference
            cls = type(cls.__name__, (cls, ref), {"backend": acc.name})
        new = cls()
        with _lock:
            impl = _implementations.setdefault((acc.name, family), new)
    return impl


def select(family: str, size: int, settings) -> Family:
    """The implementation of ``family`` that runs a problem of ``size`` (vertices or unknowns)
    under ``settings`` (a :class:`~shapeflow.accel.Backend`)."""
    ref = reference(family)
    mode = settings.kernels
    if mode != "off":
        for acc in accelerators():
            if family not in acc.families:
                continue
            if mode == "auto":
                low = ref.min_size if ref.min_size is not None else \
                    acc.min_size if acc.min_size is not None else settings.min_size
                if size < low:
                    continue
            if acc.available():
                if acc.activate is not None:
                    acc.activate()
                return _implementation(acc, family)
    return ref
