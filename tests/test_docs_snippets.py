"""Every code snippet of README.md and docs/*.md runs as written, in a folder of its own.

```python blocks run in order, one namespace per page; ```bash blocks run their ``shapeflow``
commands (``pip install`` lines are what installed the environment under test, and ``python -m
pytest`` is this suite).  A block that cannot run here says why on the line before it, with an HTML
comment ``<!-- not run: REASON -->``; any other command in a bash block fails the test, so a new
snippet is either run or explicitly excused.  The files the snippets name (model.obj, part.glb,
scans/, ...) are made from the bundled examples first.  Where an extra is not installed (the plain
install runs this too), a snippet that needs it skips naming it.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

import shapeflow as sf
from shapeflow.errors import OptionalDependencyError

ROOT = Path(__file__).resolve().parents[1]
#: docs/index.md is README.md with its links rewritten (docs/make_index.py): its blocks are README's
PAGES = ["README.md"] + sorted(f"docs/{p.name}" for p in (ROOT / "docs").glob("*.md") if p.name != "index.md")
FENCE = re.compile(r"(?P<before>(?:^[^\n]*\n)?)^```(?P<lang>python|bash)\n(?P<code>.*?)^```", re.M | re.S)
NOT_RUN = re.compile(r"<!--\s*not run:\s*(?P<why>[^>]*?)\s*-->")


def snippets(page: str) -> list[tuple[int, str, str, str | None]]:
    """(line, language, code, reason it is not run or None) of every python/bash block of a page."""
    text = (ROOT / page).read_text(encoding="utf-8")
    out = []
    for m in FENCE.finditer(text):
        line = text.count("\n", 0, m.start("lang")) + 1
        why = NOT_RUN.search(m.group("before"))
        out.append((line, m.group("lang"), m.group("code"), why.group("why") if why else None))
    return out


def make_inputs(folder: Path) -> dict[str, str]:
    """The files the snippets read, from the bundled examples; returns those that cannot be made
    here (a format whose extra is not installed) with the reason."""
    cage, spot = sf.load_example("spot_cage"), sf.load_example("spot")
    missing = {}
    for name, mesh in (("model.obj", cage), ("part.glb", cage), ("scans/a.ply", cage), ("scans/deep/b.ply", spot),
                       ("assets/cage.obj", cage), ("parts/p.obj", cage), ("in/a.obj", cage), ("in/b.ply", cage),
                       ("spot.ply", spot)):
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        try:
            sf.save(folder / name, mesh)
        except OptionalDependencyError as exc:      # part.glb without the gltf extra
            missing[name] = str(exc)
    (folder / "out").mkdir()
    (folder / "models.csv").write_text("path\nmodel.obj\nparts/p.obj\n")
    return missing


def run_bash(code: str, where: str) -> None:
    for raw in code.splitlines():
        line = raw.split(" #")[0].strip() if not raw.lstrip().startswith("#") else ""
        for cmd in filter(None, (c.strip() for c in line.split("&&"))):
            words = shlex.split(cmd)
            if words[0] == "shapeflow":
                r = subprocess.run([sys.executable, "-m", "shapeflow", *words[1:]], capture_output=True, text=True,
                                   timeout=600, env={**os.environ, "NO_COLOR": "1"})
                if r.returncode == 2 and "needs the optional package" in r.stderr:
                    pytest.skip(f"{where}: {r.stderr.strip()}")
                assert r.returncode == 0, f"{where}: {cmd}\n{r.stderr}"
            elif words[:2] == ["pip", "install"] or words[:4] == ["python", "-m", "pytest", "-q"]:
                continue          # the environment under test / this suite
            else:
                raise AssertionError(f"{where}: '{cmd}' is not a shapeflow command; run it here or mark the "
                                     "block <!-- not run: REASON -->")


@pytest.mark.parametrize("page", [p for p in PAGES if snippets(p)])
def test_snippets_run(page, tmp_path, monkeypatch):
    blocks = snippets(page)
    missing = make_inputs(tmp_path)
    monkeypatch.chdir(tmp_path)
    namespace = {"__name__": "snippet"}
    ran = 0
    for line, lang, code, why in blocks:
        if why is not None:
            assert why, f"{page}:{line}: say why the block is not run"
            continue
        where = f"{page}:{line}"
        for name, reason in missing.items():
            if name in code:
                pytest.skip(f"{where} reads {name}, which cannot be made here: {reason}")
        if lang == "python":
            try:
                exec(compile(code, where, "exec"), namespace)
            except OptionalDependencyError as exc:
                pytest.skip(f"{where}: {exc}")
        else:
            run_bash(code, where)
        ran += 1
    assert ran or all(why for *_, why in blocks)


def test_every_excused_block_says_why():
    excused = [(page, line, why) for page in PAGES for line, _, _, why in snippets(page) if why is not None]
    assert all(why.strip() for _, _, why in excused)
    # what is excused, so a reader of this test sees it
    assert {why for *_, why in excused} <= {
        "needs Blender's bpy module", "builds Blender extensions: downloads SciPy wheels for four platforms",
        "needs a web browser", "needs a Dask cluster on several machines", "needs Blender"}, excused


def test_the_marker_excuses_only_the_block_after_it(tmp_path):
    page = tmp_path / "p.md"
    page.write_text("<!-- not run: needs a web browser -->\n```bash\nfirefox\n```\n\n"
                    "```bash\nshapeflow --version\n```\n")
    text = page.read_text()
    found = [(m.group("lang"), (NOT_RUN.search(m.group("before")) or [None])[0] is not None)
             for m in FENCE.finditer(text)]
    assert found == [("bash", True), ("bash", False)]
    with pytest.raises(AssertionError, match="not a shapeflow command"):
        run_bash("firefox index.html", "p.md:3")
