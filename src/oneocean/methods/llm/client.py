"""An OpenAI-compatible chat-completions client using only the standard library.

Works against any endpoint speaking ``POST {base_url}/chat/completions`` (vLLM, llama.cpp
server, Ollama, hosted APIs). The API key is read from the environment variable *named* in the
configuration (the key itself is never part of the configuration). Every request uses the
configured temperature (0 by default), timeout and output-token limit.
:class:`CachedClient` puts the response cache in front of any backend (this endpoint client,
:class:`~oneocean.methods.llm.local.LocalClient`): a hit replays the reply with the usage and
latency recorded when it was fetched.

Failures of the endpoint -- HTTP errors, timeouts, refused connections, malformed responses --
become an :class:`LLMError` with a one-line message and a ``kind``; the caller (the planner)
turns those into its fallback and never crashes. Bad *configuration* is a
:class:`~oneocean.errors.ConfigError`, raised when the client is built.
"""

from __future__ import annotations

import http.client
import json
import os
import time
import urllib.error
import urllib.request
from dataclasses import dataclass
from typing import Any, Sequence

from oneocean.errors import ConfigError

from .cache import ResponseCache, cache_key

#: ``LLMError.kind`` values: what went wrong talking to the endpoint.
ERROR_KINDS = ("http", "timeout", "connection", "bad_response")


class LLMError(RuntimeError):
    """The endpoint gave no usable reply.

    ``str(err)`` is one line.

    Parameters
    ----------
    kind : str
        What went wrong, one of :data:`ERROR_KINDS`; kept as ``err.kind``.
    message : str
        The message, collapsed to one line.
    latency_s : float, optional
        Wall time spent before giving up, s (default 0; kept as ``err.latency_s``).
    """

    def __init__(self, kind: str, message: str, latency_s: float = 0.0):
        assert kind in ERROR_KINDS, kind
        super().__init__(" ".join(str(message).split()))
        self.kind = kind
        self.latency_s = latency_s


@dataclass(frozen=True)
class ClientConfig:
    """Where and how to ask; checked when built (:func:`check_config`).

    Parameters
    ----------
    base_url : str
        The API root including its version prefix (e.g. ``http://127.0.0.1:8000/v1``).
    model : str
        Model id sent to the endpoint (part of the cache key).
    api_key_env : str, optional
        Name of the environment variable holding the key (default ``""``: send no key, as local
        servers usually need none).
    temperature : float, optional
        Sampling temperature, >= 0 (default 0).
    timeout_s : float, optional
        Bound of each socket operation (connect, each read), s (default 30).
    max_tokens : int, optional
        Output-token limit, >= 1 (default 256).

    Raises
    ------
    ConfigError
        One line, if the configuration cannot work.
    """

    base_url: str
    model: str
    api_key_env: str = ""
    temperature: float = 0.0
    timeout_s: float = 30.0
    max_tokens: int = 256

    def __post_init__(self):
        check_config(self)


