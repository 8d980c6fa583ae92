"""Write docs/index.md, the documentation site's home page, from README.md (links made relative to docs/).

Run after editing the README: ``python docs/make_index.py``; ``tests/test_readme.py`` checks they agree.
"""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HEADER = "<!-- generated from README.md by docs/make_index.py; edit the README -->\n"


def index_text() -> str:
    return HEADER + (ROOT / "README.md").read_text(encoding="utf-8").replace("](docs/", "](")


if __name__ == "__main__":
    (ROOT / "docs" / "index.md").write_text(index_text(), encoding="utf-8")
