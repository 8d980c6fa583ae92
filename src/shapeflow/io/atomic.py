"""Reading whole files, and writing them atomically (never a half-written or stray file)."""

from __future__ import annotations

import contextlib
import contextvars
import errno
import os
import stat
import tempfile
from typing import BinaryIO, Callable, Iterator

from ..errors import MeshError, OutputError, ParameterError

__all__ = ["as_path", "os_error", "read_bytes", "umask", "bundled_data_dir", "output_target", "atomic_write",
           "side_file", "writing_in"]

#: the folder of the file :func:`atomic_write` is writing (for writers that need a path of their own)
_WRITING_IN: contextvars.ContextVar[str | None] = contextvars.ContextVar("shapeflow_writing_in", default=None)


def as_path(path, what: str = "path") -> str:
    """A file path (str, bytes or os.PathLike) as str; anything else is a ParameterError."""
    try:
        name = os.fspath(path)
    except TypeError:
        raise ParameterError(f"{what} must be a file path (str or os.PathLike), got {path!r}") from None
    return os.fsdecode(name)



def os_error(name: str, exc: OSError) -> MeshError:
    return MeshError(f"{name}: cannot read file: {exc.strerror or exc} ({type(exc).__name__})")


def read_bytes(name: str) -> bytes:
    try:
        # /dev/zero, a FIFO...: no end to trust (and opening a FIFO waits for a writer): checked first
        st = os.stat(name)
        mode = st.st_mode
        if not stat.S_ISREG(mode) and not stat.S_ISDIR(mode):   # a directory: open() names it below
            raise MeshError(f"{name}: not a regular file (a device, pipe or socket); give a file")
        with open(name, "rb") as f:
            return f.read()
    except OSError as exc:
        raise os_error(name, exc) from exc
    except MemoryError as exc:
        raise MeshError(f"{name}: the file does not fit in memory ({st.st_size:,} bytes)") from exc


def umask() -> int:
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)  # no way to read it without setting it
    os.umask(mask)
    return mask


def bundled_data_dir() -> str:
    return os.path.realpath(os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "data"))


def output_target(path, *, force: bool = False) -> str:
    """Check that ``path`` can be written, before any work; returns the file a write replaces.

    A symbolic link is followed to its final target, which is what gets
    replaced (GNU's rule: the link stays a link).  Refused with an
    :class:`~shapeflow.errors.OutputError` naming ``path``: a missing folder,
    a directory, shapeflow's bundled example data (never written), a folder
    without write permission, and a read-only file unless ``force``.
    """
    name = as_path(path)
    if not name:
        raise OutputError("the output path is empty")
    target = os.path.realpath(name)
    folder = os.path.dirname(target)
    if os.path.isdir(target):
        raise OutputError(f"{name}: is a directory, not a file")
    if not os.path.isdir(folder):
        shown = os.path.dirname(name) or folder
        raise OutputError(f"{name}: the output folder {shown!r} does not exist")
    if os.path.commonpath([folder, bundled_data_dir()]) == bundled_data_dir():
        raise OutputError(f"{name}: is shapeflow's bundled example data, which is never written; "
                          "choose another output path")
    try:
        st = os.stat(target)
    except FileNotFoundError:
        st = None
    except OSError as exc:
        raise OutputError(f"{name}: cannot write: {exc.strerror or exc}") from None
    if st is not None and not force and (not st.st_mode & 0o222 or not os.access(target, os.W_OK)):
        raise OutputError(f"{name}: is read-only; pass --force (force=True) to replace it")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputError(f"{name}: cannot write in the folder {folder!r} (permission denied)")
    return target


def atomic_write(name: str, write: Callable[[BinaryIO], None], *, force: bool = False) -> None:
    """Write through ``write(f)`` to an unnamed temporary file, fsync, then rename it onto ``name``.

    The file is created with ``O_TMPFILE`` where the platform has it: it has
    no name until the data is complete, so even a killed process leaves
    nothing behind; it gets a hidden name for the instant of the rename.
    Elsewhere a named temporary file is removed on any exception (the CLI
    turns SIGTERM and SIGHUP into one).  Errors name ``name``, not the
    temporary file.
    """
    target = output_target(name, force=force)
    directory = os.path.dirname(target)
    try:
        mode = stat.S_IMODE(os.stat(target).st_mode)
    except OSError:
        mode = 0o666 & ~umask()
    tmp = None
    try:
        fd = unnamed_file(directory)
        if fd is None:
            fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(target) + ".", suffix=".tmp", dir=directory)
        with os.fdopen(fd, "wb") as f:
            token = _WRITING_IN.set(directory)
            try:
                write(f)
            finally:
                _WRITING_IN.reset(token)
            f.flush()
            os.fchmod(f.fileno(), mode)
            os.fsync(f.fileno())
            if tmp is None:   # give the finished file a name, for the rename only
                tmp = link_unnamed(f.fileno(), directory, os.path.basename(target))
        os.replace(tmp, target)
        tmp = None
    except OSError as exc:
        raise OutputError(f"{name}: cannot write: {exc.strerror or exc}") from exc
    finally:
        if tmp is not None:
            try:
                os.unlink(tmp)
            except OSError:
                pass
    try:  # make the rename durable (best effort, POSIX only)
        dfd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(dfd)
    except OSError:
        pass
    finally:
        os.close(dfd)


def writing_in() -> str | None:
    """The folder of the file :func:`atomic_write` is writing now (None outside it)."""
    return _WRITING_IN.get()


@contextlib.contextmanager
def side_file(suffix: str) -> Iterator[str]:
    """A path for a library that writes only to paths (pxr's crate files): a new hidden file in the
    folder of the file :func:`atomic_write` is writing (never the system's temporary folder, which
    may be full or elsewhere), else in the temporary folder; removed afterwards, whatever happens."""
    fd, path = tempfile.mkstemp(prefix=".shapeflow.", suffix=suffix, dir=_WRITING_IN.get())
    os.close(fd)
    try:
        yield path
    finally:
        with contextlib.suppress(OSError):
            os.unlink(path)


def unnamed_file(directory: str) -> int | None:
    """A file descriptor of a new unnamed file in ``directory`` (Linux ``O_TMPFILE``), or None."""
    flag = getattr(os, "O_TMPFILE", None)
    if flag is None or not os.path.isdir("/proc/self/fd"):
        return None
    try:
        return os.open(directory, flag | os.O_WRONLY, 0o600)
    except OSError as exc:
        if exc.errno in (errno.EOPNOTSUPP, errno.EISDIR, errno.EINVAL, errno.ENOENT):
            return None   # the file system has no unnamed files: a named temporary file instead
        raise


def link_unnamed(fd: int, directory: str, base: str) -> str:
    """Give the unnamed file ``fd`` a fresh hidden name in ``directory``; returns the name."""
    # linkat(..., AT_SYMLINK_FOLLOW): os.link takes that path only when given a dir_fd
    dfd = os.open(directory, os.O_RDONLY)
    try:
        for _ in range(100):
            tmp = os.path.join(directory, f".{base}.{os.urandom(6).hex()}.tmp")
            try:
                os.link(f"/proc/self/fd/{fd}", tmp, src_dir_fd=dfd, follow_symlinks=True)
                return tmp
            except FileExistsError:
                continue
    finally:
        os.close(dfd)
    raise FileExistsError(errno.EEXIST, "no free temporary name", directory)
