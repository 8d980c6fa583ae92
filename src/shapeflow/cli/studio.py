"""``shapeflow studio [MESH]``: the studio in a web browser (needs ``shapeflow[studio]``)."""

from __future__ import annotations

from .common import eprint, load_mesh_arg


def register(sub) -> None:
    p = sub.add_parser(
        "studio", help="enhance, paint weights and sculpt in a web browser (needs shapeflow[studio])",
        description="Start ShapeFlow Studio on MESH (default example:spot) and open it in the browser: a λ slider "
                    "that walks a family of shapes from smoothing to enhancement, weight painting, the enhancement "
                    "and inflate brushes with X symmetry, a stroke per undo step (Ctrl+Z), download in every "
                    "format; '?' on the page lists the keys.  Serves on 127.0.0.1 only unless --host says "
                    "otherwise; every request needs the token in the printed address (?token=...); Ctrl-C ends it.")
    p.add_argument("mesh", nargs="?", default="example:spot", metavar="MESH",
                   help="a mesh file or example:NAME (default example:spot)")
    p.add_argument("--port", type=int, default=8765, help="port (default 8765; 0 picks a free one)")
    p.add_argument("--host", default="127.0.0.1",
                   help="address to listen on (default 127.0.0.1: this machine only; 0.0.0.0 serves the network)")
    p.add_argument("--allow-host", action="append", default=[], metavar="NAME",
                   help="another name browsers may use for this machine (e.g. its DNS name with --host 0.0.0.0); "
                        "repeatable")
    p.add_argument("--max-upload", type=float, default=512, metavar="MIB",
                   help="largest file a page may open, in MiB (default 512)")
    p.add_argument("--front", choices=["+x", "-x", "+y", "-y", "+z", "-z"], default=None, metavar="AXIS",
                   help="the axis the model faces, one of +x -x +y -y +z -z (default: the file's own, as the bundled "
                        "examples carry it, else +z with y up and -y for STL, as 'render'); files opened in the page "
                        "that name none face it too; the page's View section changes it")
    p.add_argument("--no-browser", action="store_true", help="print the address, do not open a browser")
    p.set_defaults(func=run)


def run(args) -> int:
    import os
    import threading

    from .. import params
    from ..studio import StudioServer

    mesh = load_mesh_arg(args.mesh)
    mib = params.number("--max-upload", args.max_upload, lo=0.001)
    server = StudioServer(mesh, host=args.host, port=args.port, max_upload=int(mib * 2**20),
                          name=os.path.basename(args.mesh).removeprefix("example:"), allow_hosts=args.allow_host,
                          front=args.front)
    eprint(f"shapeflow studio: {mesh.n_vertices:,} vertices at {server.url} (Ctrl-C ends it)")
    if not server.loopback:
        eprint(f"shapeflow studio: warning: listening on {args.host}: anyone who can reach this machine and has "
               "the address above (its token) can edit; HTTP is not encrypted, so use it on networks you trust")
    opener = None
    if not args.no_browser:
        opener = _open_browser(server.url)
    try:
        threading.Event().wait()
    finally:
        server.stop()
        if opener is not None:
            opener.cleanup()
    return 0


def _open_browser(url: str):
    """Open ``url`` through a page only this user can read (as Jupyter does): a browser started with
    the token on its command line would show it to every user of the machine (``ps``).  Returns the
    temporary folder holding that page."""
    import html
    import os
    import tempfile
    import webbrowser

    folder = tempfile.TemporaryDirectory(prefix="shapeflow-studio-open-")
    os.chmod(folder.name, 0o700)
    page = os.path.join(folder.name, "open.html")
    fd = os.open(page, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "w", encoding="utf-8") as f:
        u = html.escape(url, quote=True)
        f.write(f'<!doctype html><meta charset="utf-8"><meta http-equiv="refresh" content="0;url={u}">'
                f'<title>ShapeFlow Studio</title><p><a href="{u}">ShapeFlow Studio</a></p>\n')
    webbrowser.open("file://" + page)
    return folder
