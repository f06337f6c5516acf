"""Who may reach the station view: its address, the loopback test and the token's form.

Separate from the server because these are the view's access rules, read before anything
is served (``clark run --view``, ``clark replay``) as well as by the server's checks
(docs/station-view.md, "Security"):

- It binds 127.0.0.1 by default. A token is required whenever the bind address is not
  loopback: :class:`~clark_engine.station.server.ViewServer` refuses to start without
  one (a usage error, exit 2).
- A token is printable ASCII without spaces, :data:`MIN_TOKEN_CHARS` to
  :data:`MAX_TOKEN_CHARS` characters; a request carries it as ``?token=`` once, then a
  cookie, or an :data:`TOKEN_HEADER` header or ``Authorization: Bearer``.
"""

from __future__ import annotations

import ipaddress
from typing import Final

from clark_engine.errors import UsageError

MIN_TOKEN_CHARS: Final = 16
"""Shortest token accepted: a token is a secret, not a password to remember."""

MAX_TOKEN_CHARS: Final = 256

TOKEN_HEADER: Final = "X-Clark-Token"


def is_loopback_host(host: str) -> bool:
    """True for ``localhost`` and the loopback addresses (127.0.0.0/8, ::1)."""
    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def parse_view_address(text: str) -> tuple[str, int]:
    """``[HOST:]PORT`` (``8080``, ``127.0.0.1:8080``, ``0.0.0.0:8080``, ``[::1]:8080``).

    Raises:
        UsageError: Not of that form, or a port outside 0-65535 (0 picks a free one).
    """
    host, sep, port_text = text.rpartition(":")
    if not sep:
        host, port_text = "127.0.0.1", text
    host = host.strip()
    if host.startswith("[") and host.endswith("]"):
        host = host[1:-1]
    if not host:
        raise UsageError(f"--view {text!r}: give [HOST:]PORT, e.g. 8080 or 127.0.0.1:8080")
    try:
        port = int(port_text)
    except ValueError:
        raise UsageError(
            f"--view {text!r}: the port must be a number (e.g. 8080; 0 picks a free one)"
        ) from None
    if not 0 <= port <= 65535:
        raise UsageError(f"--view {text!r}: the port must be within 0-65535")
    return host, port


def check_token(token: str) -> str:
    """The token, when it is usable: printable ASCII without spaces, 16-256 characters.

    Raises:
        UsageError: It is not.
    """
    if not MIN_TOKEN_CHARS <= len(token) <= MAX_TOKEN_CHARS:
        raise UsageError(
            f"the view token must be {MIN_TOKEN_CHARS}-{MAX_TOKEN_CHARS} characters long "
            "(e.g. from `python -c 'import secrets; print(secrets.token_urlsafe(24))'`)"
        )
    if not all(33 <= ord(c) <= 126 for c in token):
        raise UsageError("the view token must be printable ASCII without spaces")
    return token


__all__ = [
    "MAX_TOKEN_CHARS",
    "MIN_TOKEN_CHARS",
    "TOKEN_HEADER",
    "check_token",
    "is_loopback_host",
    "parse_view_address",
]
