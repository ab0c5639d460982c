"""Discrete plans from an LLM: prompt, validation against a schema, deterministic fallback,
and per-episode accounting.

A plan is an assignment of integers, ``{"assignment": [i_0, ..., i_{N-1}]}`` with exactly N
entries each in ``[0, K)`` (a source per agent for SPC, a waypoint offset per agent for AS and
PI). :class:`Planner` asks the model, validates the answer and, if the answer is invalid or
never came (:class:`~oneocean.methods.llm.client.LLMError`: HTTP error, timeout, refused
connection, malformed response), returns the caller's deterministic fallback instead -- never
raising. Each call yields a :class:`CallRecord`; :func:`episode_totals` sums them into the
cost-table columns.
"""

from __future__ import annotations

import json
import math
import operator
import re
from dataclasses import dataclass
from typing import Iterable, Sequence

import jsonschema
from jsonschema.exceptions import best_match

from .client import LLMClient, LLMError

#: ``CallRecord.fallback_reason`` values when the model answered but the answer is unusable
#: (the others are :data:`~oneocean.methods.llm.client.ERROR_KINDS`: no answer at all).
INVALID_REASONS = ("not_json", "schema")

DEFAULT_SYSTEM_PROMPT = (
    "You are the high-level planner of a team of marine robots. You receive a compact summary "
    "of the task state and answer with a single JSON object and nothing else."
)

_FENCE = re.compile(r"```(?:json|JSON)?[ \t]*\n?(.*?)```", re.DOTALL)


def assignment_schema(n_agents: int, n_targets: int) -> dict:
    """JSON schema of an assignment of ``n_agents`` agents to ``n_targets`` targets.

    ``{"assignment": [...]}`` with exactly ``n_agents`` integers in ``[0, n_targets)``. Other
    keys (e.g. a model's ``"reason"``) are allowed and ignored.

    Parameters
    ----------
    n_agents : int
        Agents, >= 1.
    n_targets : int
        Targets, >= 1.

    Returns
    -------
    dict
        A JSON Schema (draft 2020-12).

    Raises
    ------
    ValueError
        If a count is not an integer >= 1.
    """
    n_agents, n_targets = _count(n_agents, "n_agents"), _count(n_targets, "n_targets")
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "type": "object",
        "required": ["assignment"],
        "properties": {
            "assignment": {
                "type": "array",
                "minItems": n_agents,
                "maxItems": n_agents,
                "items": {"type": "integer", "minimum": 0, "maximum": n_targets - 1},
            }
        },
    }


def _count(value, name: str) -> int:
    """``value`` as a Python int >= 1 (numpy integers accepted); ``ValueError`` otherwise."""
    try:
        n = operator.index(value)
    except TypeError:
        raise ValueError(f"{name} must be an integer >= 1, got {value!r}") from None
    if isinstance(value, bool) or n < 1:
        raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
    return n


@dataclass(frozen=True)
class PlanInvalid:
    """Why a model's text is not a plan.

    Parameters
    ----------
    reason : str
        One of :data:`INVALID_REASONS`.
    message : str
        One line.
    """

    reason: str
    message: str


def extract_json(text: str):
    """The JSON value in ``text``: the whole text, else the first fenced code block.

    A Markdown fence of three backticks, optionally tagged ``json``; the first block that
    parses.

    Parameters
    ----------
    text : str
        The model's reply.

    Returns
    -------
    object
        The decoded JSON value.

    Raises
    ------
    ValueError
        One line, if neither the text nor a fenced block parses.
    """
    stripped = text.strip()
    try:
        return json.loads(stripped)
    except ValueError:
        pass
    for block in _FENCE.findall(stripped):
        try:
            return json.loads(block.strip())
        except ValueError:
            continue
    preview = " ".join(stripped.split())[:80]
    raise ValueError(f"no JSON object in the reply ({preview!r})")


def _one_line(message: str, limit: int = 200) -> str:
    """``message`` collapsed to one line of at most ``limit`` characters."""
    text = " ".join(str(message).split())
    return text[:limit] + ("..." if len(text) > limit else "")


def validate_plan(text: str, schema: dict) -> dict | PlanInvalid:
    """The plan in ``text`` if it is valid JSON for ``schema``, else why not.

    The JSON may be bare or in a fenced code block (:func:`extract_json`).

    Parameters
    ----------
    text : str
        The model's reply.
    schema : dict
        The JSON Schema (:func:`assignment_schema`).

    Returns
    -------
    dict or PlanInvalid
        The plan, with the ``assignment`` entries as Python ints; else a :class:`PlanInvalid`
        (``not_json`` or ``schema``).
    """
    try:
        obj = extract_json(text)
    except ValueError as err:
        return PlanInvalid("not_json", _one_line(err))
    error = best_match(jsonschema.Draft202012Validator(schema).iter_errors(obj))
    if error is not None:
        where = "/".join(str(p) for p in error.absolute_path) or "(root)"
        return PlanInvalid("schema", _one_line(f"at {where}: {error.message}"))
    if isinstance(obj, dict) and isinstance(obj.get("assignment"), list):
        obj = {**obj, "assignment": [int(v) for v in obj["assignment"]]}
    return obj


