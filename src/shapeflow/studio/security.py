"""Who may use a running studio: a token, and the ``Host`` and ``Origin`` of every request.

The model is Jupyter's.  Every server start draws a random token (:func:`new_token`, 256 bits);
the address the command line prints and opens, and :attr:`StudioServer.url`, carry it as
``?token=…``.  :class:`Guard` checks every request, before any handler runs:

1. **Host** (DNS rebinding): the ``Host`` header must name the address the server listens on —
   ``127.0.0.1``, ``localhost`` or ``[::1]`` for a loopback server, the address given otherwise,
   any IP literal for a server on every interface (``0.0.0.0``/``::``), and names added with
   ``allow_hosts`` — with the server's port.  A page on ``evil.example`` whose name was rebound to
   127.0.0.1 sends ``Host: evil.example:PORT`` and is refused.
2. **Origin**: a request that names an origin (every browser ``fetch``, form post and WebSocket
   does) must come from the studio's own origin, ``http://`` + its ``Host``.  ``Origin: null``
   (sandboxed frames, ``file:`` pages) is refused; so are requests marked cross-site or same-site
   by ``Sec-Fetch-Site`` that change state.  A cross-origin "simple" ``POST`` (``text/plain``, no
   preflight) is refused here, before its body is read.
3. **Token**: the ``token`` query parameter, the ``X-Shapeflow-Token`` header or, for reading
   requests only (``GET``: the page, its scripts, downloads), the cookie the page received when
   it was opened with the token (``HttpOnly``, ``SameSite=Strict``, named after the port).
   Requests that change state — the WebSocket and every ``POST`` — need the token itself, in the
   query or the header: a cookie alone never edits.  Tokens are compared in constant time.

Refusals are ``403`` (``400`` for a missing or malformed ``Host``) with one line saying why; no
refusal names the token.
"""

from __future__ import annotations

import hmac
import ipaddress
import secrets
from urllib.parse import quote

__all__ = ["new_token", "Guard", "HEADER", "LOOPBACK", "is_loopback", "content_disposition", "check_name"]

#: the header a page (or a script) may carry the token in
HEADER = "X-Shapeflow-Token"
#: the names of this machine's loopback interface a browser may use in ``Host``
LOOPBACK = ("127.0.0.1", "localhost", "::1")
#: headers every answer carries: no MIME sniffing, no embedding of its bytes by another origin
SAFE_HEADERS = {"X-Content-Type-Options": "nosniff", "Cross-Origin-Resource-Policy": "same-origin",
                "Referrer-Policy": "no-referrer", "Cache-Control": "no-store"}


def new_token() -> str:
    """A fresh random token: 32 bytes from the operating system's generator, URL-safe base64."""
    return secrets.token_urlsafe(32)


def is_loopback(host: str) -> bool:
    """Whether ``host`` (a name or an address) is this machine's loopback interface."""
    h = host.strip("[]").lower()
    if h == "localhost":
        return True
    try:
        return ipaddress.ip_address(h).is_loopback
    except ValueError:
        return False


def _split_host(value: str) -> tuple[str, int | None] | None:
    """``Host`` header → (lower-case host without brackets, port or None); None when malformed."""
    value = value.strip()
    if not value or any(c in value for c in "/\\@ \t\r\n\0"):
        return None
    if value.startswith("["):                       # [v6]:port
        end = value.find("]")
        if end < 0:
            return None
        host, rest = value[1:end], value[end + 1:]
        if rest and not rest.startswith(":"):
            return None
        port = rest[1:] if rest else None
    elif value.count(":") == 1:
        host, port = value.split(":")
    elif ":" in value:                               # a bare IPv6 address is not a valid Host
        return None
    else:
        host, port = value, None
    if port is not None:
        if not (port.isascii() and port.isdigit()) or len(port) > 5:
            return None
        port = int(port)
    if not host.isascii() or not host or host.endswith("."):    # "localhost." and friends: not our names
        return None
    return host.lower(), port


def _is_ip(host: str) -> bool:
    try:
        ipaddress.ip_address(host)
        return True
    except ValueError:
        return False


