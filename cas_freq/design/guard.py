"""Who may talk to the design server: the checks every request passes before it is served.

The server runs on the user's machine while the user browses other sites, so a request may
come from any web page (a cross-site form or ``fetch``) or from a name that a hostile DNS server
points at 127.0.0.1 (DNS rebinding). As Jupyter and other local servers do, a request is
served only when

- its ``Host`` is the served address: ``127.0.0.1``, ``localhost`` or ``[::1]`` with the
  served port (any host with ``--allow-remote``, where the user chose to be reached);
- it is not cross-origin: an ``Origin`` header, when sent, is ``http://`` and that host, and
  ``Sec-Fetch-Site``, when sent, is ``same-origin`` or ``none`` (typed into the address bar);
- for the API (``/api/...``), it carries the per-launch token (the ``token`` of the URL the
  command prints, sent by the page as the ``X-Cas-Freq-Token`` header: a header a cross-site
  page cannot set without the server's consent);
- for a ``POST``, its body is ``application/json`` (the content type a cross-site form cannot
  send).
"""

import hmac
import secrets
from dataclasses import dataclass, field

#: The loopback addresses the server may listen on without ``--allow-remote``.
LOOPBACK_ADDRESSES = ("127.0.0.1", "localhost", "::1")
#: Their names as a browser sends them in ``Host`` (an IPv6 address in brackets).
LOOPBACK_NAMES = tuple(f"[{a}]" if ":" in a else a for a in LOOPBACK_ADDRESSES)
#: The header that carries the per-launch token.
TOKEN_HEADER = "X-Cas-Freq-Token"


class Refused(Exception):
    """A request the guard does not serve: its HTTP ``status`` and a one-line reason."""

    def __init__(self, status, reason):
        super().__init__(reason)
        self.status = status


def new_token():
    """A per-launch secret: 32 random bytes, URL-safe text."""
    return secrets.token_urlsafe(32)


@dataclass(frozen=True)
class Guard:
    """The checks of one served address.

    Parameters
    ----------
    port : int
        The port served.
    token : str
        The per-launch token (:func:`new_token`).
    remote : bool
        Whether every interface is served (``--allow-remote``): any ``Host`` then.
    """

    port: int
    token: str = field(repr=False)
    remote: bool = False

    def hosts(self):
        """The ``Host`` values served (``host:port``, lower case)."""
        return {f"{name}:{self.port}" for name in LOOPBACK_NAMES}

    def check(self, method, path, headers):
        """Raise :class:`Refused` unless the request may be served.

        Parameters
        ----------
        method : str
            ``GET`` or ``POST``.
        path : str
            The URL's path (``/api/state``).
        headers : email.message.Message
            The request's headers.
        """
        host = (headers.get("Host") or "").strip().lower()
        if not host:
            raise Refused(400, "no Host header")
        if not self.remote and host not in self.hosts():
            raise Refused(403, f"Host {host!r} is not this server's address (served as "
                               f"127.0.0.1, localhost or [::1] on port {self.port})")
        origin = headers.get("Origin")
        if origin is not None and origin.strip().lower() != f"http://{host}":
            raise Refused(403, f"cross-origin request from {origin!r} refused (the design "
                               f"page is served as http://{host})")
        site = headers.get("Sec-Fetch-Site")
        if site is not None and site.strip().lower() not in ("same-origin", "none"):
            raise Refused(403, f"cross-site request ({site}) refused")
        if path.startswith("/api/"):
            sent = headers.get(TOKEN_HEADER) or ""
            if not hmac.compare_digest(sent.encode(), self.token.encode()):
                raise Refused(403, f"the {TOKEN_HEADER} header is missing or wrong (open the "
                                   "URL that cas-freq design printed, with its token)")
        if method == "POST":
            kind = (headers.get("Content-Type") or "").split(";")[0].strip().lower()
            if kind != "application/json":
                raise Refused(415, f"Content-Type {kind or 'none'!r}: expected "
                                   "application/json")


__all__ = ["LOOPBACK_ADDRESSES", "LOOPBACK_NAMES", "TOKEN_HEADER", "Guard", "Refused", "new_token"]
