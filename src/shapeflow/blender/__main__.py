"""``python -m shapeflow.blender build --output DIR``: build the Blender extension zip(s)."""

from __future__ import annotations

import argparse
import sys

from .build import PLATFORMS, SCIPY_VERSION, BuildError, build, default_cache_dir


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m shapeflow.blender",
        description="Build the shapeflow Blender extension (Blender 4.2 to 5.0).",
    )
    sub = ap.add_subparsers(dest="command", metavar="COMMAND", required=True)
    b = sub.add_parser("build", help="write one extension zip per platform",
                       description="Write shapeflow-VERSION-PLATFORM.zip for each platform: the add-on, "
                                   f"a wheel of this shapeflow and a scipy {SCIPY_VERSION} wheel. Install it in "
                                   "Blender with Edit > Preferences > Get Extensions > Install from Disk.")
    b.add_argument("--output", "-o", required=True, metavar="DIR", help="directory for the zip files")
    b.add_argument("--platform", "-p", action="append", dest="platforms", metavar="NAME",
                   choices=[*PLATFORMS, "all"],
                   help=f"Blender platform: {', '.join(PLATFORMS)} or all (default); repeatable")
    b.add_argument("--wheel-dir", action="append", default=[], metavar="DIR",
                   help="look for the scipy wheels here first (e.g. wheels fetched on another machine)")
    b.add_argument("--cache-dir", metavar="DIR",
                   help=f"where downloaded wheels are kept (default {default_cache_dir()})")
    b.add_argument("--offline", action="store_true", help="never run pip download; fail if a wheel is missing")
    b.add_argument("--scipy-version", default=SCIPY_VERSION, metavar="X.Y.Z",
                   help=f"scipy to bundle (default {SCIPY_VERSION}: the newest that runs on Blender 4.2's numpy 1.24)")
    args = ap.parse_args(argv)
    try:
        results = build(args.output, args.platforms or ["all"], scipy_version=args.scipy_version,
                        cache_dir=args.cache_dir, wheel_dirs=args.wheel_dir, offline=args.offline,
                        log=lambda m: print(m, file=sys.stderr))
    except (BuildError, OSError) as exc:
        print(f"shapeflow.blender: error: {exc}", file=sys.stderr)
        return 2
    for r in results:
        print(r.path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