def build_messages(summary_text: str, n_agents: int, n_targets: int,
                   system_prompt: str = DEFAULT_SYSTEM_PROMPT) -> list[dict]:
    """The chat messages asking for an assignment of ``n_agents`` agents to ``n_targets`` targets.

    Parameters
    ----------
    summary_text : str
        The task state (an adapter's :class:`~oneocean.methods.llm.adapters.Decision`).
    n_agents : int
        Agents, numbered 0 to ``n_agents - 1``.
    n_targets : int
        Targets, numbered 0 to ``n_targets - 1``.
    system_prompt : str, optional
        The system message (default :data:`DEFAULT_SYSTEM_PROMPT`).

    Returns
    -------
    list of dict
        The system message, then the user message (the summary and the answer's format).
    """
    instruction = (
        f"Assign each of the {n_agents} agents (numbered 0 to {n_agents - 1}, in order) one "
        f"target index in [0, {n_targets}). Reply with JSON only, exactly: "
        f'{{"assignment": [t_0, ..., t_{n_agents - 1}]}} -- a list of {n_agents} integers.'
    )
    return [
        {"role": "system", "content": system_prompt},
        {"role": "user", "content": f"{summary_text.strip()}\n\n{instruction}"},
    ]


@dataclass(frozen=True)
class CallRecord:
    """One planner call.

    Parameters
    ----------
    outcome : str
        ``"valid"`` (the model's plan was used), ``"invalid"`` (it answered, the answer failed
        validation) or ``"error"`` (no answer: :class:`LLMError`).
    assignment : tuple of int
        The assignment returned (the model's or the fallback).
    fallback_reason : str or None
        None when valid, else a value of :data:`INVALID_REASONS` or
        :data:`~oneocean.methods.llm.client.ERROR_KINDS`.
    error : str or None
        The reason's one-line message.
    cached : bool
        True if the reply came from the cache.
    latency_s : float
        Wall time of the request that fetched the reply, s (for a cache hit: the latency
        recorded when it was fetched; for an error: the time until giving up).
    prompt_tokens, completion_tokens : int or None
        Token counts from the API's ``usage`` (None if absent or no answer).
    calls : int, optional
        Requests (or cache lookups) of the record (default 1).
    """

    outcome: str
    assignment: tuple[int, ...]
    fallback_reason: str | None
    error: str | None
    cached: bool
    latency_s: float
    prompt_tokens: int | None
    completion_tokens: int | None
    calls: int = 1  # one request (or cache lookup) per record

    @property
    def valid(self) -> bool:
        """True if the model's plan was used."""
        return self.outcome == "valid"

    @property
    def used_fallback(self) -> bool:
        """True if the fallback assignment was returned."""
        return self.fallback_reason is not None


def check_fallback(fallback: Sequence[int], n_agents: int, n_targets: int) -> tuple[int, ...]:
    """The fallback as a tuple of ints, checked to be a valid assignment itself.

    Parameters
    ----------
    fallback : sequence of int
        The caller's assignment.
    n_agents : int
        Agents.
    n_targets : int
        Targets.

    Returns
    -------
    tuple of int
        The fallback.

    Raises
    ------
    ValueError
        If it is not a valid assignment (a bug of the caller, not of the model).
    """
    plan = validate_plan(json.dumps({"assignment": [int(v) for v in fallback]}),
                         assignment_schema(n_agents, n_targets))
    if isinstance(plan, PlanInvalid):
        raise ValueError(f"fallback assignment is invalid: {plan.message}")
    return tuple(plan["assignment"])


