"""A scripted OpenAI-compatible chat-completions server on loopback, for tests.

``FakeLLMServer(script)`` listens on ``127.0.0.1`` at a free port (``http.server`` in a
thread). Each POST to ``/v1/chat/completions`` takes the next behaviour of ``script`` (the last
one repeats once the script runs out) and is recorded in ``requests`` (path, headers, parsed
JSON body) *before* the behaviour runs. Behaviours are built by the small functions below::

    with FakeLLMServer([answer('{"assignment": [1, 0]}'), status(500)]) as srv:
        ...  # srv.base_url == "http://127.0.0.1:<port>/v1"

``rotate(shift)`` answers from the prompt itself: it reads "Assign each of the N agents ...
in [0, K)" from the last message and assigns agent i -> (i + shift) % K, with usage counted
from the request (:func:`prompt_words`, :func:`words`), so a test can recompute every token
the planner should have accounted for from ``requests``.
"""

from __future__ import annotations

import json
import re
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer


def answer(content: str, prompt_tokens: int | None = 50, completion_tokens: int | None = 7,
           usage: bool = True) -> dict:
    """A 200 chat completion whose message content is ``content``; ``usage=False`` omits the
    ``usage`` field."""
    return {"kind": "answer", "content": content, "usage": usage,
            "prompt_tokens": prompt_tokens, "completion_tokens": completion_tokens}


def assignment(values, **kw) -> dict:
    """A 200 chat completion whose content is ``{"assignment": values}``."""
    return answer(json.dumps({"assignment": list(values)}), **kw)


_ASK = re.compile(r"Assign each of the (\d+) agents .*? in \[0, (\d+)\)", re.DOTALL)


def rotate(shift: int = 1) -> dict:
    """A 200 chat completion computed from the request: agent i -> (i + shift) % K for the
    N agents and K targets the last message asks for (``{"assignment": []}`` if it asks for
    none); usage: ``prompt_tokens`` = :func:`prompt_words` of the request,
    ``completion_tokens`` = :func:`words` of the answer."""
    return {"kind": "rotate", "shift": int(shift)}


def words(text: str) -> int:
    """Whitespace-separated words of ``text`` (the fake server's token count)."""
    return len(text.split())


def prompt_words(body: dict) -> int:
    """The fake server's prompt-token count of a request body: words over all messages."""
    return sum(words(m.get("content", "")) for m in body.get("messages", []))


def rotated(body: dict, shift: int = 1) -> str:
    """The content :func:`rotate` answers to the request ``body``."""
    m = _ASK.search(body["messages"][-1]["content"])
    if m is None:
        return json.dumps({"assignment": []})
    n, k = int(m.group(1)), int(m.group(2))
    return json.dumps({"assignment": [(i + shift) % k for i in range(n)]})


def status(code: int, body: str = '{"error": {"message": "scripted failure"}}') -> dict:
    """An HTTP error ``code`` with a JSON error body."""
    return {"kind": "status", "code": code, "body": body}


def raw(body: bytes | str, code: int = 200) -> dict:
    """A response whose body is ``body`` verbatim (e.g. not JSON, or JSON without choices)."""
    return {"kind": "raw", "code": code, "body": body}


def sleep(seconds: float, then: dict | None = None) -> dict:
    """Wait ``seconds`` before behaving as ``then`` (a valid empty-ish answer by default)."""
    return {"kind": "sleep", "seconds": seconds, "then": then or answer('{"assignment": []}')}


class _Handler(BaseHTTPRequestHandler):
    server: "_Server"

    def log_message(self, *args):  # keep test output quiet
        pass

    def do_POST(self):  # noqa: N802 - http.server's naming
        length = int(self.headers.get("Content-Length", 0))
        body = self.rfile.read(length)
        try:
            parsed = json.loads(body)
        except ValueError:
            parsed = None
        behaviour = self.server.owner._record(self.path, dict(self.headers), parsed)
        try:
            self._behave(behaviour, parsed)
        except (BrokenPipeError, ConnectionResetError):
            pass  # the client gave up (timeout): nothing to answer

    def _send(self, code: int, body: bytes, content_type: str = "application/json"):
        self.send_response(code)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def _behave(self, b: dict, request: dict | None):
        if b["kind"] == "sleep":
            time.sleep(b["seconds"])
            return self._behave(b["then"], request)
        if b["kind"] == "status":
            return self._send(b["code"], b["body"].encode())
        if b["kind"] == "raw":
            body = b["body"].encode() if isinstance(b["body"], str) else b["body"]
            return self._send(b["code"], body, "text/plain")
        if b["kind"] == "rotate":
            content = rotated(request or {}, b["shift"])
            b = answer(content, prompt_tokens=prompt_words(request or {}),
                       completion_tokens=words(content))
        response = {
            "id": "chatcmpl-fake",
            "object": "chat.completion",
            "created": 0,
            "model": (request or {}).get("model", "fake"),
            "choices": [{"index": 0, "finish_reason": "stop",
                         "message": {"role": "assistant", "content": b["content"]}}],
        }
        if b["usage"]:
            p, c = b["prompt_tokens"], b["completion_tokens"]
            response["usage"] = {"prompt_tokens": p, "completion_tokens": c,
                                 "total_tokens": (p or 0) + (c or 0)}
        return self._send(200, json.dumps(response).encode())


class _Server(ThreadingHTTPServer):
    daemon_threads = True
    block_on_close = False
    owner: "FakeLLMServer"


class FakeLLMServer:
    """The scripted server; a context manager that starts and stops it."""

    def __init__(self, script: list[dict]):
        if not script:
            raise ValueError("the script needs at least one behaviour")
        self.script = list(script)
        self.requests: list[dict] = []
        self._lock = threading.Lock()
        self._httpd: _Server | None = None
        self._thread: threading.Thread | None = None
        self._port: int | None = None

    def _record(self, path: str, headers: dict, body: dict | None) -> dict:
        with self._lock:
            i = len(self.requests)
            self.requests.append({"path": path, "headers": headers, "body": body})
            return self.script[min(i, len(self.script) - 1)]

    @property
    def port(self) -> int:
        """The port it listens (or listened) on."""
        return self._port

    @property
    def base_url(self) -> str:
        return f"http://127.0.0.1:{self.port}/v1"

    def start(self) -> "FakeLLMServer":
        self._httpd = _Server(("127.0.0.1", 0), _Handler)
        self._httpd.owner = self
        self._port = self._httpd.server_address[1]
        self._thread = threading.Thread(target=self._httpd.serve_forever,
                                        kwargs={"poll_interval": 0.02}, daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        if self._httpd is not None:
            self._httpd.shutdown()
            self._httpd.server_close()
            self._thread.join(timeout=5)
            self._httpd = None

    def __enter__(self) -> "FakeLLMServer":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()
