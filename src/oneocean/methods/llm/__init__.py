"""The LLM planner: a language model as the high-level planner of SPC, AS and PI rollouts.

Every K steps the model gets a compact text summary of an episode's state and answers with a
discrete assignment (``{"assignment": [...]}``: a source per agent for SPC, a waypoint skip
per agent for AS and PI); low-level control stays the task's fused heuristic ``act``. Invalid,
late or failed answers fall back to the heuristic's own plan, deterministically, and are
counted; a model that always fails reproduces the heuristic's cell table.

* :mod:`.client` -- :class:`ClientConfig`, :class:`LLMClient` (OpenAI-compatible chat
  completions, standard library only), :class:`CachedClient`, :class:`Reply`,
  :class:`LLMError`.
* :mod:`.local` -- :class:`~.local.LocalClient`: a local GGUF model through
  ``xllamacpp`` in-process, JSON-schema-constrained (optional, imported only when configured).
* :mod:`.cache` -- :class:`ResponseCache`, :func:`cache_key` (replies with the usage and
  latency measured when fetched: reruns are free and report the same accounting).
* :mod:`.plan` -- :func:`assignment_schema`, :func:`validate_plan`, :class:`Planner`,
  :class:`CallRecord`, :func:`episode_totals`.
* :mod:`.adapters` -- ``ADAPTERS``: per task, the heuristic's plan as the fallback, the
  summary and target count of a decision, and how an assignment becomes plan tokens.
* :mod:`.rollout` -- ``planner_cell`` (the cell table with per-episode accounting columns),
  ``planner_cell_to_file`` (its Parquet file), ``model_config``, ``make_client``.

:mod:`.adapters` and :mod:`.rollout` (numba, the tasks) are imported on first use of their
names here, so the client alone stays light.
"""

from .cache import ResponseCache, cache_key
from .client import CachedClient, ClientConfig, LLMClient, LLMError, Reply
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

#: Names served lazily from :mod:`.adapters` and :mod:`.rollout`.
_LAZY = {
    "ADAPTERS": "adapters", "Decision": "adapters", "adapter_for": "adapters",
    "ACCOUNTING": "rollout", "make_client": "rollout", "model_config": "rollout",
    "planner_cell": "rollout", "planner_cell_to_file": "rollout",
}


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "ACCOUNTING",
    "ADAPTERS",
    "CachedClient",
    "CallRecord",
    "ClientConfig",
    "Decision",
    "LLMClient",
    "LLMError",
    "PlanInvalid",
    "Planner",
    "Reply",
    "ResponseCache",
    "adapter_for",
    "assignment_schema",
    "build_messages",
    "cache_key",
    "episode_totals",
    "extract_json",
    "make_client",
    "model_config",
    "planner_cell",
    "planner_cell_to_file",
    "validate_plan",
]
