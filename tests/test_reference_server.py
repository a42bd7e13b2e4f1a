"""The reference model's chat server: real sockets, the official openai client, no mocks."""

from __future__ import annotations

import contextlib
import http.client
import json
import re
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import openai
import pytest
from conftest import assert_clean_error, cli

from actionreasoning.errors import ConfigError, LLMError
from actionreasoning.reasoners import guarded_http
from actionreasoning.reasoners.backend import ServerOptions
from actionreasoning.reasoners.chat import ChatRequest, StructuredMode, user_message
from actionreasoning.reasoners.llm import TOOL_RESULTS
from actionreasoning.reasoners.openai_chat import OpenAIChat
from actionreasoning.reasoners.reference_model import UnreadableConversation, reply
from actionreasoning.reasoners.reference_server import (
    MAX_BODY_BYTES,
    ReferenceServer,
    estimate_tokens,
)
from actionreasoning.world.pictures import Picture, PictureKind, depth_png

PROBE = [{"role": "user", "content": 'Answer with the JSON object {"ok": true}.'}]
PROBE_SCHEMA = {"type": "object", "properties": {"ok": {"type": "boolean"}}, "required": ["ok"]}
#: No agent's prompt and no JSON object: nothing the reference model can answer.
UNREADABLE = [{"role": "user", "content": "Stack the bricks, please."}]


@contextlib.contextmanager
def serving(**bounds: Any) -> Iterator[ReferenceServer]:
    """A reference server on a free port, served by a thread, closed on exit."""
    server = ReferenceServer(port=0, **bounds)
    thread = threading.Thread(target=server.serve_forever, args=(0.05,), daemon=True)
    thread.start()
    yield server
    server.shutdown()
    server.server_close()


@pytest.fixture
def server() -> Iterator[ReferenceServer]:
    with serving() as running:
        yield running


def client(server: ReferenceServer) -> openai.OpenAI:
    return openai.OpenAI(base_url=server.url, api_key="no-key", max_retries=0)


def raw_request(
    server: ReferenceServer, method: str, path: str, body: bytes = b"", **headers: str
) -> tuple[int, dict]:
    """Status and JSON body of one request sent as given."""
    host, port = server.server_address[:2]
    connection = http.client.HTTPConnection(host, port, timeout=10)
    try:
        connection.putrequest(method, path)
        for name, value in {"Content-Length": str(len(body)), **headers}.items():
            connection.putheader(name.replace("_", "-"), value)
        connection.endheaders(body)
        response = connection.getresponse()
        return response.status, json.loads(response.read())
    finally:
        connection.close()


def test_estimate_tokens_counts_words_digit_runs_and_other_characters() -> None:
    # {" position _ m ": [ 0 . 125 , - 1 . 5 ], " id ": 123 45 }
    assert estimate_tokens('{"position_m": [0.125, -1.5], "id": 12345}') == 21
    assert estimate_tokens("  \n ") == 0


def test_the_probe_comes_back_as_its_json_object_with_estimated_usage(
    server: ReferenceServer,
) -> None:
    completion = client(server).chat.completions.create(
        model="anything",
        messages=PROBE,
        response_format={
            "type": "json_schema",
            "json_schema": {"name": "probe", "schema": PROBE_SCHEMA},
        },
        temperature=0.0,
        seed=0,
        max_tokens=20,
    )
    assert completion.object == "chat.completion" and completion.model == "anything"
    choice = completion.choices[0]
    assert choice.index == 0 and choice.finish_reason == "stop"
    assert choice.message.role == "assistant"
    assert json.loads(choice.message.content) == {"ok": True}
    # Answer with the JSON object { " ok " : true } . -> 13, +4 for the message
    usage = completion.usage
    assert (usage.prompt_tokens, usage.completion_tokens, usage.total_tokens) == (14, 5, 19)