class Guard:
    """The checks of the module docstring for one server (``bind``: the address it listens on).

    ``allow_hosts``: more names a browser may use for this machine (e.g. its DNS name when the
    server listens on the network).  :meth:`refusal` returns ``None`` for a request that may
    proceed, else ``(status, reason)``.
    """

    def __init__(self, token: str, bind: str, port: int, *, allow_hosts=()):
        self.token = token
        self.port = int(port)
        self.bind = bind
        self.everywhere = bind in ("", "0.0.0.0", "::")
        names = {h.strip("[]").lower() for h in allow_hosts}
        if is_loopback(bind) or self.everywhere:
            names.update(LOOPBACK)
        if not self.everywhere:
            names.add(bind.strip("[]").lower())
        self.names = frozenset(names)
        #: the page's cookie holds this, not the token: browsers send a cookie to every port of its
        #: host, so its value must be worth nothing but the page and its scripts
        self.cookie_value = secrets.token_urlsafe(32)

    @property
    def cookie(self) -> str:
        """The name of the page's cookie (one per port, though cookies do not tell ports apart)."""
        return f"shapeflow-studio-{self.port}"

    # --- the three checks ---------------------------------------------
    def host_ok(self, host_header: str | None) -> bool:
        parts = _split_host(host_header or "")
        if parts is None:
            return False
        host, port = parts
        if port not in (None, self.port) or (port is None and self.port != 80):
            return False
        return host in self.names or (self.everywhere and _is_ip(host))

    def origin_ok(self, origin: str | None, host_header: str) -> bool:
        if origin is None:
            return True                 # not a browser's cross-origin request (a script, curl)
        return origin.strip().lower() == f"http://{host_header.strip().lower()}"

    def token_is(self, given: str) -> bool:
        """Whether ``given`` is the token (compared in constant time)."""
        return hmac.compare_digest(given.encode("utf-8", "replace"), self.token.encode())

    def token_ok(self, request, *, cookie_allowed: bool) -> bool:
        good = self.token.encode()
        if any(g is not None and hmac.compare_digest(g.encode("utf-8", "replace"), good)
               for g in (request.query.get("token"), request.headers.get(HEADER))):
            return True
        c = request.cookies.get(self.cookie)
        return cookie_allowed and c is not None and hmac.compare_digest(c.encode("utf-8", "replace"),
                                                                        self.cookie_value.encode())

    def refusal(self, request) -> tuple[int, str] | None:
        host = request.headers.get("Host")
        if not self.host_ok(host):
            return 400 if not host else 403, (
                "this studio answers only requests addressed to "
                f"{' or '.join(sorted(self.names)) or 'an IP address'} on port {self.port} "
                f"(Host: {_printable(host)}); start it with --allow-host NAME to add a name")
        if not request.raw_path.startswith("/"):   # GET http://elsewhere/ ...: its authority would win
            return 400, "this studio takes request targets as paths (/…), not absolute addresses"
        changes = request.method not in ("GET", "HEAD") or request.path == "/ws"
        # the cookie opens the page and its scripts, nothing else (downloads need the token)
        page = request.method in ("GET", "HEAD") and (request.path == "/" or request.path.startswith("/static/"))
        if not self.origin_ok(request.headers.get("Origin"), host):
            return 403, f"requests from another origin ({_printable(request.headers.get('Origin'))}) are refused"
        if changes and request.headers.get("Sec-Fetch-Site", "").lower() in ("cross-site", "same-site"):
            return 403, "requests from another site are refused"
        if not self.token_ok(request, cookie_allowed=page and not changes):
            return 403, ("this studio needs its token: open the address shapeflow studio printed "
                         "(…/?token=…)" if request.method == "GET" else
                         "this request needs the studio's token (?token=… or the X-Shapeflow-Token header)")
        return None


def _printable(value) -> str:
    if value is None:
        return "none"
    s = "".join(c if c.isprintable() else "?" for c in str(value))
    return s if len(s) <= 80 else s[:77] + "..."


# --- names in URLs and downloads -------------------------------------------------
#: characters no file name the studio takes or gives may hold (Windows' reserved ones included)
_BAD_NAME = set('/\\"<>:|?*')
#: Unicode categories refused in names: controls, format characters (bidi overrides such as
#: U+202E), line and paragraph separators, surrogates, private use, unassigned
_BAD_CATEGORIES = {"Cc", "Cf", "Zl", "Zp", "Cs", "Co", "Cn"}


def check_name(name: str, what: str = "the file name") -> str | None:
    """Why ``name`` cannot name a file the studio receives or sends (None when it can): empty,
    ``.`` or ``..``, a control or format character (U+0085, U+202E, U+2028...), a slash, a
    backslash, one of ``" < > : | ? *``, over 255 bytes of UTF-8."""
    import unicodedata

    if not name:
        return f"{what} is empty"
    if name in (".", ".."):
        return f"{what} is {name!r}"
    if any(c in _BAD_NAME for c in name):
        return f'{what} holds a slash, a backslash or one of " < > : | ? *'
    if any(unicodedata.category(c) in _BAD_CATEGORIES for c in name):
        return f"{what} holds a control or formatting character"
    if len(name.encode("utf-8", "surrogatepass")) > 255:
        return f"{what} is longer than 255 bytes"
    return None


def content_disposition(name: str) -> str:
    """``attachment`` with ``name`` encoded as RFC 6266 says: an ASCII ``filename`` (other
    characters as ``_``) and the exact name as ``filename*=UTF-8''…``."""
    ascii_name = "".join(c if 32 <= ord(c) < 127 and c not in '"\\%' else "_" for c in name)
    return f"attachment; filename=\"{ascii_name}\"; filename*=UTF-8''{quote(name, safe='')}"
