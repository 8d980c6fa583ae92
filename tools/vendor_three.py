"""Refresh the three.js files the studio ships (``src/shapeflow/studio/static/vendor/three``).

    python tools/vendor_three.py 0.187.0

Runs ``npm pack three@VERSION`` in a temporary folder (npm is needed here only, never to install
or run shapeflow) and copies ``build/three.module.js``, ``build/three.core.js``,
``examples/jsm/controls/OrbitControls.js`` and ``LICENSE`` verbatim, then rewrites VENDORED.txt.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

DEST = Path(__file__).resolve().parents[1] / "src" / "shapeflow" / "studio" / "static" / "vendor" / "three"
FILES = {"build/three.module.js": "three.module.js", "build/three.core.js": "three.core.js",
         "examples/jsm/controls/OrbitControls.js": "OrbitControls.js", "LICENSE": "LICENSE"}


def main(version: str) -> int:
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run(["npm", "pack", f"three@{version}"], cwd=tmp, check=True, capture_output=True)
        with tarfile.open(next(Path(tmp).glob("three-*.tgz"))) as tar:
            tar.extractall(tmp, filter="data")
        for src, dst in FILES.items():
            shutil.copyfile(Path(tmp) / "package" / src, DEST / dst)
    (DEST / "VENDORED.txt").write_text(
        f"three.js {version}, from the npm registry (npm pack three@{version}), files verbatim:\n"
        "build/three.module.js, build/three.core.js, examples/jsm/controls/OrbitControls.js, LICENSE.\n"
        "Refresh with: python tools/vendor_three.py VERSION\n")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else "0.187.0"))
