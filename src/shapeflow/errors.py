"""Exception types.

Every error shapeflow raises on bad input is a :class:`ValueError` subclass, so
``except ValueError`` catches all of them; the message names the offending
shape, index, file or line.
"""

from __future__ import annotations


class ShapeflowError(ValueError):
    """Base class of every input error raised by shapeflow."""


class MeshError(ShapeflowError):
    """A mesh (in memory or in a file) is malformed."""


class ParameterError(ShapeflowError):
    """A parameter (λ, iterations, weights, options...) is out of its domain."""


class OutputError(ShapeflowError, OSError):
    """An output file cannot be written (missing folder, read-only file, bundled data...).

    The message names the path the caller gave (never a temporary file).  It
    is an ``OSError`` too, so ``except OSError`` keeps working.
    """


class OptionalDependencyError(ImportError):
    """An optional feature was used without its extra installed."""

    def __init__(self, module: str, extra: str, feature: str):
        super().__init__(
            f"{feature} needs the optional package '{module}': "
            f"pip install 'shapeflow[{extra}]'"
        )
        self.extra = extra


class DataLossWarning(UserWarning):
    """Something a file or a mesh carried cannot be kept by this format or operation.

    The message names what is lost (``'l' lines (polylines)``, ``corner attribute 'uv'``...);
    the command line prints it as one ``warning:`` line.
    """