class Planner:
    """Asks a client for assignments; keeps this episode's :class:`CallRecord` s.

    The client is an :class:`LLMClient` or any :class:`~.client.CachedClient` (such as the
    local model's). :meth:`plan` never raises for anything the endpoint or the model does;
    :meth:`totals` sums the records (:func:`episode_totals`) and :meth:`reset` starts a new
    episode.

    Parameters
    ----------
    client : CachedClient
        The model's client.
    system_prompt : str, optional
        The system message (default :data:`DEFAULT_SYSTEM_PROMPT`).
    """

    def __init__(self, client: LLMClient, system_prompt: str = DEFAULT_SYSTEM_PROMPT):
        self.client = client
        self.system_prompt = system_prompt
        self.records: list[CallRecord] = []

    def plan(self, summary_text: str, n_agents: int, n_targets: int,
             fallback: Sequence[int]) -> tuple[list[int], CallRecord]:
        """Ask for an assignment: the model's if valid, else the fallback.

        Parameters
        ----------
        summary_text : str
            The task state.
        n_agents : int
            Agents.
        n_targets : int
            Targets.
        fallback : sequence of int
            The deterministic fallback assignment (the heuristic's plan).

        Returns
        -------
        assignment : list of int
            The model's valid assignment, else ``fallback``.
        record : CallRecord
            The call's record (also appended to ``records``).

        Raises
        ------
        ValueError
            Only for a caller's bug: counts that are not integers >= 1 or an invalid
            ``fallback``.
        """
        schema = assignment_schema(n_agents, n_targets)
        n_agents, n_targets = _count(n_agents, "n_agents"), _count(n_targets, "n_targets")
        fallback = check_fallback(fallback, n_agents, n_targets)
        messages = build_messages(summary_text, n_agents, n_targets, self.system_prompt)
        try:
            reply = self.client.complete(messages, schema)
        except LLMError as err:
            record = CallRecord("error", fallback, err.kind, str(err), cached=False,
                                latency_s=err.latency_s, prompt_tokens=None,
                                completion_tokens=None)
        else:
            plan = validate_plan(reply.text, schema)
            common = dict(cached=reply.cached, latency_s=reply.latency_s,
                          prompt_tokens=reply.prompt_tokens,
                          completion_tokens=reply.completion_tokens)
            if isinstance(plan, PlanInvalid):
                record = CallRecord("invalid", fallback, plan.reason, plan.message, **common)
            else:
                record = CallRecord("valid", tuple(plan["assignment"]), None, None, **common)
        self.records.append(record)
        return list(record.assignment), record

    def totals(self) -> dict:
        """This episode's totals (:func:`episode_totals` of its records).

        Returns
        -------
        dict
            The cost-table totals.
        """
        return episode_totals(self.records)

    def reset(self) -> None:
        """Forget the records (start of an episode)."""
        self.records = []


def episode_totals(records: Iterable[CallRecord]) -> dict:
    """Cost-table totals of one episode's calls.

    ``calls = valid + invalid + errors``; ``fallbacks = invalid + errors``;
    ``cached_calls + uncached_calls = calls``. ``latency_s`` sums every call's latency, cached
    ones included at the latency recorded when the reply was fetched (errors at the time until
    giving up); ``mean_latency_s = latency_s / calls`` (None without calls). Token totals are
    over every call that returned a reply, cached ones included (a hit carries the usage
    recorded when it was fetched). So the totals of a rerun served from the cache equal those
    of the run that filled it, but for ``cached_calls`` / ``uncached_calls`` (errors are never
    cached: a rerun asks again). ``replies_without_usage`` counts replies whose endpoint gave
    no usage (their tokens are not in the totals).

    Parameters
    ----------
    records : iterable of CallRecord
        The episode's calls.

    Returns
    -------
    dict
        ``calls``, ``valid``, ``invalid``, ``errors``, ``fallbacks``, ``fallback_reasons``
        (reason -> count), ``cached_calls``, ``uncached_calls``, ``latency_s`` (s),
        ``mean_latency_s`` (s), ``prompt_tokens``, ``output_tokens``, ``total_tokens``,
        ``replies_without_usage``.
    """
    records = list(records)
    uncached = [r for r in records if not r.cached]
    replies = [r for r in records if r.outcome != "error"]
    prompt = sum(r.prompt_tokens for r in replies if r.prompt_tokens is not None)
    output = sum(r.completion_tokens for r in replies if r.completion_tokens is not None)
    reasons: dict[str, int] = {}
    for r in records:
        if r.fallback_reason is not None:
            reasons[r.fallback_reason] = reasons.get(r.fallback_reason, 0) + 1
    latency = math.fsum(r.latency_s for r in records)
    return {
        "calls": sum(r.calls for r in records),
        "valid": sum(r.outcome == "valid" for r in records),
        "invalid": sum(r.outcome == "invalid" for r in records),
        "errors": sum(r.outcome == "error" for r in records),
        "fallbacks": sum(r.used_fallback for r in records),
        "fallback_reasons": dict(sorted(reasons.items())),
        "cached_calls": sum(r.calls for r in records if r.cached),
        "uncached_calls": sum(r.calls for r in uncached),
        "latency_s": latency,
        "mean_latency_s": latency / len(records) if records else None,
        "prompt_tokens": prompt,
        "output_tokens": output,
        "total_tokens": prompt + output,
        "replies_without_usage": sum(r.prompt_tokens is None or r.completion_tokens is None
                                     for r in replies),
    }
