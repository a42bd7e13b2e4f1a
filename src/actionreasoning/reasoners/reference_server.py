"""An OpenAI-compatible chat server on loopback for the prompt-only reference model.

``POST /v1/chat/completions`` answers every conversation with
:func:`~actionreasoning.reasoners.reference_model.reply`, from the messages' text alone;
``response_format``, ``temperature``, ``seed``, ``max_tokens`` and any other field are
accepted and ignored, and any model name is echoed back. ``GET /v1/models`` lists the one
model, ``reference``. Failures are OpenAI error bodies: 400 for a malformed request or a
conversation the model cannot read (with its reason), 404 for an unknown path, 413 for a body
over :data:`MAX_BODY_BYTES`, 500 with one line for anything else (the traceback goes to
stderr only).

Clients that connect and then stall are bounded by
:class:`~actionreasoning.reasoners.guarded_http.GuardedHTTPServer`: a read timeout, a bound on
the requests handled at once and on the connections waiting, one stderr line per dropped
client.

Token usage is an estimate (:func:`estimate_tokens`, and :func:`image_tokens` for image
parts): there is no tokenizer behind the model. The server binds a loopback address only;
its HTTP is the standard library's.
"""

from __future__ import annotations

import base64
import binascii
import ipaddress
import json
import math
import re
import socket
import struct
import sys
import time
import traceback
import uuid
from http import HTTPStatus
from typing import Any
from urllib.parse import urlsplit

from actionreasoning.errors import ConfigError
from actionreasoning.reasoners.chat import image_urls, message_text
from actionreasoning.reasoners.guarded_http import GuardedHandler, GuardedHTTPServer
from actionreasoning.reasoners.reference_model import Message, UnreadableConversation, reply
from actionreasoning.world.pictures import PNG_SIGNATURE

MODEL_ID = "reference"
#: A larger request body is refused with 413 before it is read.
MAX_BODY_BYTES = 8 * 1024 * 1024
#: Tokens added per message for its role and framing, as chat formats do.
TOKENS_PER_MESSAGE = 4
_TOKEN = re.compile(r"[A-Za-z]+|[0-9]{1,3}|[^\sA-Za-z0-9]{1,3}")


def estimate_tokens(text: str) -> int:
    """An estimate of the BPE tokens in ``text``: one per run of letters, per run of up to
    three digits (as GPT tokenizers split numbers) and per run of up to three other
    non-space characters (``":[`` is one token there). On the agents' conversations of a
    nominal pyramid trial it is within 1 % of OpenAI's o200k_base tokenizer (14,352 against
    14,274 tokens per brick, 4 per message included)."""
    return sum(1 for _ in _TOKEN.finditer(text))


class ReferenceServer(GuardedHTTPServer):
    """The reference model's chat server on ``host`` (loopback only) and ``port`` (0: a free
    one); run it with :meth:`serve_forever`, stop it with :meth:`shutdown` and
    :meth:`server_close`. ``verbose`` logs one line per request to stderr; ``bounds``
    (``read_timeout_s``, ``max_handlers``, ``max_waiting``) bound what stalled clients may
    hold."""

    name = "reference server"

    def __init__(
        self, host: str = "127.0.0.1", port: int = 0, verbose: bool = False, **bounds: Any
    ) -> None:
        _check_loopback(host)
        self.address_family = socket.AF_INET6 if ":" in host else socket.AF_INET
        self.verbose = verbose
        try:
            super().__init__((host, port), _Handler, **bounds)
        except OSError as error:
            raise ConfigError(f"cannot listen on {host} port {port}: {error.strerror}") from None

    @property
    def url(self) -> str:
        """The base URL clients are given, ``http://HOST:PORT/v1``."""
        host, port = str(self.server_address[0]), self.server_address[1]
        shown = f"[{host}]" if self.address_family == socket.AF_INET6 else host
        return f"http://{shown}:{port}/v1"


