"""The README's and the Python tour's examples run as written; the README keeps the two commands first."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
CI = ROOT / ".ci" / "run"


@pytest.mark.parametrize("page", ["README.md", "docs/python.md"])
def test_python_examples_run(tmp_path, monkeypatch, page):
    text = (ROOT / page).read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert blocks, f"no python example in {page}"
    monkeypatch.chdir(tmp_path)
    namespace = {"__name__": "example"}
    for code in blocks:
        exec(compile(code, str(ROOT / page), "exec"), namespace)
    import shapeflow as sf

    # a comment that counts shapes counts what the line returns
    for n in re.findall(r"^shapes = .*# (\d+) shapes", text, flags=re.M):
        assert namespace["shapes"].shape[0] == int(n)

    out = sf.load(tmp_path / "spot_enhanced.ply")        # the example's output, read back
    spot = sf.load_example("spot")
    assert out.n_vertices == spot.n_vertices and out.n_faces == spot.n_faces
    assert 0.0 < abs(out.vertices - spot.vertices).max()  # enhanced, not a copy


def test_readme_starts_with_the_two_commands_and_ci_runs_the_test_command():
    text = README.read_text(encoding="utf-8")
    first = re.search(r"```bash\n(.*?)```", text, flags=re.S).group(1).splitlines()
    install, tests = (line.split("#")[0].strip() for line in first[:2])
    assert install.startswith("pip install") and "shapeflow " in install
    assert tests.endswith("python -m pytest -q")
    ci = CI.read_text(encoding="utf-8")
    # CI's fresh-clone leg runs both, as written, in a clone with nothing beside it
    assert f"README_INSTALL='{install}'" in ci and f"README_TESTS='{tests}'" in ci
    assert len(text.splitlines()) < 200


def test_docs_home_page_is_the_readme():
    import importlib.util

    spec = importlib.util.spec_from_file_location("make_index", ROOT / "docs" / "make_index.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert (ROOT / "docs" / "index.md").read_text(encoding="utf-8") == mod.index_text(), \
        "docs/index.md is out of date: python docs/make_index.py"
