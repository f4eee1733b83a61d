"""A small OpenAI-compatible VLM server for tests and GPU-free trials of the reasoning loop (Sec. IV).

It speaks ``GET /v1/models`` and ``POST /v1/chat/completions`` like vLLM, and answers the three DRIVE-Nav
questions, ApexNav's category question (:mod:`drivenav.semantics.prompts`) and the floor question
(:func:`drivenav.semantics.openai_backend.floor_text`) without looking at the images: the question is recognised by
the answer schema its text ends with. Modes:

- ``ok``: valid JSON: the first direction label mentioned, target not visible, phrase = the goal, "sure"; for a
  category, :data:`FAKE_SIMILAR` (less the goal), threshold 0.45, any room; for a floor, :data:`FAKE_FLOOR`;
- ``fenced``: the same answer in a Markdown ```json fence after a line of prose;
- ``garbage``: prose without JSON;
- ``bad-then-good``: a malformed answer, then a valid one once the conversation holds a repair request;
- ``error``: HTTP 500; ``flaky``: HTTP 503 for the first ``fail_first`` chat requests, then ``ok``;
- ``stall``: waits ``stall_s`` seconds before answering; ``empty``: a reply with no choices.

``GET /v1/_stats`` returns the request counts, the last chat request bodies and their ``Authorization``
headers, so tests can check what a client sent. Run ``python -m drivenav.semantics.fake_vlm_server --port 0
--mode ok``: the first line printed is the base URL to give the ``openai`` reasoner.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import re
import threading
import urllib.request
from collections import deque
from collections.abc import Callable, Sequence
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

from drivenav.jsonstream import JsonObject
from drivenav.semantics.openai_backend import FLOOR_SCHEMA
from drivenav.semantics.prompts import GOAL_PREFIX, HINTS_SCHEMA, PROPOSE_SCHEMA, SELECT_SCHEMA, VERIFY_SCHEMA
from drivenav.semantics.protocols import EVERYWHERE, FloorGuess

MODES = ("ok", "fenced", "garbage", "bad-then-good", "error", "flaky", "stall", "empty")
MALFORMED = '{"direction": "left", "target_visible": "maybe", "phrase": "", "judgement": "probably", "floor": "up"}'
_GOAL = re.compile(re.escape(GOAL_PREFIX) + r'("(?:[^"\\]|\\.)*")')
_LABEL = re.compile(r"direction (\d+)")
FAKE_SIMILAR = ("chair", "table", "cabinet")
"""The confusable objects the fake model names for any category."""
FAKE_FLOOR: FloorGuess = "other"
"""The fake model's floor answer for any goal and views: the one that makes an agent act (leave the floor)."""


def _texts(message: Any) -> str:
    """The text of a chat message, whether its content is a string or a list of parts."""
    content = message.get("content") if isinstance(message, dict) else None
    if isinstance(content, str):
        return content
    parts = content if isinstance(content, list) else []
    return "\n".join(str(part.get("text", "")) for part in parts if isinstance(part, dict))


def _question_answer(question: str) -> JsonObject:
    """A valid answer to the question text, recognised by its schema."""
    found = _GOAL.search(question)
    goal = json.loads(found.group(1)) if found else "object"
    if VERIFY_SCHEMA in question:
        return {"judgement": "sure"}
    if PROPOSE_SCHEMA in question:
        return {"phrase": goal}
    if HINTS_SCHEMA in question:
        return {"similar_objects": [n for n in FAKE_SIMILAR if n != goal], "threshold": 0.45, "room": EVERYWHERE}
    if FLOOR_SCHEMA in question:
        return {"floor": FAKE_FLOOR}
    if SELECT_SCHEMA in question:
        labels = list(dict.fromkeys(int(label) for label in _LABEL.findall(question)))
        return {
            "direction": labels[0] if labels else None,
            "target_visible": False,
            "target_direction": None,
            "descriptions": {str(label): f"a room seen towards direction {label}" for label in labels},
        }
    return {"error": "unrecognised question"}