def _is_number(value) -> bool:
    """True for an int or float that is not a bool."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def check_config(cfg: ClientConfig) -> None:
    """Check a client configuration.

    Parameters
    ----------
    cfg : ClientConfig
        The configuration.

    Raises
    ------
    ConfigError
        One line, naming the first key that cannot work (URL not http(s), empty model, a
        non-string ``api_key_env``, a negative temperature, a timeout <= 0, ``max_tokens`` < 1).
    """
    url, model, env = cfg.base_url, cfg.model, cfg.api_key_env
    if not isinstance(url, str) or not url.startswith(("http://", "https://")):
        raise ConfigError(f"llm.base_url must be an http(s) URL, got {url!r}")
    if not isinstance(model, str) or not model.strip():
        raise ConfigError(f"llm.model must be a non-empty string, got {model!r}")
    if not isinstance(env, str):
        raise ConfigError(f"llm.api_key_env must name an environment variable, got {env!r}")
    if not _is_number(cfg.temperature) or cfg.temperature < 0:
        raise ConfigError(f"llm.temperature must be a number >= 0, got {cfg.temperature!r}")
    if not _is_number(cfg.timeout_s) or cfg.timeout_s <= 0:
        raise ConfigError(f"llm.timeout_s must be a number > 0, got {cfg.timeout_s!r}")
    if not isinstance(cfg.max_tokens, int) or isinstance(cfg.max_tokens, bool) \
            or cfg.max_tokens < 1:
        raise ConfigError(f"llm.max_tokens must be an integer >= 1, got {cfg.max_tokens!r}")


def read_api_key(env_name: str, environ: dict | None = None) -> str | None:
    """The API key from the environment variable ``env_name``.

    Parameters
    ----------
    env_name : str
        The variable's name; empty: no key.
    environ : dict, optional
        The environment (default ``os.environ``).

    Returns
    -------
    str or None
        The key; None if ``env_name`` is empty.

    Raises
    ------
    ConfigError
        One line naming the variable (never showing any value) if it is unset or empty.
    """
    if not env_name:
        return None
    environ = os.environ if environ is None else environ
    key = environ.get(env_name, "")
    if not key:
        raise ConfigError(f"llm.api_key_env names the environment variable {env_name}, "
                          f"which is not set (export it, or set llm.api_key_env to '' for no key)")
    return key


@dataclass(frozen=True)
class Reply:
    """One chat completion.

    ``latency_s`` is the wall time of the request that fetched the reply: a cache hit carries
    the latency (and the usage) recorded when the reply was first fetched, so a rerun from the
    cache reports the same numbers (``cached`` tells the two apart).

    Parameters
    ----------
    text : str
        The assistant's text.
    prompt_tokens, completion_tokens : int or None
        Token counts from the API's ``usage`` (None where the endpoint gave none).
    latency_s : float
        Wall time of the fetching request, s.
    cached : bool
        True if served from the response cache.
    """

    text: str
    prompt_tokens: int | None
    completion_tokens: int | None
    latency_s: float
    cached: bool


def endpoint_url(base_url: str) -> str:
    """The chat-completions URL of an API root.

    Parameters
    ----------
    base_url : str
        The API root.

    Returns
    -------
    str
        ``{base_url}/chat/completions`` with exactly one slash between.
    """
    return base_url.rstrip("/") + "/chat/completions"


def request_body(cfg: ClientConfig, messages: Sequence[dict]) -> dict:
    """The JSON body of a chat-completions request.

    Parameters
    ----------
    cfg : ClientConfig
        Model, temperature and output-token limit.
    messages : sequence of dict
        Chat messages (``role``, ``content``).

    Returns
    -------
    dict
        ``model``, ``messages``, ``temperature``, ``max_tokens`` and ``stream: False``.
    """
    return {
        "model": cfg.model,
        "messages": [dict(m) for m in messages],
        "temperature": float(cfg.temperature),
        "max_tokens": int(cfg.max_tokens),
        "stream": False,
    }


def _usage_count(usage: Any, name: str) -> int | None:
    """``usage[name]`` if it is a non-negative integer, else None."""
    if not isinstance(usage, dict):
        return None
    value = usage.get(name)
    if isinstance(value, int) and not isinstance(value, bool) and value >= 0:
        return value
    return None


def parse_response(raw: bytes) -> tuple[str, int | None, int | None]:
    """The text and token counts of a chat-completions response body.

    Parameters
    ----------
    raw : bytes
        The response body (UTF-8 JSON).

    Returns
    -------
    text : str
        The assistant's text.
    prompt_tokens, completion_tokens : int or None
        Token counts (None where the response has none).

    Raises
    ------
    LLMError
        Kind ``bad_response``, if the body is not the expected JSON.
    """
    try:
        data = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as err:
        raise LLMError("bad_response", f"llm: response body is not JSON ({err})") from None
    return parse_completion(data)


def parse_completion(data: Any) -> tuple[str, int | None, int | None]:
    """The text and token counts of a decoded chat completion.

    The OpenAI layout: ``choices[0].message.content`` and ``usage``.

    Parameters
    ----------
    data : dict
        The decoded completion.

    Returns
    -------
    text : str
        The assistant's text.
    prompt_tokens, completion_tokens : int or None
        Token counts from ``usage`` (None where absent or not a non-negative integer).

    Raises
    ------
    LLMError
        Kind ``bad_response``, if it has no string content.
    """
    try:
        text = data["choices"][0]["message"]["content"]
    except (KeyError, IndexError, TypeError):
        raise LLMError("bad_response",
                       "llm: response has no choices[0].message.content") from None
    if not isinstance(text, str):
        raise LLMError("bad_response",
                       f"llm: choices[0].message.content is {type(text).__name__}, not a string")
    usage = data.get("usage") if isinstance(data, dict) else None
    return text, _usage_count(usage, "prompt_tokens"), _usage_count(usage, "completion_tokens")


def _snippet(raw: bytes, limit: int = 160) -> str:
    """The first ``limit`` characters of an error body, on one line."""
    text = " ".join(raw.decode("utf-8", "replace").split())
    return text[:limit] + ("..." if len(text) > limit else "")


def post_json(url: str, body: dict, headers: dict, timeout_s: float) -> bytes:
    """POST ``body`` as JSON and return the response body.

    Parameters
    ----------
    url : str
        The endpoint.
    body : dict
        The request body.
    headers : dict
        Extra headers (``Content-Type: application/json`` is always sent).
    timeout_s : float
        Bound of each socket operation, s.

    Returns
    -------
    bytes
        The response body.

    Raises
    ------
    LLMError
        Every failure: kinds ``http``, ``timeout``, ``connection``, ``bad_response``.
    """
    data = json.dumps(body).encode("utf-8")
    req = urllib.request.Request(url, data=data, method="POST",
                                 headers={"Content-Type": "application/json", **headers})
    try:
        with urllib.request.urlopen(req, timeout=timeout_s) as resp:
            return resp.read()
    except urllib.error.HTTPError as err:
        try:
            detail = _snippet(err.read())
        except Exception:  # noqa: BLE001 - the status alone is the message then
            detail = ""
        suffix = f": {detail}" if detail else ""
        raise LLMError("http", f"llm: HTTP {err.code} from {url}{suffix}") from None
    except urllib.error.URLError as err:
        if isinstance(err.reason, TimeoutError):
            raise LLMError("timeout", f"llm: no answer from {url} within {timeout_s:g} s") from None
        raise LLMError("connection", f"llm: cannot reach {url}: {err.reason}") from None
    except TimeoutError:
        raise LLMError("timeout", f"llm: no answer from {url} within {timeout_s:g} s") from None
    except http.client.HTTPException as err:
        raise LLMError("bad_response", f"llm: bad HTTP response from {url}: "
                                       f"{type(err).__name__} {err}") from None
    except OSError as err:
        raise LLMError("connection", f"llm: connection to {url} failed: {err}") from None


class CachedClient:
    """Chat completions through an optional :class:`~oneocean.methods.llm.cache.ResponseCache`.

    A subclass sets ``config`` (anything with ``model``, ``temperature`` and ``max_tokens``)
    and ``cache`` and implements :meth:`fetch`; :meth:`complete` looks the messages up in the
    cache, else fetches, times and stores the reply. A ``constrained`` client decodes under
    the reply's JSON schema, which is then part of the cache key.
    """

    config: Any
    cache: ResponseCache | None = None
    constrained: bool = False

    def key(self, messages: Sequence[dict], schema: dict | None = None) -> str:
        """The cache key of ``messages`` under this client's model and sampling settings.

        Parameters
        ----------
        messages : sequence of dict
            Chat messages.
        schema : dict, optional
            The reply's JSON schema (in the key only if the client is ``constrained``).

        Returns
        -------
        str
            The hex sha256 (:func:`~oneocean.methods.llm.cache.cache_key`).
        """
        cfg = self.config
        return cache_key(cfg.model, messages, cfg.temperature, cfg.max_tokens,
                         schema if self.constrained else None)

    def fetch(self, messages: Sequence[dict],
              schema: dict | None = None) -> tuple[str, int | None, int | None]:
        """Ask the model (a subclass's request).

        Parameters
        ----------
        messages : sequence of dict
            Chat messages.
        schema : dict, optional
            The reply's JSON schema (used by ``constrained`` clients).

        Returns
        -------
        text : str
            The assistant's text.
        prompt_tokens, completion_tokens : int or None
            Token counts.

        Raises
        ------
        LLMError
            Any failure (the only exception it raises).
        """
        raise NotImplementedError

    def complete(self, messages: Sequence[dict], schema: dict | None = None) -> Reply:
        """The reply to ``messages``, from the cache if present, else from the model.

        A hit makes no request and carries the latency and usage recorded when it was fetched
        (``cached=True``); a miss is fetched, timed and stored in the cache.

        Parameters
        ----------
        messages : sequence of dict
            Chat messages.
        schema : dict, optional
            The reply's JSON schema (a ``constrained`` client decodes under it).

        Returns
        -------
        Reply
            The reply.

        Raises
        ------
        LLMError
            If the model gave no usable reply (its ``latency_s`` set); nothing else.
        """
        key = self.key(messages, schema) if self.cache is not None else None
        if key is not None:
            hit = self.cache.get(key)
            if hit is not None:
                return Reply(hit["text"], hit["prompt_tokens"], hit["completion_tokens"],
                             latency_s=float(hit["latency_s"]), cached=True)
        cfg = self.config
        t0 = time.perf_counter()
        try:
            text, n_prompt, n_out = self.fetch(messages, schema)
        except LLMError as err:
            err.latency_s = time.perf_counter() - t0
            raise
        latency = time.perf_counter() - t0
        if key is not None:
            self.cache.put(key, {
                "model": cfg.model,
                "messages": [dict(m) for m in messages],
                "temperature": float(cfg.temperature),
                "max_tokens": int(cfg.max_tokens),
                "text": text,
                "prompt_tokens": n_prompt,
                "completion_tokens": n_out,
                "latency_s": latency,
            })
        return Reply(text, n_prompt, n_out, latency_s=latency, cached=False)


class LLMClient(CachedClient):
    """Chat completions against one configured endpoint, optionally through a cache.

    The cache is a :class:`~oneocean.methods.llm.cache.ResponseCache` (:class:`CachedClient`).
    The key is read once, when the client is built (a missing variable is a
    :class:`ConfigError` then, not mid-episode), and never appears in ``repr``.

    Parameters
    ----------
    config : ClientConfig
        The endpoint.
    cache : ResponseCache, optional
        The response cache (None: every call asks).
    environ : dict, optional
        The environment to read the key from (default ``os.environ``).
    """

    def __init__(self, config: ClientConfig, cache: ResponseCache | None = None,
                 environ: dict | None = None):
        self.config = config
        self.cache = cache
        self._api_key = read_api_key(config.api_key_env, environ)

    def __repr__(self) -> str:
        return (f"LLMClient(model={self.config.model!r}, base_url={self.config.base_url!r}, "
                f"cache={self.cache!r})")

    def headers(self) -> dict:
        """Request headers beyond Content-Type.

        Returns
        -------
        dict
            ``Authorization: Bearer <key>`` when a key is set, else empty.
        """
        return {"Authorization": f"Bearer {self._api_key}"} if self._api_key else {}

    def fetch(self, messages: Sequence[dict],
              schema: dict | None = None) -> tuple[str, int | None, int | None]:
        """One POST to the endpoint (unconstrained: ``schema`` is not sent).

        Parameters
        ----------
        messages : sequence of dict
            Chat messages.
        schema : dict, optional
            Ignored (the reply is validated afterwards).

        Returns
        -------
        text : str
            The assistant's text.
        prompt_tokens, completion_tokens : int or None
            Token counts.

        Raises
        ------
        LLMError
            Any failure of the endpoint (:func:`post_json`, :func:`parse_response`).
        """
        cfg = self.config
        raw = post_json(endpoint_url(cfg.base_url), request_body(cfg, messages),
                        self.headers(), cfg.timeout_s)
        return parse_response(raw)
