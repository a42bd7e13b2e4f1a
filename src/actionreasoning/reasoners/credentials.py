"""A server's base URL and the credentials that must never be stored or shown.

A base URL may carry a credential in its user name, its password or its query
(``http://TOKEN@host/v1``, ``https://host/v1?key=TOKEN``); the API key comes from the
environment. :func:`check_base_url` refuses what is not an http(s) URL with a host,
:func:`shown_url` is a URL with those parts replaced, and :class:`Redactor` cuts them and the
key out of any text: raw, percent-decoded, and as the HTTP Basic credential the client sends
for a URL's user info.
"""

from __future__ import annotations

import base64
from dataclasses import dataclass
from urllib.parse import unquote, unquote_plus, urlsplit, urlunsplit

from actionreasoning.errors import ConfigError

REDACTED = "[redacted]"
#: Shorter secrets are not cut out of text: a query value such as ``1`` would cut every
#: digit 1 out of the model's answers. The shown URL hides them all the same.
MIN_SECRET_CHARS = 4


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
    def of(cls, base_url: str | None, key: str | None) -> Redactor:
        """The secrets of a base URL (user name, password, query values) and an API key."""
        found = [key or ""]
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
