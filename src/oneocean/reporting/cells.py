"""Cell files into rows: what one rollout cell's episodes give a table.

A cell is one (task, tier, method, condition) rollout, one Parquet file with a row per
episode and its own record (:func:`oneocean.engine.recording.read_metrics_meta`). Here:

* :func:`read_cell` -- the one reader of a cell file: its episodes and its identity (task,
  tier, method, forcing, ablation, applicability, ...);
* :func:`load_cells` -- cell files into one row per file (``n`` episodes, ``k`` successes, the
  success vector), the ladder's and the figures' input; :func:`load_cell_frames` -- the same
  with each cell's forcing condition and episodes, in canonical order, the paper tables'
  input;
* :func:`ladder_frame` -- each data or currents-off cell's success rate with its Wilson 95 %
  interval; :func:`macro_rate` -- the macro success rate of one method at one tier over the
  tasks, with its stratified-bootstrap interval.

The intervals themselves are :mod:`oneocean.reporting.stats`'. A cell the region cannot host
(``applicable: false``, zero episodes) has no rate: NaN, and it is left out of the macros.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd

from .stats import Rate, cell_rate, stratified_macro


# ------------------------------------------------------------------------------ reading

def read_cell(path) -> tuple[pd.DataFrame, dict]:
    """A cell file's per-episode table and its identity.

    The one reader of cell files (tables, figures and the ladder use it). The identity comes
    from the file's own record (a workflow cell), else from its first row's columns (e.g. a
    user's ``oneocean evaluate`` file).

    Parameters
    ----------
    path : path-like
        A cell's Parquet file (``results/rollouts/...parquet``).

    Returns
    -------
    df : pandas.DataFrame
        One row per episode.
    identity : dict
        ``task, tier, method, currents``; ``run_gain`` (the run's gain g on the data
        currents, a tier's own gain divided out); ``tide`` (the synthetic tide term or
        None); ``forcing`` (``data``: the product's currents as they are, ``off``, ``gain``:
        another gain, ``tide``: a synthetic tide added); ``applicable, reason, vehicle,
        n_agents, seed``; what an ablation cell changed: ``info`` (the information level the
        method was given instead of its own sensing, e.g. ``true_current``; ``""`` for its
        own), ``tier_overrides`` (the tier parameters it replaced, ``{}`` for none) and
        ``ablation`` (either of the two: such a cell is never one of the ladder's normal
        cells); and ``meta``, the file's whole record.
    """
    from ..engine.recording import read_metrics_meta

    df = pd.read_parquet(path)
    meta = read_metrics_meta(path)
    first = df.iloc[0] if len(df) else {}

    def get(key, default=None):
        return meta[key] if key in meta else first.get(key, default)

    currents = bool(get("currents", True))
    tier_gain = float((meta.get("tier_params") or {}).get("current_gain", 1.0))
    run_gain = float(meta.get("current_gain", tier_gain)) / (tier_gain or 1.0)
    tide = meta.get("tide")
    forcing = ("off" if not currents else "tide" if tide is not None
               else "gain" if abs(run_gain - 1.0) > 1e-12 else "data")
    seed = get("seed")
    method = get("method")
    info = meta.get("info") or ""
    if info == own_info(method):
        info = ""
    overrides = dict(meta.get("tier_overrides") or {})
    return df, {"task": get("task"), "tier": int(get("tier", -1)), "method": method,
                "currents": currents, "run_gain": run_gain, "tide": tide, "forcing": forcing,
                "info": info, "tier_overrides": overrides, "ablation": bool(info or overrides),
                "applicable": bool(meta.get("applicable", True)),
                "reason": meta.get("reason", ""), "vehicle": meta.get("vehicle", ""),
                "n_agents": int(get("n_agents", 0)),
                "seed": None if seed is None else int(seed), "meta": meta}


def own_info(method) -> str:
    """The information level ``method`` senses with by default.

    Parameters
    ----------
    method : str
        A method name.

    Returns
    -------
    str
        One of :data:`oneocean.sensing.INFO_LEVELS`: ``truth`` for the oracle, ``sensors``
        for every other method.
    """
    from ..methods.heuristic import SENSING

    return SENSING.get(str(method), "sensors")


def load_cells(files) -> pd.DataFrame:
    """Read cell files into one row per file.

    The ladder and its macros use the ``data`` and ``off`` cells only, never an ablation
    cell (an information level or tier override).

    Parameters
    ----------
    files : iterable of path-like
        Cell files (:func:`read_cell`).

    Returns
    -------
    pandas.DataFrame
        ``task, tier, method, currents, forcing, info, ablation, applicable, reason,
        vehicle, n_agents, seed`` (:func:`read_cell` says what each is), ``n`` episodes,
        ``k`` successes, ``success`` (the episodes' success, a bool array) and ``current``
        (the current speed each episode met, m s-1, a float64 array; empty for a file
        without the column).
    """
    rows = []
    for f in files:
        df, c = read_cell(f)
        rows.append({**{k: c[k] for k in ("task", "tier", "method", "currents", "forcing",
                                          "info", "ablation", "applicable", "reason",
                                          "vehicle", "n_agents", "seed")},
                     "n": int(len(df)), "k": int(df["success"].sum()),
                     "success": df["success"].to_numpy(dtype=bool),
                     "current": (df["current_speed_ms"].to_numpy(dtype=np.float64)
                                 if "current_speed_ms" in df else np.zeros(0))})
    return pd.DataFrame(rows)


# ------------------------------------------------------------------------------ conditions

#: Condition ids of the main tables' cells and of the currents-off ablation.
DATA_GROUNDED = "data-grounded"
CURRENTS_OFF = "currents-off"


def _condition(currents: bool, gain: float, tide: str | None) -> tuple[str, str, tuple]:
    """``(id, label, sort key)`` of a cell's forcing condition (``tide``: canonical JSON)."""
    if not currents:
        return CURRENTS_OFF, "Currents off", (1, 0, 0.0, "")
    parts, label = [], []
    if gain != 1.0:
        parts.append(f"gain-{gain:g}")
        label.append(f"Currents $\\times${gain:g}")
    if tide is not None:
        t = json.loads(tide)
        a, p = float(t.get("amplitude_ms", math.nan)), float(t.get("period_s", math.nan))
        parts.append(f"tide-{a:g}ms-{p:g}s")
        label.append(f"+ tide ({a:g} m/s, {p / 3600.0:.3g} h)")
    if not parts:
        return DATA_GROUNDED, "Data-grounded", (0, 0, 1.0, "")
    return "+".join(parts), " ".join(label), (0, int(tide is not None), float(gain), tide or "")


#: Labels of the information levels an ablation cell gives a method instead of its sensors.
INFO_LABEL = {"sensors": "Sensors", "true_current": "True current",
              "true_position": "True position", "true_target": "True target",
              "truth": "Truth"}


def _ablation_condition(cond: str, label: str, key: tuple, info: str,
                        overrides: dict) -> tuple[str, str, tuple]:
    """A cell's condition with its ablation (information level, tier overrides) appended:
    ``info-<level>``, ``set-<key>[+<key>...]``; unchanged for a normal cell."""
    parts, labels = [], []
    if info:
        parts.append(f"info-{info}")
        labels.append(INFO_LABEL.get(info, info))
    if overrides:
        parts.append("set-" + "+".join(sorted(overrides)))
        labels.append(", ".join(f"{k} = {json.dumps(overrides[k])}" for k in sorted(overrides)))
    if not parts:
        return cond, label, key
    base = [] if cond == DATA_GROUNDED else [cond]
    return ("+".join(base + parts), "; ".join(([] if cond == DATA_GROUNDED else [label])
                                              + labels), (2, *key, "+".join(parts)))


def _user_method(method: str, policies: list) -> None:
    """Check that ``method`` is registered; a method that is not, whose every cell file was
    written by ``oneocean evaluate`` (its record names the scored ``policy``), is registered
    as a user's method (kind ``callable``, labelled by its name) so the tables take its
    cells; anything else unregistered is the registry's one-line ConfigError."""
    from .. import registry
    from ..errors import ConfigError

    try:
        registry.method_spec(method)        # built in, packaged or registered
        return
    except ConfigError:
        pass
    if policies and all(isinstance(p, str) and p for p in policies):
        registry.register_method(registry.MethodSpec(
            method, method, "callable", "its own (step API observations)",
            f"a user's policy scored with oneocean evaluate ({', '.join(sorted(set(policies)))})"))
        return
    registry.method_spec(method)


def load_cell_frames(cell_files) -> pd.DataFrame:
    """Read cell files into one row per cell, in canonical order.

    The order is registry task order, registry method order, tier, condition. Identity
    comes from the file's record, else from its columns (a user's ``oneocean evaluate``
    file). A method that is not registered but whose every file was written by ``oneocean
    evaluate`` is registered as a user's method (kind ``callable``) so the tables take it.

    Parameters
    ----------
    cell_files : iterable of path-like or pandas.DataFrame
        Rollout cell files; a DataFrame (rows of this function) is returned as it is.

    Returns
    -------
    pandas.DataFrame
        ``task, tier, method, currents``; ``current_gain`` (the run's gain g, a tier's own gain
        divided out); ``tide`` (the synthetic tide as canonical JSON, None: none); ``condition,
        condition_label, condition_key`` (the forcing condition's id, table label and sort key:
        ``data-grounded``, ``currents-off``, ``gain-<g>``, ``tide-...``); ``info`` and
        ``tier_overrides`` (canonical JSON, ``""`` for none) and ``ablation`` of an ablation cell
        (:func:`read_cell`), whose condition gets ``info-<level>`` / ``set-<key>`` and is never
        ``data-grounded``; ``applicable, reason, vehicle, n_agents, seed``; ``n`` episodes, ``k``
        successes, ``success`` (bool array; the columns of :func:`load_cells`, so its macros
        apply), ``episodes`` (the cell's per-episode DataFrame) and ``file``.

    Raises
    ------
    ConfigError
        An unregistered task or method, or two files for the same cell (never silently
        dropped or pooled).
    """
    from .. import registry
    from ..errors import ConfigError

    if isinstance(cell_files, pd.DataFrame):
        return cell_files
    rows = []
    for f in cell_files:
        df, c = read_cell(f)
        gain = float(c["meta"].get("current_gain", 1.0)) / (
            float((c["meta"].get("tier_params") or {}).get("current_gain", 1.0)) or 1.0)
        tide = None if c["tide"] is None else json.dumps(c["tide"], sort_keys=True)
        cond, label, key = _ablation_condition(*_condition(c["currents"], gain, tide),
                                               c["info"], c["tier_overrides"])
        rows.append({**{k: c[k] for k in ("task", "tier", "method", "currents")},
                     "current_gain": gain, "tide": tide, "condition": cond,
                     "condition_label": label, "condition_key": key, "info": c["info"],
                     "tier_overrides": (json.dumps(c["tier_overrides"], sort_keys=True)
                                        if c["tier_overrides"] else ""),
                     "ablation": c["ablation"],
                     **{k: c[k] for k in ("applicable", "reason", "vehicle", "n_agents",
                                          "seed")},
                     "n": int(len(df)), "k": int(df["success"].sum()),
                     "success": df["success"].to_numpy(dtype=bool), "episodes": df,
                     "file": str(f), "policy": c["meta"].get("policy")})
    cols = ["task", "tier", "method", "currents", "current_gain", "tide", "condition",
            "condition_label", "condition_key", "info", "tier_overrides", "ablation",
            "applicable", "reason", "vehicle", "n_agents", "seed", "n", "k", "success",
            "episodes", "file", "policy"]
    if not rows:
        return pd.DataFrame(columns=cols[:-1])
    cells = pd.DataFrame(rows, columns=cols)
    for t in cells["task"].unique():
        registry.task_spec(t)                     # an unregistered task: one-line error
    for m in cells["method"].unique():
        _user_method(m, list(cells.loc[cells["method"] == m, "policy"]))
    cells = cells.drop(columns="policy")
    t_order = {t: i for i, t in enumerate(registry.task_ids())}
    m_order = {m: i for i, m in enumerate(registry.method_names())}
    cells["_o"] = [(t_order[t], m_order[m], k, c) for t, m, k, c in
                   zip(cells["task"], cells["method"], cells["tier"], cells["condition_key"])]
    cells = cells.sort_values("_o", kind="stable").drop(columns="_o").reset_index(drop=True)
    dup = cells.duplicated(["task", "tier", "method", "condition"], keep=False)
    if dup.any():
        d = cells[dup]
        raise ConfigError(f"two cell files for the same cell ({d['task'].iloc[0]} tier "
                          f"{d['tier'].iloc[0]} {d['method'].iloc[0]}, "
                          f"{d['condition'].iloc[0]}): {', '.join(d['file'])}")
    return cells


# ------------------------------------------------------------------------------ rates

def _data_and_off(cells: pd.DataFrame) -> pd.DataFrame:
    """The data-grounded and currents-off cells (all of them for a frame without
    ``forcing``), never an ablation cell (information level or tier override)."""
    if "forcing" in cells:
        cells = cells[cells["forcing"].isin(("data", "off"))]
    if "ablation" in cells:
        cells = cells[~cells["ablation"].astype(bool)]
    return cells


def ladder_frame(cells: pd.DataFrame) -> pd.DataFrame:
    """The ladder's rates: one row per data or currents-off cell.

    Other forcings and ablation cells have their own tables.

    Parameters
    ----------
    cells : pandas.DataFrame
        :func:`load_cells`' rows.

    Returns
    -------
    pandas.DataFrame
        ``task, method, currents, tier, sr, lo, hi, n, applicable, reason, vehicle``: the
        success rate and its Wilson 95 % bounds in % (NaN and ``n = 0`` for a cell that is
        not applicable).
    """
    out = []
    for _, c in _data_and_off(cells).iterrows():
        r = cell_rate(c["k"], c["n"]) if c["applicable"] else Rate(math.nan, math.nan,
                                                                   math.nan, 0)
        out.append({"task": c["task"], "method": c["method"], "currents": c["currents"],
                    "tier": c["tier"], "sr": r.sr, "lo": r.lo, "hi": r.hi, "n": r.n,
                    "applicable": c["applicable"], "reason": c["reason"],
                    "vehicle": c["vehicle"]})
    return pd.DataFrame(out)


def macro_rate(cells: pd.DataFrame, method: str, tier: int, currents: bool = True) -> dict:
    """Macro success rate of one (method, tier, currents) over the applicable tasks.

    The unweighted mean of the tasks' rates, with a stratified-bootstrap 95 % interval
    (:func:`stratified_macro`, tasks in sorted order); data and currents-off cells only.

    Parameters
    ----------
    cells : pandas.DataFrame
        :func:`load_cells`' rows.
    method : str
        The method.
    tier : int
        The tier.
    currents : bool, default True
        False: the currents-off cells.

    Returns
    -------
    dict
        ``sr, lo, hi`` (%, NaN without applicable cells), ``tasks`` (applicable tasks with
        episodes, averaged) and ``na`` (selected cells left out).
    """
    cells = _data_and_off(cells)
    sel = cells[(cells["method"] == method) & (cells["tier"] == tier)
                & (cells["currents"] == currents)]
    # tasks in one canonical order, so the interval does not depend on the file order
    app = sel[sel["applicable"] & (sel["n"] > 0)].sort_values("task", kind="stable")
    if app.empty:
        return {"sr": math.nan, "lo": math.nan, "hi": math.nan, "tasks": 0,
                "na": int(len(sel))}
    point, lo, hi = stratified_macro(list(app["success"]))
    return {"sr": point, "lo": lo, "hi": hi, "tasks": int(len(app)),
            "na": int(len(sel) - len(app))}
