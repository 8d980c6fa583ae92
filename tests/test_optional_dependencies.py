"""An optional dependency that fails to import, for any reason, is an OptionalDependencyError naming the
cause, and the tests that need it skip naming it too.  Broken packages are simulated: a module on
sys.path whose import raises what a missing system library makes a real one raise."""

from __future__ import annotations

import pickle
import sys

import pytest
from conftest import import_failure, need

import shapeflow as sf
import shapeflow.interop
from shapeflow.cli import main
from shapeflow.errors import OptionalDependencyError

LIBUSB = "libusb-1.0.so.0: cannot open shared object file: No such file or directory"


@pytest.fixture
def broken(tmp_path, monkeypatch):
    """``broken(name, "raise ImportError(...)")``: a package ``name`` whose import runs that statement."""
    def make(name: str, statement: str):
        pkg = tmp_path / "site" / name
        pkg.mkdir(parents=True)
        (pkg / "__init__.py").write_text(statement + "\n")
        monkeypatch.syspath_prepend(str(tmp_path / "site"))
        for mod in [m for m in sys.modules if m == name or m.startswith(name + ".")]:
            monkeypatch.delitem(sys.modules, mod)
    return make


@pytest.mark.parametrize("statement,kind", [
    (f"raise ImportError({LIBUSB!r})", "ImportError"),
    (f"raise OSError({LIBUSB!r})", "OSError"),
])
def test_a_broken_package_is_named_with_its_cause(broken, statement, kind):
    broken("open3d", statement)
    with pytest.raises(OptionalDependencyError) as info:
        sf.interop.to_open3d(sf.load_example("spot_cage"))
    msg = str(info.value)
    assert msg == (f"conversion to open3d needs the optional package 'open3d', which is installed but fails to "
                   f"import: {kind}: {LIBUSB} (install what it names, or reinstall: pip install 'shapeflow[interop]')")
    assert info.value.cause == f"{kind}: {LIBUSB}" and isinstance(info.value, ImportError)


def test_a_missing_package_says_what_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "open3d", None)      # import open3d raises ModuleNotFoundError
    with pytest.raises(OptionalDependencyError) as info:
        sf.interop.to_open3d(sf.load_example("spot_cage"))
    assert str(info.value).startswith("conversion to open3d needs the optional package 'open3d' (import of open3d")
    assert str(info.value).endswith(": pip install 'shapeflow[interop]'")
    assert "fails to import" not in str(info.value)


def test_the_error_survives_pickling_with_its_message():
    exc = OptionalDependencyError("open3d", "interop", "conversion to open3d", ImportError(LIBUSB))
    back = pickle.loads(pickle.dumps(exc))
    assert type(back) is OptionalDependencyError and str(back) == str(exc) and back.extra == "interop"


def test_the_command_line_says_it_in_one_line(broken, tmp_path, capsys):
    broken("pygltflib", "raise ImportError('libfoo.so.3: cannot open shared object file')")
    src = tmp_path / "in.obj"                    # a new glTF document is made with pygltflib
    src.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    assert main(["smooth", str(src), str(tmp_path / "out.glb"), "--strength", "1"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("shapeflow smooth: error: ")
    assert not (tmp_path / "out.glb").exists()
    assert "ImportError: libfoo.so.3: cannot open shared object file" in err


def test_need_skips_naming_the_missing_system_library(broken):
    broken("open3d", f"raise ImportError({LIBUSB!r})")
    with pytest.raises(pytest.skip.Exception) as info:
        need("open3d", "open3d (a test dependency)")
    assert str(info.value.msg) == f"open3d (a test dependency) cannot be imported: ImportError: {LIBUSB}"


def test_need_says_not_installed_for_a_missing_module_and_returns_a_working_one():
    assert import_failure("json") is None
    with pytest.raises(pytest.skip.Exception) as info:
        need("shapeflow_no_such_module_anywhere")
    assert info.value.msg == "shapeflow_no_such_module_anywhere is not installed"
    assert need("json").dumps([1]) == "[1]"
