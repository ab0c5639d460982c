"""The planning suite's tables (paper Tables IV and VI) from its cell files.

The suite: the planning-sensitive tasks (SPC, AS, PI) at one tier with scaled currents
(config ``planning``), methods heuristic, BC and every configured LLM planner
(``llm_<name>``), one Parquet cell per (task, method). Rows appear only for methods whose
cells exist: an LLM row is never invented.

* :func:`performance_frame` (Table IV): per method the suite's average SR (macro over the
  tasks, stratified-bootstrap 95 % interval), per task SR (Wilson interval) and its key
  metric, and T and E (means over every episode, seeded-bootstrap intervals).
* :func:`cost_frame` (Table VI): over the first ``cost_episodes`` episodes of every cell:
  average SR, LLM calls per episode, latency per episode, ms per call, prompt / output /
  total tokens per episode, and the share of calls that fell back to the heuristic's plan.
  Latencies are the fetch-time latencies of each call (a rerun served from the response
  cache reports the same numbers); methods without planner calls have zeros.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from ..io import write_text_atomic
from .latex import booktabs
from .stats import cell_rate, mean_ci, stratified_macro

#: Each suite task's key metric (column, table label) and short label.
SUITE_TASKS = {"SPC": ("cleanup_rate", "Cleanup"), "AS": ("coverage_fraction", "Scan"),
               "PI": ("inspection_score", "Pipe")}
METRIC_LABEL = {"SPC": "Cleanup rate", "AS": "Scan cov.", "PI": "Pipe score"}
#: Per-episode accounting columns of a planner cell (0 for methods that make no calls).
LLM_COLUMNS = ("llm_calls", "llm_fallbacks", "llm_latency_s", "llm_prompt_tokens",
               "llm_output_tokens", "llm_total_tokens")


def load_suite(files) -> pd.DataFrame:
    """Every episode of the suite's cell files in one table.

    Cells that are not applicable or have no episodes are left out.

    Parameters
    ----------
    files : iterable of path-like
        The suite's cell files.

    Returns
    -------
    pandas.DataFrame
        The cells' rows with ``task``, ``method``, ``label`` (the method's table label: the
        registry's, else the one its file records) and the :data:`LLM_COLUMNS` (0 where a
        method has none); an empty frame with columns ``task, method, label, episode,
        success`` when no cell has episodes.
    """
    from .. import registry
    from ..engine.recording import read_metrics_meta

    parts = []
    for f in files:
        df = pd.read_parquet(f)
        meta = read_metrics_meta(f)
        if not meta.get("applicable", True) or len(df) == 0:
            continue
        method = meta.get("method", df["method"].iloc[0])
        if method in registry.method_names():
            label = registry.method_spec(method).short
        else:   # a planner this process did not register: the label its file records
            label = meta.get("label") or (meta.get("model") or {}).get("label") or method
        df = df.assign(task=meta.get("task", df["task"].iloc[0]), method=method, label=label)
        for c in LLM_COLUMNS:
            if c not in df:
                df[c] = 0
        parts.append(df)
    if not parts:
        return pd.DataFrame(columns=["task", "method", "label", "episode", "success"])
    return pd.concat(parts, ignore_index=True)


def not_applicable(files) -> list[str]:
    """The cells the region could not host.

    Parameters
    ----------
    files : iterable of path-like
        The suite's cell files.

    Returns
    -------
    list of str
        ``"<task> (<method>)"`` of every cell file recorded as not applicable.
    """
    from ..engine.recording import read_metrics_meta

    out = []
    for f in files:
        meta = read_metrics_meta(f)
        if not meta.get("applicable", True):
            out.append(f"{meta.get('task')} ({meta.get('method')})")
    return out


def _methods(df: pd.DataFrame) -> list[str]:
    from .. import registry

    order = {m: i for i, m in enumerate(registry.method_names())}
    return sorted(df["method"].unique(), key=lambda m: (order.get(m, len(order)), m))


def _rate(s) -> tuple[float, float, float]:
    r = cell_rate(int(np.sum(s)), len(s))
    return (r.sr, r.lo, r.hi)


def performance_frame(df: pd.DataFrame, tasks=tuple(SUITE_TASKS)) -> pd.DataFrame:
    """Table IV as numbers: one row per method.

    Parameters
    ----------
    df : pandas.DataFrame
        :func:`load_suite`'s episodes.
    tasks : sequence of str, default ``tuple(SUITE_TASKS)``
        The suite's tasks (keys of :data:`SUITE_TASKS`).

    Returns
    -------
    pandas.DataFrame
        ``method, label``; ``sr_avg`` (macro SR over the tasks with episodes, %,
        stratified bootstrap); per task ``<T>_n`` episodes, ``<T>_sr`` (%, Wilson) and
        ``<T>_metric`` (mean of the key metric, seeded bootstrap); ``T_s`` (mean episode
        time, s) and ``E`` (mean team energy proxy, m2 s-1). Each value has ``_lo`` /
        ``_hi`` columns, its 95 % bounds.
    """
    rows = []
    for m in _methods(df):
        d = df[df["method"] == m]
        row = {"method": m, "label": d["label"].iloc[0]}
        row["sr_avg"], row["sr_avg_lo"], row["sr_avg_hi"] = stratified_macro(
            [d.loc[d["task"] == t, "success"].to_numpy() for t in tasks])
        for t in tasks:
            dt = d[d["task"] == t]
            col, _ = SUITE_TASKS[t]
            row[f"{t}_n"] = len(dt)
            row[f"{t}_sr"], row[f"{t}_sr_lo"], row[f"{t}_sr_hi"] = (
                _rate(dt["success"].to_numpy()) if len(dt) else (math.nan,) * 3)
            row[f"{t}_metric"], row[f"{t}_metric_lo"], row[f"{t}_metric_hi"] = mean_ci(
                dt[col].to_numpy() if len(dt) else [])
        row["T_s"], row["T_s_lo"], row["T_s_hi"] = mean_ci(d["T_s"].to_numpy())
        row["E"], row["E_lo"], row["E_hi"] = mean_ci(d["E"].to_numpy())
        rows.append(row)
    return pd.DataFrame(rows)


def cost_frame(df: pd.DataFrame, cost_episodes: int, tasks=tuple(SUITE_TASKS)) -> pd.DataFrame:
    """Table VI as numbers over episodes ``0 .. cost_episodes-1`` of every cell.

    Parameters
    ----------
    df : pandas.DataFrame
        :func:`load_suite`'s episodes.
    cost_episodes : int
        Episodes counted per cell (the first ones).
    tasks : sequence of str, default ``tuple(SUITE_TASKS)``
        The suite's tasks, for the macro SR.

    Returns
    -------
    pandas.DataFrame
        One row per method: ``method, label, episodes``; ``sr_avg, sr_avg_lo, sr_avg_hi``
        (macro SR, %, stratified-bootstrap 95 % interval); per-episode means ``calls``,
        ``latency_s`` (s), ``prompt_tokens``, ``output_tokens``, ``total_tokens``;
        ``ms_per_call`` (total latency / total calls, ms; 0 without calls), ``fallbacks``
        (calls that fell back to the heuristic's plan, over the counted episodes) and
        ``fallback_pct`` (their % of the calls; NaN without calls).
    """
    d0 = df[df["episode"] < int(cost_episodes)]
    rows = []
    for m in _methods(d0):
        d = d0[d0["method"] == m]
        row = {"method": m, "label": d["label"].iloc[0], "episodes": len(d)}
        row["sr_avg"], row["sr_avg_lo"], row["sr_avg_hi"] = stratified_macro(
            [d.loc[d["task"] == t, "success"].to_numpy() for t in tasks])
        calls = float(d["llm_calls"].sum())
        row["calls"] = float(d["llm_calls"].mean())
        row["latency_s"] = float(d["llm_latency_s"].mean())
        row["ms_per_call"] = 1000.0 * float(d["llm_latency_s"].sum()) / calls if calls else 0.0
        row["prompt_tokens"] = float(d["llm_prompt_tokens"].mean())
        row["output_tokens"] = float(d["llm_output_tokens"].mean())
        row["total_tokens"] = float(d["llm_total_tokens"].mean())
        row["fallbacks"] = int(d["llm_fallbacks"].sum())
        row["fallback_pct"] = (100.0 * row["fallbacks"] / calls if calls
                               else math.nan)   # no calls: nothing to fall back from
        rows.append(row)
    return pd.DataFrame(rows)


def _ci(v, lo, hi, fmt: str = "{:.1f}") -> str:
    if not np.isfinite(v):
        return "--"
    return f"{fmt.format(v)} [{fmt.format(lo)}, {fmt.format(hi)}]"


def _bold_best(values: list[float], texts: list[str], higher: bool) -> list[str]:
    finite = [v for v in values if np.isfinite(v)]
    if len(finite) < 2:
        return texts
    best = max(finite) if higher else min(finite)
    return [f"\\textbf{{{t}}}" if np.isfinite(v) and v == best else t
            for v, t in zip(values, texts)]


def _latex(header: list[str], cols: list[list[str]], caption: str, label: str) -> str:
    """The planning tables, column by column, through the tables' one booktabs writer."""

    return booktabs(header, [list(row) for row in zip(*cols)], caption, label)


def _esc(s: str) -> str:
    return str(s).replace("_", "\\_").replace("%", "\\%")


def performance_latex(perf: pd.DataFrame, *, tier: int, gain: float, episodes: int,
                      note: str = "") -> str:
    """Table IV as a LaTeX booktabs table (best value per column in bold).

    Parameters
    ----------
    perf : pandas.DataFrame
        :func:`performance_frame`'s rows.
    tier : int
        The suite's tier, for the caption.
    gain : float
        The suite's gain on the currents, for the caption.
    episodes : int
        Episodes per task and method, for the caption.
    note : str, default ""
        A sentence appended to the caption.

    Returns
    -------
    str
        The LaTeX table (label ``tab:planning_performance``).
    """
    tasks = [t for t in SUITE_TASKS if f"{t}_sr" in perf]
    header = ["Method"]
    cols = [[_esc(v) for v in perf["label"]]]

    def add(name, key, higher, fmt="{:.1f}"):
        header.append(name)
        vals = perf[key].tolist()
        texts = [_ci(v, lo, hi, fmt) for v, lo, hi in
                 zip(vals, perf[f"{key}_lo"], perf[f"{key}_hi"])]
        cols.append(_bold_best(vals, texts, higher))

    add("SR avg (\\%)", "sr_avg", True)
    for t in tasks:
        add(f"{SUITE_TASKS[t][1]} SR (\\%)", f"{t}_sr", True)
        add(METRIC_LABEL[t], f"{t}_metric", True, "{:.2f}")
    add("T (s)", "T_s", False, "{:.0f}")
    add("E", "E", False, "{:.0f}")
    caption = (f"Planning suite (Tier {tier}, currents $\\times${gain:g}): {episodes} episodes "
               "per task and method on the evaluation seed. Rates with Wilson 95\\% intervals; "
               "SR avg is the unweighted mean over the tasks (stratified bootstrap); metric, T "
               "and E are means with seeded-bootstrap intervals. Best per column in bold."
               + (f" {note}" if note else ""))
    return _latex(header, cols, caption, "tab:planning_performance")


def cost_latex(cost: pd.DataFrame, *, tier: int, gain: float, episodes: int,
               note: str = "") -> str:
    """Table VI as a LaTeX booktabs table.

    Parameters
    ----------
    cost : pandas.DataFrame
        :func:`cost_frame`'s rows.
    tier : int
        The suite's tier, for the caption.
    gain : float
        The suite's gain on the currents, for the caption.
    episodes : int
        Episodes counted per task (``cost_episodes``), for the caption.
    note : str, default ""
        A sentence appended to the caption.

    Returns
    -------
    str
        The LaTeX table (label ``tab:planning_cost``).
    """
    header = ["Method", "Avg SR (\\%)", "Calls", "Lat. (s)", "ms/call", "Prompt tok.",
              "Output tok.", "Total tok.", "Fallbacks", "Fallback (\\%)"]
    cols = [[_esc(v) for v in cost["label"]],
            _bold_best(cost["sr_avg"].tolist(),
                       [_ci(v, lo, hi) for v, lo, hi in
                        zip(cost["sr_avg"], cost["sr_avg_lo"], cost["sr_avg_hi"])], True)]
    for key, fmt in (("calls", "{:.2f}"), ("latency_s", "{:.2f}"), ("ms_per_call", "{:.1f}"),
                     ("prompt_tokens", "{:.0f}"), ("output_tokens", "{:.0f}"),
                     ("total_tokens", "{:.0f}"), ("fallbacks", "{:.0f}"),
                     ("fallback_pct", "{:.1f}")):
        cols.append([fmt.format(v) if np.isfinite(v) else "--" for v in cost[key]])
    caption = (f"Planning-suite cost (Tier {tier}, currents $\\times${gain:g}; the first "
               f"{episodes} episodes of every task): planner calls, latency and tokens per "
               "episode (latency measured when each reply was fetched; cached reruns report "
               "the same), and the calls (count over the episodes, share) that fell back to "
               "the heuristic's plan. "
               "Avg SR with a stratified-bootstrap 95\\% interval." + (f" {note}" if note else ""))
    return _latex(header, cols, caption, "tab:planning_cost")


def episodes_note(perf: pd.DataFrame, episodes: int) -> str:
    """The caption's sentence on methods that played another number of episodes.

    Parameters
    ----------
    perf : pandas.DataFrame
        :func:`performance_frame`'s rows.
    episodes : int
        The configured episodes per task and method.

    Returns
    -------
    str
        ``"<label> played <n> episodes per task."`` for each such method, else ``""``.
    """
    out = []
    for _, row in perf.iterrows():
        ns = sorted({int(row[f"{t}_n"]) for t in SUITE_TASKS if f"{t}_n" in row
                     and row[f"{t}_n"] > 0})
        if ns and ns != [int(episodes)]:
            out.append(f"{_esc(row['label'])} played {'/'.join(map(str, ns))} episodes per "
                       "task.")
    return " ".join(out)


def omitted_note(configured_llms) -> str:
    """The caption's sentence on LLM rows.

    Parameters
    ----------
    configured_llms : sequence of str
        The configured LLM planners (config ``llm.models``).

    Returns
    -------
    str
        A sentence saying no LLM endpoint is configured, or ``""`` when one is.
    """
    if configured_llms:
        return ""
    return ("No LLM endpoint is configured (config llm.models is empty), so no LLM rows: "
            "none are invented (a local model's row: config/llm/smollm2.yaml).")


def planning_tables(cell_files, perf_tex, cost_tex, *, tier: int, gain: float, episodes: int,
                    cost_episodes: int, configured_llms=()) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Write Tables IV and VI: LaTeX, plus the numbers as Parquet beside each ``.tex``.

    Parameters
    ----------
    cell_files : iterable of path-like
        The suite's cell files.
    perf_tex : path-like
        Table IV's ``.tex`` (its numbers go to the same path with ``.parquet``).
    cost_tex : path-like
        Table VI's ``.tex`` (likewise).
    tier : int
        The suite's tier.
    gain : float
        The suite's gain on the currents.
    episodes : int
        Episodes per task and method, for Table IV's caption.
    cost_episodes : int
        The first episodes of each cell counted in Table VI.
    configured_llms : sequence of str, default ()
        The configured LLM planners (:func:`omitted_note`).

    Returns
    -------
    perf : pandas.DataFrame
        :func:`performance_frame`'s rows.
    cost : pandas.DataFrame
        :func:`cost_frame`'s rows.
    """
    from ..engine.recording import write_metrics
    from pathlib import Path

    df = load_suite(cell_files)
    perf = performance_frame(df)
    cost = cost_frame(df, cost_episodes)
    note = omitted_note(configured_llms)
    na = not_applicable(cell_files)
    if na:
        note = (note + " " if note else "") + (
            "Not applicable in this region (no episodes; the cell files record why): "
            + ", ".join(_esc(c) for c in na) + "; SR avg is over the tasks it hosts.")
    played = episodes_note(perf, episodes)
    write_text_atomic(perf_tex, performance_latex(perf, tier=tier, gain=gain,
                                                  episodes=episodes,
                                                  note=" ".join(filter(None, (played, note)))))
    counted = " ".join(f"{_esc(r.label)} counts {r.episodes} episodes over the tasks."
                       for r in cost.itertuples() if r.episodes != cost["episodes"].max())
    write_text_atomic(cost_tex, cost_latex(cost, tier=tier, gain=gain, episodes=cost_episodes,
                                           note=" ".join(filter(None, (counted, note)))))
    meta = {"stage": "planning_table", "tier": int(tier), "current_gain": float(gain),
            "configured_llms": list(configured_llms)}
    write_metrics(perf, Path(perf_tex).with_suffix(".parquet"), meta={**meta,
                                                                      "episodes": episodes})
    write_metrics(cost, Path(cost_tex).with_suffix(".parquet"), meta={**meta,
                                                                      "episodes": cost_episodes})
    return perf, cost
