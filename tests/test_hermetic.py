"""Every test has a temporary folder of its own (tests/conftest.py): TMPDIR, TEMP, TMP and
tempfile.tempdir point at it, for the test and the processes it starts."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path


def test_the_temporary_folder_is_the_tests_own_and_starts_empty(own_temporary_folder, tmp_path):
    folder = str(own_temporary_folder)
    assert tempfile.gettempdir() == folder and os.environ["TMPDIR"] == os.environ["TMP"] == folder
    assert list(own_temporary_folder.iterdir()) == []
    assert own_temporary_folder != tmp_path
    made = Path(tempfile.mkdtemp(prefix="shapeflow-studio-"))
    assert made.parent == own_temporary_folder
    child = subprocess.run([sys.executable, "-c", "import tempfile; print(tempfile.gettempdir())"],
                           capture_output=True, text=True, check=True).stdout.strip()
    assert child == folder


def test_another_test_gets_another_folder(own_temporary_folder):
    assert list(own_temporary_folder.iterdir()) == []          # nothing the test above made
    assert tempfile.gettempdir() == str(own_temporary_folder)