def test_a_message_with_pictures_is_read_by_its_text_and_its_images_counted(
    server: ReferenceServer,
) -> None:
    """The official client sends a probe with two pictures as content parts: the answer is
    the text's, and each picture adds its estimated tokens (a 640 x 480 PNG: 85 + 2 x 170)."""
    picture = Picture("pick_side", PictureKind.DEPTH, depth_png(np.ones((480, 640))))
    message = user_message(PROBE[0]["content"], [picture, picture])
    completion = client(server).chat.completions.create(model="m", messages=[message])
    assert json.loads(completion.choices[0].message.content) == {"ok": True}
    assert completion.usage.prompt_tokens == 14 + 2 * (85 + 2 * 170)


def test_our_client_settles_on_json_schema(server: ReferenceServer) -> None:
    chat = OpenAIChat("anything", ServerOptions(base_url=server.url))
    assert chat.negotiate() is StructuredMode.JSON_SCHEMA


@pytest.mark.parametrize(
    ("body", "needle"),
    [
        (b'{"messages": [', "not valid JSON"),
        (b"\xff\xfe", "not valid JSON"),
        (b"[" * 100_000, "not valid JSON"),
        (b"[1]", "a JSON object"),
        (b'{"model": "m"}', "'messages' must be a list"),
        (b'{"messages": [{"content": "hi"}]}', "messages[0] must be an object"),
        (b'{"messages": [{"role": "user", "content": 7}]}', "messages[0].content"),
        (b'{"messages": [], "stream": true}', "'stream' is not supported"),
        (b'{"messages": [{"role": "user", "content": [7]}]}', "messages[0].content[0] must be"),
        (
            b'{"messages": [{"role": "user", "content": [{"type": "image_url", "image_url": '
            b'"data:"}]}]}',
            "messages[0].content[0] must be a text part",
        ),
    ],
)
def test_a_malformed_body_gets_400_naming_the_problem(
    server: ReferenceServer, body: bytes, needle: str
) -> None:
    status, answer = raw_request(server, "POST", "/v1/chat/completions", body)
    assert status == 400
    assert answer["error"]["type"] == "invalid_request_error"
    assert needle in answer["error"]["message"]
    assert answer["error"]["code"] is None


@pytest.mark.parametrize(
    ("method", "path", "headers", "status"),
    [
        ("GET", "/v1/nothing", {}, 404),
        ("POST", "/v1/completions", {}, 404),
        ("GET", "/v1/chat/completions", {}, 404),
        ("DELETE", "/v1/models", {}, 501),
        ("POST", "/v1/chat/completions", {"Content-Length": str(MAX_BODY_BYTES + 1)}, 413),
        ("POST", "/v1/chat/completions", {"Transfer-Encoding": "chunked"}, 411),
    ],
)
def test_other_requests_get_an_openai_error_body(
    server: ReferenceServer, method: str, path: str, headers: dict[str, str], status: int
) -> None:
    got, answer = raw_request(server, method, path, **headers)
    assert got == status
    assert answer["error"]["message"] and answer["error"]["type"] == "invalid_request_error"


def test_an_unreadable_conversation_is_refused_with_the_reason(server: ReferenceServer) -> None:
    with pytest.raises(UnreadableConversation) as unreadable:
        reply(UNREADABLE)
    with pytest.raises(openai.BadRequestError) as refused:
        client(server).chat.completions.create(model="reference", messages=UNREADABLE)
    assert refused.value.status_code == 400
    assert str(unreadable.value) in refused.value.message
    chat = OpenAIChat("reference", ServerOptions(base_url=server.url, max_retries=0))
    with pytest.raises(LLMError) as error:
        chat.complete(ChatRequest(messages=tuple(UNREADABLE), schema_name="s", schema={}))
    assert error.value.reason == "llm_bad_request" and str(unreadable.value) in error.value.detail


def test_models_lists_the_reference_model(server: ReferenceServer) -> None:
    assert [model.id for model in client(server).models.list()] == ["reference"]