def fake_answer(mode: str, messages: Sequence[Any]) -> str:
    """The assistant text the server answers ``messages`` with in ``mode`` (HTTP-level modes excluded)."""
    users = [m for m in messages if isinstance(m, dict) and m.get("role") == "user"]
    repairing = any(isinstance(m, dict) and m.get("role") == "assistant" for m in messages)
    if mode == "garbage":
        return "I looked carefully, but I would rather not say."
    if mode == "bad-then-good" and not repairing:
        return MALFORMED
    answer = json.dumps(_question_answer(_texts(users[0]) if users else ""))
    return f"Here is my answer.\n```json\n{answer}\n```" if mode == "fenced" else answer


class FakeVLMServer(ThreadingHTTPServer):
    """The server, bound to 127.0.0.1; :meth:`start` serves from a daemon thread and :meth:`stop` ends it."""

    daemon_threads = True

    def __init__(
        self,
        port: int = 0,
        mode: str = "ok",
        model: str = "fake-vlm",
        api_key: str | None = None,
        fail_first: int = 2,
        stall_s: float = 10.0,
        keep: int = 20,
    ) -> None:
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
        super().__init__(("127.0.0.1", port), _Handler)
        self.mode = mode
        self.model = model
        self.api_key = api_key
        self.fail_first = fail_first
        self.stall_s = stall_s
        self.requests = 0
        self.chat_requests = 0
        self.bodies: deque[Any] = deque(maxlen=keep)
        self.authorizations: deque[str | None] = deque(maxlen=keep)
        self.lock = threading.Lock()
        self.stopping = threading.Event()
        self._stopped = False
        self._timer: threading.Timer | None = None

    @property
    def url(self) -> str:
        """The base URL clients use (``.../v1``)."""
        return f"http://127.0.0.1:{self.server_address[1]}/v1"

    def start(self, lifetime: float | None) -> None:
        """Serve from a daemon thread; stop by itself after ``lifetime`` seconds (``None``: until :meth:`stop`)."""
        threading.Thread(target=self.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True).start()
        if lifetime is not None:
            self._timer = threading.Timer(lifetime, self.stop)
            self._timer.daemon = True
            self._timer.start()

    def stop(self) -> None:
        """Stop serving, wake stalled handlers and close the socket; later calls do nothing."""
        with self.lock:
            if self._stopped:
                return
            self._stopped = True
        self.stopping.set()
        if self._timer is not None:
            self._timer.cancel()
        self.shutdown()
        self.server_close()

    def stats(self) -> JsonObject:
        with self.lock:
            return {
                "requests": self.requests,
                "chat_requests": self.chat_requests,
                "bodies": list(self.bodies),
                "authorizations": list(self.authorizations),
            }