def _check_loopback(host: str) -> None:
    """Refuse any host but ``localhost`` or a loopback address."""
    try:
        loopback = host == "localhost" or ipaddress.ip_address(host).is_loopback
    except ValueError:
        loopback = False
    if not loopback:
        raise ConfigError(
            f"--host {host} is not a loopback address: the reference server listens on this "
            "machine only (127.0.0.1, ::1 or localhost)"
        )


class _RequestError(Exception):
    """A request answered with an OpenAI error body."""

    def __init__(self, status: int, message: str, kind: str = "invalid_request_error") -> None:
        super().__init__(message)
        self.status = status
        self.kind = kind


class _Handler(GuardedHandler):
    server: ReferenceServer
    protocol_version = "HTTP/1.1"  # keep-alive, as the openai client expects
    server_version = "actionreasoning-reference"

    def do_GET(self) -> None:
        if self._path() == "/v1/models":
            models = [{"id": MODEL_ID, "object": "model", "created": 0, "owned_by": "local"}]
            self._send(HTTPStatus.OK, {"object": "list", "data": models})
        else:
            self._unknown_path()

    def do_POST(self) -> None:
        if self._path() != "/v1/chat/completions":
            self.close_connection = True  # the body is left unread
            self._unknown_path()
            return
        try:
            payload = _completion(self._body())
        except _RequestError as error:
            self._error(error.status, str(error), error.kind)
            return
        self._send(HTTPStatus.OK, payload)

    def send_error(self, code: int, message: str | None = None, explain: str | None = None) -> None:
        """The base class's own errors (a bad request line, an unknown method) as JSON."""
        self.close_connection = True
        self._error(code, message or HTTPStatus(code).phrase)

    def log_message(self, format: str, *args: Any) -> None:
        if self.server.verbose:
            super().log_message(format, *args)

    def _path(self) -> str:
        return urlsplit(self.path).path.rstrip("/")

    def _unknown_path(self) -> None:
        self._error(404, f"Unknown request URL: {self.command} {self._path()}")

    def _body(self) -> dict[str, Any]:
        """The request body as a JSON object; the connection is closed after a body that
        could not be read whole."""
        if "chunked" in self.headers.get("Transfer-Encoding", "").lower():
            self.close_connection = True
            raise _RequestError(411, "send the body with a Content-Length, not chunked")
        try:
            length = int(self.headers.get("Content-Length", ""))
        except ValueError:
            length = -1
        if length < 0:
            self.close_connection = True
            raise _RequestError(411, "the request needs a Content-Length byte count")
        if length > MAX_BODY_BYTES:
            self.close_connection = True
            raise _RequestError(
                413, f"the body has {length} bytes; at most {MAX_BODY_BYTES} are accepted"
            )
        raw = self.rfile.read(length)
        if len(raw) < length:  # the client closed its side mid-body
            self.close_connection = True
            raise ConnectionAbortedError(f"sent {len(raw)} of {length} body bytes")
        try:
            body = json.loads(raw)
        except (ValueError, RecursionError) as error:  # not UTF-8, not JSON, nested too deep
            raise _RequestError(400, f"the body is not valid JSON ({error})"[:300]) from None
        if not isinstance(body, dict):
            raise _RequestError(400, "the body must be a JSON object")
        return body

    def _error(self, status: int, message: str, kind: str = "invalid_request_error") -> None:
        self._send(status, {"error": {"message": message, "type": kind, "code": None}})

    def _send(self, status: int, payload: dict[str, Any]) -> None:
        data = json.dumps(payload).encode()
        self.send_response(status)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(data)))
        if self.close_connection:
            self.send_header("Connection", "close")
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(data)
        self.answered()


