"""The LLM planner's backend: an OpenAI-compatible chat-completions client (standard library
only), a content-addressed response cache, and plan validation with a deterministic fallback
and per-episode accounting.

* :mod:`.client` -- :class:`ClientConfig`, :class:`LLMClient`, :class:`Reply`, :class:`LLMError`.
* :mod:`.cache` -- :class:`ResponseCache`, :func:`cache_key`.
* :mod:`.plan` -- :func:`assignment_schema`, :func:`validate_plan`, :class:`Planner`,
  :class:`CallRecord`, :func:`episode_totals`.

Nothing here is wired into tasks or the workflow yet; the planner is called with a text summary
and returns a discrete assignment (or the caller's fallback) plus a record for the cost table.
"""

from .cache import ResponseCache, cache_key
from .client import ClientConfig, LLMClient, LLMError, Reply
from .plan import (
    CallRecord,
    PlanInvalid,
    Planner,
    assignment_schema,
    build_messages,
    episode_totals,
    extract_json,
    validate_plan,
)

__all__ = [
    "CallRecord",
    "ClientConfig",
    "LLMClient",
    "LLMError",
    "PlanInvalid",
    "Planner",
    "Reply",
    "ResponseCache",
    "assignment_schema",
    "build_messages",
    "cache_key",
    "episode_totals",
    "extract_json",
    "validate_plan",
]