class _Handler(BaseHTTPRequestHandler):
    server: FakeVLMServer

    def log_message(self, format: str, *args: Any) -> None:
        """Quiet: tests and trial runs do not want a line per request."""

    def do_GET(self) -> None:
        with self.server.lock:
            self.server.requests += 1
        if self.path == "/v1/models":
            self._json(200, {"object": "list", "data": [{"id": self.server.model, "object": "model"}]})
        elif self.path == "/v1/_stats":
            self._json(200, self.server.stats())
        else:
            self._json(404, {"error": {"message": f"no route {self.path}"}})

    def do_POST(self) -> None:
        body = self.rfile.read(int(self.headers.get("Content-Length") or 0))
        try:
            request = json.loads(body)
        except ValueError:
            request = None
        with self.server.lock:
            self.server.requests += 1
            self.server.chat_requests += 1
            count = self.server.chat_requests
            self.server.bodies.append(request)
            self.server.authorizations.append(self.headers.get("Authorization"))
        refusal = self._refusal(request, count)
        if refusal is not None:
            self._json(*refusal)
        elif self.server.mode == "stall" and self.server.stopping.wait(self.server.stall_s):
            return  # stopped while stalling: leave without answering
        elif self.server.mode == "empty":
            self._json(200, {"object": "chat.completion", "choices": []})
        else:
            self._completion(fake_answer(self.server.mode, request["messages"]))

    def _refusal(self, request: Any, count: int) -> tuple[int, JsonObject] | None:
        """The HTTP error this request gets, if any, checked in the order vLLM would."""
        expected = f"Bearer {self.server.api_key}" if self.server.api_key else None
        if self.path != "/v1/chat/completions":
            return 404, {"error": {"message": f"no route {self.path}"}}
        if expected is not None and self.headers.get("Authorization") != expected:
            return 401, {"error": {"message": "invalid API key"}}
        if not (isinstance(request, dict) and isinstance(request.get("messages"), list)):
            return 400, {"error": {"message": "body must be a JSON object with a messages list"}}
        if request.get("model") != self.server.model:
            return 404, {"error": {"message": f"the model {request.get('model')!r} does not exist"}}
        if self.server.mode == "error":
            return 500, {"error": {"message": "fake internal error"}}
        if self.server.mode == "flaky" and count <= self.server.fail_first:
            return 503, {"error": {"message": "fake overload, try again"}}
        return None

    def _completion(self, text: str) -> None:
        message = {"role": "assistant", "content": text}
        choice = {"index": 0, "message": message, "finish_reason": "stop"}
        self._json(200, {"object": "chat.completion", "model": self.server.model, "choices": [choice]})

    def _json(self, status: int, payload: Any) -> None:
        data = json.dumps(payload).encode("utf-8")
        try:
            self.send_response(status)
            self.send_header("Content-Type", "application/json")
            self.send_header("Content-Length", str(len(data)))
            self.end_headers()
            self.wfile.write(data)
        except (BrokenPipeError, ConnectionResetError):
            pass  # the client gave up (a timeout test): nothing to tell it


def start_fake_server(
    mode: str = "ok",
    *,
    model: str = "fake-vlm",
    api_key: str | None = None,
    fail_first: int = 2,
    stall_s: float = 10.0,
    lifetime: float = 60.0,
) -> tuple[str, Callable[[], None]]:
    """Start a server on a free 127.0.0.1 port; returns its base URL and a stop function.

    It stops by itself after ``lifetime`` seconds even if the stop function is never called.
    """
    server = FakeVLMServer(0, mode, model, api_key, fail_first, stall_s)
    server.start(lifetime)
    return server.url, server.stop


def fake_stats(url: str, timeout: float = 5.0) -> JsonObject:
    """The ``/_stats`` of the fake server at base URL ``url``: counts, last bodies and Authorization headers."""
    with urllib.request.urlopen(f"{url}/_stats", timeout=timeout) as response:
        stats: JsonObject = json.loads(response.read())
    return stats


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description="A fake OpenAI-compatible VLM server for DRIVE-Nav trials.")
    parser.add_argument("--port", type=int, default=0, help="port on 127.0.0.1 (0: any free port)")
    parser.add_argument("--mode", choices=MODES, default="ok")
    parser.add_argument("--model", default="fake-vlm", help="the model id it serves")
    parser.add_argument("--api-key", default=None, help="require this bearer token")
    parser.add_argument("--fail-first", type=int, default=2, help="flaky mode: chat requests failing with 503")
    parser.add_argument("--stall-s", type=float, default=10.0, help="stall mode: seconds before answering")
    parser.add_argument("--lifetime", type=float, default=None, help="stop after this many seconds")
    args = parser.parse_args(argv)
    server = FakeVLMServer(args.port, args.mode, args.model, args.api_key, args.fail_first, args.stall_s)
    server.start(args.lifetime)
    print(server.url, flush=True)
    print(f"fake VLM server, mode {args.mode}, model {args.model!r}; Ctrl-C stops it", flush=True)
    with contextlib.suppress(KeyboardInterrupt):
        server.stopping.wait()
    server.stop()


if __name__ == "__main__":
    main()