def _completion(body: dict[str, Any]) -> dict[str, Any]:
    """The ``chat.completion`` answering a request body."""
    model = body.get("model", MODEL_ID)
    if not isinstance(model, str):
        raise _RequestError(400, "'model' must be a string")
    if body.get("stream"):
        raise _RequestError(400, "'stream' is not supported: ask without it")
    messages = _messages(body.get("messages"))
    try:
        content = reply(messages)
    except UnreadableConversation as error:
        raise _RequestError(400, f"the reference model cannot answer: {error}") from None
    except Exception as error:  # a bug in the model: one line to the client, all to stderr
        print("reference server: reply() failed:", file=sys.stderr)
        traceback.print_exc(file=sys.stderr)
        line = f"{type(error).__name__}: {error}".splitlines()[0][:300]
        raise _RequestError(500, f"the reference model failed ({line})", "server_error") from None
    prompt_tokens = sum(
        estimate_tokens(message_text(m))
        + sum(image_tokens(url) for url in image_urls(m))
        + TOKENS_PER_MESSAGE
        for m in messages
    )
    completion_tokens = estimate_tokens(content)
    return {
        "id": f"chatcmpl-{uuid.uuid4().hex}",
        "object": "chat.completion",
        "created": int(time.time()),
        "model": model,
        "choices": [
            {
                "index": 0,
                "message": {"role": "assistant", "content": content},
                "finish_reason": "stop",
            }
        ],
        "usage": {
            "prompt_tokens": prompt_tokens,
            "completion_tokens": completion_tokens,
            "total_tokens": prompt_tokens + completion_tokens,
        },
    }


def _messages(value: object) -> list[Message]:
    """``messages`` checked: a list of objects with a string role and a content that is a
    string, null, or a list of text and image_url parts."""
    if not isinstance(value, list):
        raise _RequestError(400, "'messages' must be a list of {role, content} objects")
    for index, message in enumerate(value):
        if not isinstance(message, dict) or not isinstance(message.get("role"), str):
            raise _RequestError(400, f"messages[{index}] must be an object with a string 'role'")
        content = message.get("content")
        if isinstance(content, list):
            for number, part in enumerate(content):
                if not _is_part(part):
                    raise _RequestError(
                        400,
                        f"messages[{index}].content[{number}] must be a text part "
                        '{"type": "text", "text": ...} or an image part '
                        '{"type": "image_url", "image_url": {"url": ...}}',
                    )
        elif not isinstance(content, str | None):
            raise _RequestError(
                400, f"messages[{index}].content must be a string or a list of parts"
            )
    return value


def _is_part(part: object) -> bool:
    if not isinstance(part, dict):
        return False
    if part.get("type") == "text":
        return isinstance(part.get("text"), str)
    image = part.get("image_url")
    return (
        part.get("type") == "image_url"
        and isinstance(image, dict)
        and isinstance(image.get("url"), str)
    )


def image_tokens(url: str) -> int:
    """An estimate of an image part's prompt tokens, as OpenAI counts a high-detail image:
    85, and 170 per 512-pixel tile of the image scaled to fit 2048 x 2048 and then to a
    shortest side of at most 768. The size is read from a PNG data URL's header; an image
    of unknown size counts as one tile."""
    size = png_size(url)
    if size is None:
        return 85 + 170
    width, height = size
    scale = min(1.0, 2048 / max(width, height))
    scale *= min(1.0, 768 / (min(width, height) * scale))
    tiles = math.ceil(width * scale / 512) * math.ceil(height * scale / 512)
    return 85 + 170 * tiles


def png_size(url: str) -> tuple[int, int] | None:
    """Width and height of a base64 PNG ``data:`` URL, from its header (None: not one)."""
    prefix = "data:image/png;base64,"
    if not url.startswith(prefix):
        return None
    try:
        head = base64.b64decode(url[len(prefix) : len(prefix) + 32], validate=True)
    except binascii.Error:
        return None
    if len(head) < 24 or not head.startswith(PNG_SIGNATURE) or head[12:16] != b"IHDR":
        return None
    width, height = struct.unpack(">II", head[16:24])
    return (width, height) if width and height else None
