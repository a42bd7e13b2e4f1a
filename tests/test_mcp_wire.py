"""Raw lines on the real MCP server's stdin (`actionreasoning mcp` as a subprocess): every
malformed line gets a JSON-RPC error reply (a request's own id when it has a usable one,
null otherwise), a line over the size limit is refused without being read whole, a lone
surrogate in a tool's arguments is the tool's refusal, tool calls sent together run in the
order they arrived, and the server still answers a normal request afterwards. Replies are
awaited with a timeout, so a line the server drops fails the test instead of hanging it."""

from __future__ import annotations

import json
import queue
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from actionreasoning.agents.validation import MAX_ANSWER_CHARS
from actionreasoning.mcp_server.wire import MAX_MESSAGE_BYTES

COMMAND = [sys.executable, "-m", "actionreasoning", "mcp"]
REPLY_S = 30.0
PARSE_ERROR, INVALID_REQUEST, INVALID_PARAMS = -32700, -32600, -32602


class Server:
    """The server process, its stdout's lines read by a thread."""

    def __init__(self, errlog: Path) -> None:
        self._err = errlog.open("w")
        self.process = subprocess.Popen(
            COMMAND, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self._err
        )
        self._lines: queue.Queue[bytes] = queue.Queue()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            self._lines.put(line)

    def send(self, line: bytes) -> None:
        assert self.process.stdin is not None
        self.process.stdin.write(line + b"\n")
        self.process.stdin.flush()

    def reply(self) -> dict[str, Any]:
        try:
            line = self._lines.get(timeout=REPLY_S)
        except queue.Empty:
            pytest.fail(f"no reply within {REPLY_S:.0f} s")
        reply = json.loads(line)
        assert isinstance(reply, dict)
        return reply

    def replies(self, count: int) -> dict[Any, dict[str, Any]]:
        """The next ``count`` replies, by id."""
        return {reply["id"]: reply for reply in (self.reply() for _ in range(count))}

    def request(self, request_id: int, method: str, **params: Any) -> dict[str, Any]:
        message = {"jsonrpc": "2.0", "id": request_id, "method": method} | params
        self.send(json.dumps(message).encode())
        return self.reply()

    def close(self) -> None:
        assert self.process.stdin is not None
        self.process.stdin.close()
        self.process.wait(timeout=60)
        self._err.close()


@pytest.fixture
def server(tmp_path: Path) -> Iterator[Server]:
    log = tmp_path / "server.err"
    served = Server(log)
    try:
        init = {
            "protocolVersion": "2025-06-18",
            "capabilities": {},
            "clientInfo": {"name": "raw", "version": "0"},
        }
        assert "result" in served.request(0, "initialize", params=init)
        served.send(b'{"jsonrpc": "2.0", "method": "notifications/initialized"}')
        yield served
        assert served.request(999, "ping") == {"jsonrpc": "2.0", "id": 999, "result": {}}
    finally:
        if served.process.poll() is None:
            served.close()
    assert served.process.returncode == 0
    assert "Traceback" not in log.read_text()


HUGE_NUMBER = (
    b'{"jsonrpc": "2.0", "id": 3, "method": "ping", "params": {"x": 1' + b"0" * 5000 + b"}}"
)
DEEP = b'{"jsonrpc": "2.0", "id": 4, "method": "ping", "params": ' + b"[" * 99_999 + b"]" * 99_999
MALFORMED: list[tuple[bytes, int | str | None, int]] = [
    (b'{"jsonrpc": "2.0", "id": 1, ', None, PARSE_ERROR),  # invalid JSON
    (b"not json at all", None, PARSE_ERROR),
    (b'{"jsonrpc": "2.0", "id": 2, "method": "ping", "params": {"x": 1,}}', None, PARSE_ERROR),
    (HUGE_NUMBER, 3, INVALID_PARAMS),  # over Python's 4300 digits: its request answered
    (DEEP + b"}", None, PARSE_ERROR),  # nested deeper than the parser goes
    (b"[1, 2, 3]", None, INVALID_REQUEST),  # not an object
    (b"42", None, INVALID_REQUEST),
    (b'{"jsonrpc": "2.0", "id": 5}', 5, INVALID_REQUEST),  # no method
    (b'{"jsonrpc": "2.0", "id": "six", "method": 6}', "six", INVALID_REQUEST),
    (b'{"jsonrpc": "2.0", "id": 7, "method": "tools/call", "params": [1, 2]}', 7, INVALID_REQUEST),
    (b'{"id": 8, "method": "ping"}', 8, INVALID_REQUEST),  # no jsonrpc
    (b'{"jsonrpc": "2.0", "id": true, "method": "ping"}', None, INVALID_REQUEST),
    (b'{"jsonrpc": "2.0", "id": 1.5, "method": "ping"}', None, INVALID_REQUEST),
    # an id of more than 4300 digits is no id (read as 0 it would answer request 0)
    (b'{"jsonrpc": "2.0", "id": ' + b"1" * 5000 + b', "method": "ping"}', None, INVALID_REQUEST),
    # a request with a null id, which the SDK would drop as a notification
    (b'{"jsonrpc": "2.0", "id": null, "method": "ping"}', None, INVALID_REQUEST),
    (b'{"jsonrpc": "2.0", "id": "a\\ud800", "method": "ping"}', None, INVALID_REQUEST),
    (b"", None, PARSE_ERROR),  # a blank line
    (b" \t\r", None, PARSE_ERROR),
]  # fmt: skip


