"""A server's base URL and the credentials that must never be stored or shown.

A base URL may carry a credential in its user name, its password or its query
(``http://TOKEN@host/v1``, ``https://host/v1?key=TOKEN``); the API key comes from the
environment, and so do extra headers for gateways (:func:`extra_headers`), whose values may
be credentials too. :func:`check_base_url` refuses what is not an http(s) URL with a host,
:func:`shown_url` is a URL with those parts replaced, and :class:`Redactor` cuts them, the
key and the header values out of any text: raw, percent-decoded, and as the HTTP Basic
credential the client sends for a URL's user info.
"""

from __future__ import annotations

import base64
import json
import os
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any
from urllib.parse import unquote, unquote_plus, urlsplit, urlunsplit

from actionreasoning.errors import ConfigError

REDACTED = "[redacted]"
#: Shorter secrets are not cut out of text: a query value such as ``1`` would cut every
#: digit 1 out of the model's answers. The shown URL hides them all the same.
MIN_SECRET_CHARS = 4
#: A JSON object of extra HTTP headers sent with every request to an OpenAI-compatible server.
HEADERS_VARIABLE = "ACTIONREASONING_LLM_HEADERS"
_HEADER_NAME = re.compile(r"[!#$%&'*+.^_`|~0-9A-Za-z-]+")  # an RFC 9110 token
_HEADER_VALUE = re.compile(r"[\t\x20-\x7e]*")  # visible ASCII, spaces and tabs
#: Headers the client writes itself, from the request.
_CLIENT_HEADERS = frozenset({"content-length", "content-type", "host", "transfer-encoding"})


def check_base_url(url: str, source: str) -> None:
    """Refuse an empty ``url`` or one that is not http(s) with a host; ``source`` names where
    it came from (``--base-url``). The message never quotes the URL: it may hold a secret."""
    if not url.strip():
        raise ConfigError(
            f"{source} is empty (an unset variable?): give the server's URL, such as "
            "http://localhost:8080/v1, or leave it out to use the OpenAI API"
        )
    try:
        parts = urlsplit(url)
        parts.port  # noqa: B018 - parsing the port is the check
    except ValueError:
        raise ConfigError(
            f"{source} is not a valid URL (brackets or port): give one such as "
            "http://localhost:8080/v1"
        ) from None
    if parts.scheme not in ("http", "https") or not parts.hostname:
        raise ConfigError(
            f"{source} {shown_url(url)} is not an http:// or https:// URL with a host, such as "
            "http://localhost:8080/v1"
        )


def extra_headers(environ: Mapping[str, str] = os.environ) -> dict[str, str]:
    """The headers of :data:`HEADERS_VARIABLE`, a JSON object of names to string values
    (none if it is unset). Messages name the variable and valid header names, never a value."""
    text = environ.get(HEADERS_VARIABLE)
    if text is None:
        return {}
    example = '{"HTTP-Referer": "https://example.org", "X-Title": "my study"}'
    try:  # as name-value pairs, so that a name given twice is seen, not overwritten
        pairs = json.loads(text, object_pairs_hook=_Pairs)
    except (ValueError, RecursionError):
        pairs = None
    if not isinstance(pairs, _Pairs):
        raise ConfigError(
            f"{HEADERS_VARIABLE} is not a JSON object of header names to values, such as {example}"
        )
    seen: set[str] = set()
    for number, (name, value) in enumerate(pairs, start=1):
        if not _HEADER_NAME.fullmatch(name):
            raise ConfigError(f"{HEADERS_VARIABLE}: header {number} has no valid HTTP name")
        if name.lower() in _CLIENT_HEADERS:
            raise ConfigError(f"{HEADERS_VARIABLE}: {name} is written by the client itself")
        if name.lower() in seen:
            raise ConfigError(f"{HEADERS_VARIABLE} names {name} twice (names ignore case)")
        seen.add(name.lower())
        if not isinstance(value, str) or not _HEADER_VALUE.fullmatch(value):
            raise ConfigError(
                f"{HEADERS_VARIABLE}: the value of {name} must be a string of printable ASCII "
                "characters"
            )
        if value != value.strip(" \t"):
            raise ConfigError(
                f"{HEADERS_VARIABLE}: the value of {name} begins or ends with a space, which "
                "HTTP clients refuse to send"
            )
    return dict(pairs)


class _Pairs(list[tuple[str, Any]]):
    """A JSON object's members in order, names given twice included."""


def shown_url(url: str) -> str:
    """``url`` with its user info and every query value replaced by ``[redacted]``."""
    parts = urlsplit(url)
    host = parts.netloc.rpartition("@")[2]
    netloc = f"{REDACTED}@{host}" if "@" in parts.netloc else host
    query = "&".join(
        f"{item.partition('=')[0]}={REDACTED}" if "=" in item else REDACTED
        for item in filter(None, parts.query.split("&"))
    )
    return urlunsplit(parts._replace(netloc=netloc, query=query))


@dataclass(frozen=True)
class Redactor:
    """Cuts known secrets out of text, longest first."""

    secrets: tuple[str, ...] = ()

    @classmethod
    def of(cls, base_url: str | None, key: str | None, values: Iterable[str] = ()) -> Redactor:
        """The secrets of a base URL (user name, password, query values), an API key and
        header ``values``."""
        found = [key or "", *values]
        parts = urlsplit(base_url or "")
        user, password = parts.username, parts.password
        if user is not None or password is not None:
            user, password = user or "", password or ""
            basic = f"{unquote(user)}:{unquote(password)}"  # what the client sends
            found += [user, password, unquote(user), unquote(password)]
            found.append(base64.b64encode(basic.encode()).decode())
        for item in filter(None, parts.query.split("&")):
            name, equals, value = item.partition("=")
            raw = value if equals else name
            found += [raw, unquote_plus(raw)]
        kept = {secret for secret in found if len(secret) >= MIN_SECRET_CHARS}
        return cls(tuple(sorted(kept, key=len, reverse=True)))

    def __call__(self, text: str) -> str:
        """``text`` with every secret replaced by ``[redacted]``."""
        for secret in self.secrets:
            text = text.replace(secret, REDACTED)
        return text
