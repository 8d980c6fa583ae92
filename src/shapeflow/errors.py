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
    """An optional feature was used without its extra installed, or its package fails to import.

    ``cause`` is the exception the import raised (or its text).  A package that is simply not
    installed gives the ``pip install`` line; one that is installed but cannot load (an
    ``ImportError`` or ``OSError`` from a missing system library, such as open3d without
    ``libusb-1.0.so.0``) is named with the original error, so the message says what to fix.
    """

    def __init__(self, module: str, extra: str, feature: str, cause: BaseException | str | None = None):
        why = cause if isinstance(cause, str) or cause is None else _one_line(cause)
        if why and not why.startswith("ModuleNotFoundError"):
            text = (f"{feature} needs the optional package '{module}', which is installed but fails to import: "
                    f"{why} (install what it names, or reinstall: pip install 'shapeflow[{extra}]')")
        else:
            missing = f" ({why.split(': ', 1)[1]})" if why else ""
            text = f"{feature} needs the optional package '{module}'{missing}: pip install 'shapeflow[{extra}]'"
        super().__init__(text)
        self.module, self.extra, self.feature = module, extra, feature
        self.cause = why

    def __reduce__(self):   # picklable (the batch runner sends errors between processes)
        return (type(self), (self.module, self.extra, self.feature, self.cause))


def _one_line(exc: BaseException) -> str:
    return f"{type(exc).__name__}: {' '.join(str(exc).split()) or 'no message'}"


class DataLossWarning(UserWarning):
    """Something a file or a mesh carried cannot be kept by this format or operation.

    The message names what is lost (``'l' lines (polylines)``, ``corner attribute 'uv'``...);
    the command line prints it as one ``warning:`` line.
    """


class SolverWarning(UserWarning):
    """A fast solver path missed its tolerance and the result was computed another way.

    The message names what fell back (a family's members and their λ, ...) and how it was solved
    instead; the result meets its tolerance all the same.
    """