def test_every_malformed_line_is_answered_with_a_json_rpc_error(server: Server) -> None:
    for line, request_id, code in MALFORMED:
        server.send(line)
        reply = server.reply()
        assert reply["id"] == request_id, (line[:80], reply)
        assert reply["error"]["code"] == code, (line[:80], reply)
        assert "\n" not in reply["error"]["message"]
    # a well-formed request with an unknown method is the SDK's to answer
    assert server.request(9, "no/such/method")["error"]["code"] == -32601


def test_a_trailing_carriage_return_and_a_response_with_a_null_id_get_no_error(
    server: Server,
) -> None:
    server.send(b'{"jsonrpc": "2.0", "id": 12, "method": "ping"}\r')
    assert server.reply() == {"jsonrpc": "2.0", "id": 12, "result": {}}
    server.send(b'{"jsonrpc": "2.0", "id": null, "error": {"code": 1, "message": "x"}}')
    assert server.request(13, "ping") == {"jsonrpc": "2.0", "id": 13, "result": {}}


def test_a_line_over_the_limit_is_refused_and_the_server_lives(server: Server) -> None:
    server.send(b"x" * (MAX_MESSAGE_BYTES + 1))
    reply = server.reply()
    assert reply["id"] is None and reply["error"]["code"] == INVALID_REQUEST
    assert str(MAX_MESSAGE_BYTES) in reply["error"]["message"]
    padded = {"x": "a" * (MAX_MESSAGE_BYTES - 100)}  # just under the limit: read as usual
    assert server.request(10, "ping", params=padded)["id"] == 10
    big = {"x": "a" * (4 * MAX_MESSAGE_BYTES)}  # far over: discarded as it streams in
    server.send(json.dumps({"jsonrpc": "2.0", "id": 11, "method": "ping", "params": big}).encode())
    assert server.reply()["error"]["code"] == INVALID_REQUEST


def test_the_limit_leaves_room_for_the_longest_answer() -> None:
    # every character of an answer's text JSON-escaped as \\uXXXX, with its envelope
    assert 6 * MAX_ANSWER_CHARS + 4096 < MAX_MESSAGE_BYTES


def tool_call(request_id: int, name: str, arguments: str = "{}") -> bytes:
    """A tools/call line with ``arguments`` as JSON text."""
    line = f'{{"jsonrpc": "2.0", "id": {request_id}, "method": "tools/call", '
    return (line + f'"params": {{"name": "{name}", "arguments": {arguments}}}}}').encode()


def test_a_lone_surrogate_in_a_tools_arguments_is_a_typed_refusal(server: Server) -> None:
    for request_id, name, arguments, argument in (
        (20, "start_trial", '{"pattern": "\\ud800"}', "pattern"),
        (21, "start_trial", '{"noise": "none\\udfff.yaml", "seed": 1}', "noise"),
        (22, "submit_answer", '{"answer": {"waypoint": [{"\\udc00": 1}]}}', "answer"),
        (23, "slip_estimate", '{"brick_id": "\\ud83d"}', "brick_id"),
        (24, "start_trial", '{"\\ud800": 1}', "\\ud800"),
    ):
        server.send(tool_call(request_id, name, arguments))
        reply = server.reply()
        assert reply["id"] == request_id and "error" not in reply, reply
        assert reply["result"]["isError"], reply
        refusal = reply["result"]["structuredContent"]["refusal"]
        assert refusal["code"] == "invalid_action", refusal
        assert (
            refusal["detail"] == f"{name}: {argument}: not valid Unicode (holds a lone surrogate)"
        )
    # a pair is one character, and nothing else changed: the trial starts as asked
    server.send(tool_call(25, "start_trial", '{"pattern": "\\ud83d\\ude00.json"}'))
    assert "\U0001f600.json" in server.reply()["result"]["structuredContent"]["refusal"]["detail"]
    server.send(tool_call(26, "start_trial", '{"seed": 4, "trial": 2}'))
    trial = server.reply()["result"]["structuredContent"]["trial"]
    assert (trial["seed"], trial["trial"]) == (4, 2)


def test_tool_calls_sent_together_run_in_the_order_they_arrived(server: Server) -> None:
    order = ["start_trial", "read_state", "read_state", "finish_trial", "read_state"]
    for round_ in range(8):
        ids = [100 * round_ + k for k in range(1, len(order) + 1)]
        server.send(b"\n".join(tool_call(i, name) for i, name in zip(ids, order, strict=True)))
        replies = server.replies(len(ids))
        refused = [replies[i]["result"]["isError"] for i in ids]
        assert refused == [False, False, False, False, True], (round_, replies)
        assert replies[ids[4]]["result"]["structuredContent"]["refusal"]["code"] == "no_trial"


def test_a_call_the_sdk_refuses_or_the_client_cancels_holds_up_no_later_call(
    server: Server,
) -> None:
    cancel = b'{"jsonrpc": "2.0", "method": "notifications/cancelled", "params": {"requestId": 31}}'
    server.send(
        b"\n".join(
            [
                tool_call(30, "start_trial"),
                tool_call(31, "read_state"),  # cancelled: answered or not, never waited on
                cancel,
                tool_call(32, "read_state", "[1]"),  # the SDK's own error: never run
                tool_call(33, "read_state"),
            ]
        )
    )
    replies = server.replies(3)
    if 31 in replies:  # it ran before its cancellation was read
        replies |= server.replies(1)
    assert replies[32]["error"]["code"] == INVALID_PARAMS
    assert not replies[33]["result"]["isError"]  # after start_trial: the trial is there
