"""load()'s contract: every failure of a reader is a MeshError naming the file, chained to its cause;
a missing optional dependency, a warning turned into an error and a programming error are not
disguised as a bad file."""

from __future__ import annotations

import warnings

import pytest

import shapeflow as sf
from shapeflow import io as sio
from shapeflow.errors import DataLossWarning, MeshError, OptionalDependencyError


def _raiser(exc):
    def reader(data, name, **kw):
        raise exc
    return reader


def _register(monkeypatch, reader, external=False):
    fmt = sio.MeshFormat("Test", (".tst",), reader, lambda f, m, binary=None: None, external=external)
    monkeypatch.setitem(sio.FORMATS, ".tst", fmt)


def _deep(n=0):
    return _deep(n + 1)


@pytest.mark.parametrize("exc,words", [
    (MemoryError(), "does not fit in memory"),
    (OSError(13, "Permission denied"), "refers to cannot be read: Permission denied"),
    (AttributeError("'NoneType' object has no attribute 'x'"), "AttributeError: 'NoneType'"),
    (UnicodeDecodeError("utf-8", b"\xff", 0, 1, "invalid start byte"), "UnicodeDecodeError"),
    (RuntimeError("Error in 'Sdf_TextFileFormatParser' at line 48"), "RuntimeError: Error in"),
    (ZeroDivisionError("division by zero"), "ZeroDivisionError"),
    (MeshError("line 3: bad"), "line 3: bad"),                 # a reader's message without the name
], ids=lambda v: type(v).__name__ if isinstance(v, BaseException) else "")
def test_every_reader_failure_is_a_mesh_error_naming_the_file(tmp_path, monkeypatch, exc, words):
    _register(monkeypatch, _raiser(exc))
    p = tmp_path / "x.tst"
    p.write_bytes(b"data")
    with pytest.raises(MeshError) as err:
        sf.load(p)
    assert str(err.value).startswith(f"{p}: ") and words in str(err.value), str(err.value)
    assert err.value.__cause__ is exc


def test_recursion_is_a_mesh_error(tmp_path, monkeypatch):
    _register(monkeypatch, lambda data, name: _deep())
    p = tmp_path / "x.tst"
    p.write_bytes(b"data")
    with pytest.raises(MeshError, match="nested too deeply") as err:
        sf.load(p)
    assert isinstance(err.value.__cause__, RecursionError)


@pytest.mark.parametrize("exc", [OptionalDependencyError("usd-core", "usd", "reading"), NameError("typo"),
                                 DataLossWarning("lost")], ids=lambda e: type(e).__name__)
def test_what_is_not_the_file_s_fault_is_not_disguised(tmp_path, monkeypatch, exc):
    _register(monkeypatch, _raiser(exc))
    p = tmp_path / "x.tst"
    p.write_bytes(b"data")
    with pytest.raises(type(exc)):
        sf.load(p)


@pytest.mark.parametrize("external", [True, False])
def test_external_files_reaches_the_readers_that_take_it(tmp_path, monkeypatch, external):
    seen = []
    _register(monkeypatch, lambda data, name, **kw: seen.append(kw) or sf.Mesh([[0, 0, 0]], []), external=external)
    p = tmp_path / "x.tst"
    p.write_bytes(b"data")
    sf.load(p, external_files=False)
    sf.load(p)
    assert seen == ([{"external_files": False}, {"external_files": True}] if external else [{}, {}])


def test_a_warning_is_still_a_warning(tmp_path, monkeypatch):
    def reader(data, name):
        warnings.warn(DataLossWarning("dropped"), stacklevel=2)
        return sf.Mesh([[0, 0, 0]], [])
    _register(monkeypatch, reader)
    p = tmp_path / "x.tst"
    p.write_bytes(b"data")
    with pytest.warns(DataLossWarning, match="dropped"):
        sf.load(p)