@pytest.mark.parametrize("host", ["0.0.0.0", "::", "192.0.2.1", "example.com", ""])
def test_a_host_that_is_not_loopback_is_refused(host: str) -> None:
    with pytest.raises(ConfigError, match="not a loopback address"):
        ReferenceServer(host, 0)


def test_the_command_refuses_a_public_host_in_one_line() -> None:
    assert_clean_error(
        cli("serve-reference", "--port", "0", "--host", "0.0.0.0"), "not a loopback address"
    )


@pytest.mark.parametrize("stop", [signal.SIGTERM, signal.SIGINT], ids=lambda s: s.name)
def test_the_command_prints_its_url_serves_and_stops_cleanly(stop: signal.Signals) -> None:
    process = subprocess.Popen(
        [sys.executable, "-m", "actionreasoning", "serve-reference", "--port", "0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        # As from a terminal: Ctrl-C at its default in the child, even where this test runs
        # with SIGINT ignored (in the background of a non-interactive shell, say).
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    try:
        line = process.stdout.readline()
        match = re.fullmatch(
            r"serving the prompt-only reference model at (http://127\.0\.0\.1:\d+/v1)\n", line
        )
        assert match, (line, process.stderr.read() if process.poll() is not None else "")
        chat = OpenAIChat("reference", ServerOptions(base_url=match[1]))
        assert chat.negotiate() is StructuredMode.JSON_SCHEMA
        process.send_signal(stop)
        assert process.wait(timeout=30) == 0
        assert process.stdout.read() == "" and process.stderr.read() == ""
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
        process.stdout.close()
        process.stderr.close()


#: The one stderr line for a client the server dropped.
DROPPED = re.compile(r"reference server: dropped 127\.0\.0\.1:\d+: [^\n]+")
#: A JSON integer longer than Python converts (4300 digits by default).
HUGE_INT = "1" * 5000


@pytest.mark.parametrize(
    "messages",
    [
        [{"role": "user", "content": '{"n": ' + HUGE_INT + "}"}],
        [
            {"role": "user", "content": "# Agent 1 of 6: x\nReasoning tier: solve here"},
            {"role": "assistant", "content": '{"tool_calls": [{"name": "t", "n": ' + HUGE_INT},
            {"role": "user", "content": f"{TOOL_RESULTS}[]"},
        ],
    ],
    ids=["literal", "tool-turn"],
)
def test_a_huge_integer_in_a_message_is_refused_with_400(
    server: ReferenceServer, messages: list[dict[str, str]]
) -> None:
    body = json.dumps({"messages": messages}).encode()
    status, answer = raw_request(server, "POST", "/v1/chat/completions", body)
    assert status == 400, answer
    assert "digits" in answer["error"]["message"]
    assert answer["error"]["type"] == "invalid_request_error"


def test_a_huge_integer_in_the_body_is_refused_with_400(server: ReferenceServer) -> None:
    body = b'{"messages": [], "seed": ' + HUGE_INT.encode() + b"}"
    status, answer = raw_request(server, "POST", "/v1/chat/completions", body)
    assert status == 400 and "not valid JSON" in answer["error"]["message"]


@pytest.fixture
def guarded() -> Iterator[ReferenceServer]:
    """A server with a short read timeout and small bounds."""
    with serving(read_timeout_s=0.5, max_handlers=2, max_waiting=4) as running:
        yield running


def _connect(server: ReferenceServer) -> socket.socket:
    return socket.create_connection(server.server_address[:2], timeout=30)


def _closed_by_server(sock: socket.socket) -> bool:
    """Whether the server closes ``sock`` (reads end or reset) rather than leaving it open
    until the client gives up after 30 s."""
    try:
        while sock.recv(4096):
            pass
        return True
    except ConnectionResetError:
        return True
    except TimeoutError:
        return False


def test_silent_connections_are_closed_and_do_not_starve_a_request(
    guarded: ReferenceServer, capsys: pytest.CaptureFixture[str]
) -> None:
    # More silent clients than may wait, and some mid-headers or mid-body, as many as may
    # be handled at once.
    silent = [_connect(guarded) for _ in range(10)]
    stalled = [_connect(guarded) for _ in range(2)]
    stalled[0].sendall(b"POST /v1/chat/completions HTTP/1.1\r\nHost: x\r\n")
    stalled[1].sendall(b"POST /v1/chat/completions HTTP/1.1\r\nContent-Length: 99\r\n\r\n{")
    try:
        status, answer = 503, {}
        while status == 503:  # while the stalled clients hold both handlers: 503, retry
            try:
                status, answer = raw_request(guarded, "GET", "/v1/models")
            except ConnectionResetError:
                pass
            time.sleep(0.05)
        assert status == 200 and answer["data"][0]["id"] == "reference"
        assert all(_closed_by_server(sock) for sock in silent + stalled)
    finally:
        for sock in silent + stalled:
            sock.close()
    lines = capsys.readouterr().err.splitlines()
    assert lines and all(DROPPED.fullmatch(line) for line in lines), lines


def test_a_client_hanging_up_mid_request_is_one_line_not_a_traceback(
    server: ReferenceServer, capsys: pytest.CaptureFixture[str]
) -> None:
    head = b"POST /v1/chat/completions HTTP/1.1\r\nContent-Length: 1000\r\n\r\n"
    for reset in (True, False):
        sock = _connect(server)
        sock.sendall(head + b'{"messages": ')
        if reset:  # close with a reset, as a killed client does
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        sock.close()
    seen = ""
    for _ in range(600):  # until both are reported (at most 30 s)
        seen += capsys.readouterr().err
        if seen.count("\n") >= 2 and seen.count("dropped") + seen.count("Traceback") >= 2:
            break
        time.sleep(0.05)
    assert "Traceback" not in seen
    lines = seen.splitlines()
    assert len(lines) == 2, seen
    assert all(DROPPED.fullmatch(line) for line in lines)


def test_a_client_trickling_its_request_is_dropped_at_the_request_deadline(
    guarded: ReferenceServer, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """One byte every 0.2 s keeps each read under the 0.5 s read timeout, so only a deadline
    for the whole request stops it from holding a handler as long as it likes."""
    monkeypatch.setattr(guarded_http, "REQUEST_DEADLINE_S", 1.0)
    sock = _connect(guarded)
    request = b"POST /v1/chat/completions HTTP/1.1\r\nContent-Length: 5000\r\n\r\n" + b" " * 5000
    start = time.monotonic()
    try:
        for byte in request:
            try:
                sock.sendall(bytes([byte]))
            except (BrokenPipeError, ConnectionResetError):
                break
            time.sleep(0.2)
            if time.monotonic() - start > 15:
                break
        assert _closed_by_server(sock)
    finally:
        sock.close()
    assert time.monotonic() - start < 10
    (line,) = capsys.readouterr().err.splitlines()
    assert DROPPED.fullmatch(line) and line.endswith(": the request took longer than 1 s")


def test_headers_over_the_limit_drop_the_client(
    server: ReferenceServer, capsys: pytest.CaptureFixture[str]
) -> None:
    """40 headers of 2 KiB each: every line is legal, together they are over 64 KiB."""
    sock = _connect(server)
    header = b"X-Pad: " + b"a" * 2048 + b"\r\n"
    try:
        sock.sendall(b"GET /v1/models HTTP/1.1\r\n" + header * 40 + b"\r\n")
        assert _closed_by_server(sock)
    finally:
        sock.close()
    (line,) = capsys.readouterr().err.splitlines()
    assert DROPPED.fullmatch(line), line
    assert line.endswith(f": its headers are over {guarded_http.MAX_HEADER_BYTES} bytes")
