"""What drives a cell of the task ladder: the information ablation and the stressor table.

Both are pure functions of rollout cell files (:func:`oneocean.reporting.cells.load_cell_frames`),
like every paper table (:mod:`oneocean.reporting.tables`): a ``*_frame`` function returns the
numbers, a ``*_table`` function writes the LaTeX and the same numbers as Parquet beside it.

* :func:`information_table`: per task, one method (the heuristic) at one tier with its own
  sensors (the ladder's cell), given the true current, given its true position (cells run
  with ``info=``, :func:`oneocean.tasks.run_cell`), with the currents off (the ladder's
  currents-off cell), and the oracle for reference: success rate with its Wilson 95 %
  interval and the mean of the task's primary metric with a seeded-bootstrap interval.
* :func:`stressor_table`: per task and tier key (:func:`stressor_keys`), Tier 1 with that one
  key at its Tier-3 value and Tier 3 with it back at its Tier-1 value (cells run with
  ``tier_overrides=``), beside the ladder's Tier-1 and Tier-3 cells; the share of the task's
  T1 -> T3 drop the key alone produces at Tier 1, and the protocol's check that no key
  produces more than three quarters of it (:data:`MAX_SHARE`).

The workflow plans its cells from the same functions (:func:`stressor_cells`), so the table
and the rollouts agree on the keys. Intervals are the project's own (Wilson:
:func:`oneocean.reporting.stats.rate_ci`; means: :func:`oneocean.reporting.stats.mean_ci`), so
a number here is the number the other tables give for the same cell. A cell the region cannot
host (``applicable: false``) is shown as n/a with its reason; a cell that was not run as "--".
"""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd

from . import cells as C
from . import tables as T
from .latex import booktabs
from .stats import mean_ci, rate_ci

#: The stressor table's tiers: the easy tier whose keys are tightened one at a time, and the
#: hard tier whose keys are relaxed one at a time.
LOW_TIER, HIGH_TIER = 1, 3
#: The protocol's check: no single key applied alone to Tier 1 may produce more than this
#: share of the task's T1 -> T3 drop.
MAX_SHARE = 0.75
#: Below this T1 -> T3 drop (points of SR) a key's share is not defined (n/a).
MIN_DROP_PTS = 1.0
#: The information table's reference columns besides the information levels (in order).
SENSORS, CURRENTS_OFF, ORACLE = "sensors", "currents_off", "oracle"


# ------------------------------------------------------------------------------ stressor cells

def stressor_keys(task: str, low: int = LOW_TIER, high: int = HIGH_TIER) -> list[str]:
    """The keys of ``task``'s tier table whose ``low``- and ``high``-tier values differ.

    A key missing from either tier is left out (it has no value to set), so are keys whose
    values are equal (they tighten nothing).

    Parameters
    ----------
    task : str
        A task id.
    low : int, default ``LOW_TIER``
        The easy tier.
    high : int, default ``HIGH_TIER``
        The hard tier.

    Returns
    -------
    list of str
        Keys of the table's ``harder`` block, in its order; empty if the task lacks a tier.
    """
    from ..tasks.tiers import load_task_table

    tiers = load_task_table(task)["tiers"]
    a, b = tiers.get(int(low)), tiers.get(int(high))
    if a is None or b is None:
        return []
    return [k for k in load_task_table(task)["harder"] if k in a and k in b and a[k] != b[k]]


def stressor_cells(task: str, low: int = LOW_TIER, high: int = HIGH_TIER) -> list[dict]:
    """The stressor cells of ``task``, two per key of :func:`stressor_keys`.

    Per key: ``low`` with the key at its ``high`` value, then ``high`` with the key at its
    ``low`` value.

    Parameters
    ----------
    task : str
        A task id.
    low : int, default ``LOW_TIER``
        The easy tier.
    high : int, default ``HIGH_TIER``
        The hard tier.

    Returns
    -------
    list of dict
        ``{tier, key, from_tier, overrides}`` per cell (``overrides`` is the
        ``tier_overrides`` argument of :func:`oneocean.tasks.run_cell`).
    """
    from ..tasks.tiers import load_task_table

    tiers = load_task_table(task)["tiers"]
    out = []
    for k in stressor_keys(task, low, high):
        out.append({"tier": int(low), "key": k, "from_tier": int(high),
                    "overrides": {k: tiers[int(high)][k]}})
        out.append({"tier": int(high), "key": k, "from_tier": int(low),
                    "overrides": {k: tiers[int(low)][k]}})
    return out


# ------------------------------------------------------------------------------ shared

def _usable(c) -> bool:
    return c is not None and bool(c["applicable"]) and int(c["n"]) > 0


def _state(c) -> str:
    return "missing" if c is None else ("ok" if _usable(c) else "n/a")


def _one(cells: pd.DataFrame, task: str, method: str, tier: int, condition: str):
    sel = cells[(cells["task"] == task) & (cells["method"] == method)
                & (cells["tier"] == int(tier)) & (cells["condition"] == condition)]
    return None if sel.empty else sel.iloc[0]


def _rate_cols(prefix: str, c) -> dict:
    """``<prefix>_sr, _lo, _hi`` (percent, Wilson 95 %), ``_k``, ``_n``, ``_state``."""
    sr, lo, hi = rate_ci(c["success"]) if _usable(c) else (math.nan,) * 3
    return {f"{prefix}_sr": sr, f"{prefix}_lo": lo, f"{prefix}_hi": hi,
            f"{prefix}_k": int(c["k"]) if _usable(c) else 0,
            f"{prefix}_n": 0 if c is None else int(c["n"]), f"{prefix}_state": _state(c)}


def _text(text) -> str:
    """Plain text (a reason, a key, a note) safe in LaTeX (``->`` as an arrow)."""
    out = T._escape(str(text)).replace("#", r"\#").replace("$", r"\$")
    return (out.replace("->", "$\\to$").replace(">", "\\textgreater{}")
            .replace("<", "\\textless{}"))


def _reasons(cells: pd.DataFrame) -> str:
    """``" n/a: <reason>; <reason>."`` for the cells shown as n/a (each distinct reason once,
    as the cell files record it: the region cannot host the cell, or the task cannot build
    it with an override)."""
    na = cells[~cells["applicable"].astype(bool)]
    if na.empty:
        return ""
    reasons = list(dict.fromkeys(str(r) for r in na["reason"] if str(r)))
    what = "; ".join(_text(r) for r in reasons) if reasons else "no reason recorded"
    return f" n/a, as the cells record it: {what}."


def _metric_fmt(values) -> str:
    """One format for a row of metric means: by the largest magnitude shown."""
    v = [abs(x) for x in values if x is not None and np.isfinite(x)]
    top = max(v) if v else 0.0
    return "{:.0f}" if top >= 100 else "{:.1f}" if top >= 10 else "{:.2f}"


# ------------------------------------------------------------------------------ information

def _info_conditions(cells: pd.DataFrame, method: str, tier: int) -> list[tuple]:
    """The information table's columns: ``(id, label, method, condition)``: the method's own
    sensors, every information level with cells (in :data:`oneocean.sensing.INFO_LEVELS`
    order), currents off, the oracle."""
    from ..sensing import INFO_LEVELS

    present = set(cells.loc[(cells["method"] == method) & (cells["tier"] == int(tier)),
                            "info"])
    cols = [(SENSORS, "Sensors", method, C.DATA_GROUNDED)]
    cols += [(lvl, C.INFO_LABEL.get(lvl, lvl), method, f"info-{lvl}") for lvl in INFO_LEVELS
             if lvl in present and lvl != SENSORS]
    cols += [(CURRENTS_OFF, "Currents off", method, C.CURRENTS_OFF),
             (ORACLE, "Oracle", ORACLE, C.DATA_GROUNDED)]
    return cols


def information_frame(cell_files, tier: int = HIGH_TIER,
                      method: str = "heuristic") -> pd.DataFrame:
    """The information ablation as data: one row per task with any of its cells.

    Tasks in registry order; columns ``family, task, primary, primary_higher`` and per column
    ``c`` (``sensors``, the information levels with cells, e.g. ``true_current`` and
    ``true_position``, ``currents_off``, ``oracle``): ``c_sr, c_lo, c_hi`` (SR %, Wilson 95 %),
    ``c_k``, ``c_n``, ``c_state`` (``ok``, ``n/a``: the region cannot host it, ``missing``: not
    run), ``c_metric, c_metric_lo, c_metric_hi`` (mean of the task's primary metric over the
    episodes where it is defined, seeded-bootstrap 95 %); ``same_episodes`` (every column
    replays the sensors cell's episodes: equal ``candidate`` draws; NA without the sensors cell)
    and ``reason`` (the n/a cells' reasons).

    Parameters
    ----------
    cell_files : iterable of path-like or pandas.DataFrame
        Rollout cell files, or :func:`oneocean.reporting.cells.load_cell_frames`' rows.
    tier : int, default ``HIGH_TIER``
        The tier.
    method : str, default "heuristic"
        The method whose information is varied (the oracle is the reference column).

    Returns
    -------
    pandas.DataFrame
        The columns above.
    """
    from .. import registry

    cells = C.load_cell_frames(cell_files)
    cells = cells[cells["tier"] == int(tier)]
    conds = _info_conditions(cells, method, tier)
    rows = []
    for task in T._tasks(cells):
        spec = registry.task_spec(task)
        row = {"family": registry.family_label(spec.family), "task": task,
               "primary": spec.primary,
               "primary_higher": bool(spec.higher_is_better[spec.primary])}
        base = _one(cells, task, method, tier, C.DATA_GROUNDED)
        same, reasons = [], []
        for cid, _, m, cond in conds:
            c = _one(cells, task, m, tier, cond)
            row.update(_rate_cols(cid, c))
            mean = (mean_ci(c["episodes"][spec.primary].to_numpy(dtype=np.float64))
                    if _usable(c) and spec.primary in c["episodes"] else (math.nan,) * 3)
            row[f"{cid}_metric"], row[f"{cid}_metric_lo"], row[f"{cid}_metric_hi"] = mean
            if c is not None and not c["applicable"] and c["reason"]:
                reasons.append(str(c["reason"]))
            if _usable(c) and _usable(base) and "candidate" in c["episodes"]:
                a = c["episodes"]["candidate"].to_numpy()
                b = base["episodes"]["candidate"].to_numpy() \
                    if "candidate" in base["episodes"] else None
                same.append(b is not None and a.shape == b.shape and np.array_equal(a, b))
        row["same_episodes"] = all(same) if same else pd.NA
        row["reason"] = "; ".join(dict.fromkeys(reasons))
        rows.append(row)
    cols = ["family", "task", "primary", "primary_higher"]
    for cid, *_ in conds:
        cols += [f"{cid}_{s}" for s in ("sr", "lo", "hi", "k", "n", "state", "metric",
                                        "metric_lo", "metric_hi")]
    out = pd.DataFrame(rows, columns=cols + ["same_episodes", "reason"])
    out["same_episodes"] = out["same_episodes"].astype("boolean")
    return out


def information_latex(df: pd.DataFrame, cells: pd.DataFrame, tier: int, method: str,
                      region: str | None = None) -> str:
    """The information-ablation table as LaTeX: per task an SR line and a primary-metric line.

    Parameters
    ----------
    df : pandas.DataFrame
        :func:`information_frame`'s rows.
    cells : pandas.DataFrame
        :func:`oneocean.reporting.cells.load_cell_frames`' rows, for the caption.
    tier : int
        The tier.
    method : str
        The method (its label is named in the caption).
    region : str, optional
        The region, named in the caption and the label.

    Returns
    -------
    str
        The ``table*`` (label ``tab:information_<method>_t<tier>[:<region>]``).
    """
    from .. import registry

    conds = [c for c in dict.fromkeys(col[:-len("_state")] for col in df.columns
                                      if col.endswith("_state"))]
    labels = {SENSORS: "Sensors", CURRENTS_OFF: "Currents off", ORACLE: "Oracle",
              **{k: v for k, v in C.INFO_LABEL.items() if k != SENSORS}}
    header = ["Task", ""] + [labels.get(c, _text(c)) for c in conds]
    rows, last = [], None
    for _, r in df.iterrows():
        fam = r["family"]
        if fam != last:
            rows.append(("group", _text(fam)))
            last = fam
        sr = [T._state_text(r[f"{c}_state"], T._ci(r[f"{c}_sr"], r[f"{c}_lo"], r[f"{c}_hi"],
                                                   "{:.0f}")) for c in conds]
        fmt = _metric_fmt([r[f"{c}_metric"] for c in conds])
        metric = [T._state_text(r[f"{c}_state"], T._ci(r[f"{c}_metric"], r[f"{c}_metric_lo"],
                                                       r[f"{c}_metric_hi"], fmt))
                  for c in conds]
        arrow = "$\\uparrow$" if r["primary_higher"] else "$\\downarrow$"
        rows.append([_text(r["task"]), "SR (\\%)"] + sr)
        rows.append(["", f"\\texttt{{{_text(r['primary'])}}} {arrow}"] + metric)
    label = registry.method_spec(method).label.lower()
    what = {
        SENSORS: f"the {_text(label)} method as it runs in the ladder, with the sensor models "
                 "every non-oracle method shares (a current forecast corrected by in-situ "
                 "samples; dead-reckoning navigation with the task's aids)",
        "true_current": "the same method given the true current instead of its estimate "
                        "(its navigation unchanged)",
        "true_position": "the same method given its true position instead of its navigation "
                         "estimate (its current estimate unchanged)",
        "true_target": "the same method perceiving the mission target exactly (UPL's object, "
                       "FH's school) instead of through its perception model",
        "truth": "the same method given the true current, its true position and the exact target",
        CURRENTS_OFF: "the same method with its own sensors and the currents switched off "
                      "(g = 0, no tides)",
        ORACLE: "the privileged oracle for reference (true current and position; in some "
                "tasks also a better plan)",
    }
    notes = "; ".join(f"{labels.get(c, _text(c))}: {what.get(c, _text(c))}" for c in conds)
    same = df["same_episodes"].dropna()
    replay = ""
    if len(same) and bool(same.all()):
        replay = " Every column replays the same episodes (the same accepted draws; checked)."
    elif len(same):
        replay = (" Episodes differ from the sensors cell's for "
                  + ", ".join(df.loc[df["same_episodes"] == False, "task"])  # noqa: E712
                  + ".")
    sel = cells[cells["tier"] == int(tier)]
    caption = (
        T._protocol(sel, region, f"Information ablation of the {_text(label)} method at "
                                 f"Tier {int(tier)}")
        + " Columns: " + notes + ". Per task, first line: success rate (\\%) with its Wilson "
        "95\\% interval; second line: the mean of the task's primary metric ($\\uparrow$ higher "
        "is better, $\\downarrow$ lower) with a seeded-bootstrap 95\\% interval, over the "
        "episodes where it is defined (SK's station RMS: those that held station). The gap "
        "from Sensors to True current is what the current estimate costs, to True position "
        "what the navigation costs." + replay + " --: not run." + _reasons(sel))
    return booktabs(header, rows, caption,
                    T._label(f"tab:information_{method}_t{int(tier)}", region),
                    align="ll" + "r" * len(conds), wide=True)


def information_table(cell_files, out_tex, tier: int = HIGH_TIER, method: str = "heuristic",
                      region: str | None = None) -> pd.DataFrame:
    """Write the information-ablation table and its numbers as Parquet beside it.

    Parameters
    ----------
    cell_files : iterable of path-like or pandas.DataFrame
        Rollout cell files, or :func:`oneocean.reporting.cells.load_cell_frames`' rows.
    out_tex : path-like
        The ``.tex`` file.
    tier : int, default ``HIGH_TIER``
        The tier.
    method : str, default "heuristic"
        The method.
    region : str, optional
        The region, named in the caption and the label.

    Returns
    -------
    pandas.DataFrame
        :func:`information_frame`'s rows.
    """
    cells = C.load_cell_frames(cell_files)
    df = information_frame(cells, tier, method)
    T._write(df, information_latex(df, cells, tier, method, region), out_tex,
             {"table": "information_ablation", "tier": int(tier), "method": method,
              "region": region})
    return df


# ------------------------------------------------------------------------------ stressors

def drop_share(sr_low: float, sr_low_key: float, sr_high: float) -> float:
    """The share of the low -> high drop in SR that one key alone produces at the low tier.

    ``(sr_low - sr_low_key) / (sr_low - sr_high)``.

    Parameters
    ----------
    sr_low : float
        SR of the low tier's cell, %.
    sr_low_key : float
        SR of the low tier with the key at its high-tier value, %.
    sr_high : float
        SR of the high tier's cell, %.

    Returns
    -------
    float
        The share (1: the whole drop); NaN when a rate is None or not finite, or the drop is
        below :data:`MIN_DROP_PTS` points.
    """
    vals = (sr_low, sr_low_key, sr_high)
    if any(v is None or not np.isfinite(v) for v in vals):
        return math.nan
    drop = sr_low - sr_high
    if drop < MIN_DROP_PTS:
        return math.nan
    return (sr_low - sr_low_key) / drop


def _override(c, key: str, default):
    """The value a key cell ran ``key`` with (its recorded ``tier_overrides``), else
    ``default``."""
    if c is None or not c["tier_overrides"]:
        return default
    return json.loads(c["tier_overrides"]).get(key, default)


def _value(v) -> str:
    """A tier value as canonical JSON (numbers and lists of numbers as written)."""
    return json.dumps(v, sort_keys=True)


def stressor_frame(cell_files, method: str = "heuristic", low: int = LOW_TIER,
                   high: int = HIGH_TIER) -> pd.DataFrame:
    """The stressor table as data: one row per (task, key).

    Every task with any of its cells (registry order) and every key of
    :func:`stressor_keys` (the tier table's order). Columns:

    ``family, task, key, low_value, high_value`` (canonical JSON); the ladder's cells
    ``T<low>_*`` and ``T<high>_*`` and the key's cells ``T<low>_plus_key_*`` (the low tier
    with the key at its high value) and ``T<high>_minus_key_*`` (the high tier with the key at
    its low value), each ``_sr, _lo, _hi`` (SR %, Wilson 95 %), ``_k``, ``_n``, ``_state``
    (``ok``, ``n/a``, ``missing``); ``drop`` = SR(low) - SR(high) in points; ``share``
    (:func:`drop_share`, NaN when n/a) with ``share_state`` (``ok``, ``small drop``: the drop
    is below :data:`MIN_DROP_PTS`, ``conflict``: the key cannot be applied alone, the task
    rejects Tier ``low`` with it, ``n/a``: a cell is missing or not hostable);
    ``over_three_quarters`` (share > :data:`MAX_SHARE`; NA when the share is n/a); per task
    ``check`` (``pass``: every key's share evaluated and none above; ``FAIL``: a key above;
    ``n/a``) and ``check_note``; ``reason`` (the row's n/a cells' reasons).

    Parameters
    ----------
    cell_files : iterable of path-like or pandas.DataFrame
        Rollout cell files, or :func:`oneocean.reporting.cells.load_cell_frames`' rows.
    method : str, default "heuristic"
        The method.
    low : int, default ``LOW_TIER``
        The easy tier.
    high : int, default ``HIGH_TIER``
        The hard tier.

    Returns
    -------
    pandas.DataFrame
        The columns above; ``attrs`` holds ``low`` and ``high``.
    """
    from .. import registry
    from ..tasks.tiers import load_task_table

    cells = C.load_cell_frames(cell_files)
    cells = cells[cells["method"] == method]
    lo_p, hi_p, plus, minus = (f"T{low}", f"T{high}", f"T{low}_plus_key",
                               f"T{high}_minus_key")
    rows = []
    for task in T._tasks(cells):
        tiers = load_task_table(task)["tiers"]
        c_lo = _one(cells, task, method, low, C.DATA_GROUNDED)
        c_hi = _one(cells, task, method, high, C.DATA_GROUNDED)
        task_rows = []
        for key in stressor_keys(task, low, high):
            c_plus = _one(cells, task, method, low, f"set-{key}")
            c_minus = _one(cells, task, method, high, f"set-{key}")
            # the values the key cells ran with (their records), else the tier table's
            row = {"family": registry.family_label(registry.task_spec(task).family),
                   "task": task, "key": key,
                   "low_value": _value(_override(c_minus, key, tiers[int(low)][key])),
                   "high_value": _value(_override(c_plus, key, tiers[int(high)][key]))}
            row.update(_rate_cols(lo_p, c_lo))
            row.update(_rate_cols(plus, c_plus))
            row.update(_rate_cols(minus, c_minus))
            row.update(_rate_cols(hi_p, c_hi))
            drop = row[f"{lo_p}_sr"] - row[f"{hi_p}_sr"]
            share = drop_share(row[f"{lo_p}_sr"], row[f"{plus}_sr"], row[f"{hi_p}_sr"])
            row["drop"] = drop
            row["share"] = share
            if np.isfinite(share):
                row["share_state"] = "ok"
            elif np.isfinite(drop) and np.isfinite(row[f"{plus}_sr"]):
                row["share_state"] = "small drop"
            elif _conflict(c_plus):
                row["share_state"] = "conflict"
            else:
                row["share_state"] = "n/a"
            row["over_three_quarters"] = (bool(share > MAX_SHARE) if np.isfinite(share)
                                          else pd.NA)
            row["reason"] = "; ".join(dict.fromkeys(
                str(c["reason"]) for c in (c_lo, c_plus, c_minus, c_hi)
                if c is not None and not c["applicable"] and c["reason"]))
            task_rows.append(row)
        check, note = _check(task_rows, low, high)
        for row in task_rows:
            row["check"], row["check_note"] = check, note
        rows += task_rows
    cols = ["family", "task", "key", "low_value", "high_value"]
    for p in (lo_p, plus, minus, hi_p):
        cols += [f"{p}_{s}" for s in ("sr", "lo", "hi", "k", "n", "state")]
    cols += ["drop", "share", "share_state", "over_three_quarters", "check", "check_note",
             "reason"]
    out = pd.DataFrame(rows, columns=cols)
    out["over_three_quarters"] = out["over_three_quarters"].astype("boolean")
    out.attrs.update(low=int(low), high=int(high))
    return out


def _conflict(c) -> bool:
    """Whether a cell records that the task cannot build its tier with its override
    (``tier_conflict`` in its record: :func:`oneocean.tasks.rollout_to_file`)."""
    from ..engine.recording import read_metrics_meta

    if c is None or c["applicable"] or not c["file"]:
        return False
    return bool(read_metrics_meta(c["file"]).get("tier_conflict", False))


def flagged(value) -> bool:
    """An ``over_three_quarters`` value as a plain bool.

    Parameters
    ----------
    value : bool, None or pandas.NA
        The value.

    Returns
    -------
    bool
        ``bool(value)``; False for None and NA.
    """
    return value is not None and value is not pd.NA and bool(value)


def _check(task_rows: list[dict], low: int, high: int) -> tuple[str, str]:
    """The protocol's check on one task's keys: ``(verdict, note)``: ``FAIL`` if a key's
    share exceeds :data:`MAX_SHARE`; ``pass`` if none does and every key's share was evaluated,
    except keys that cannot be applied alone (the task rejects the Tier-1 cell with that key:
    ``conflict``, named in the note); else ``n/a`` (the drop is too small, or cells are
    missing or not hostable)."""
    if not task_rows:
        return "n/a", "no tier key differs between the tiers"
    over = [r for r in task_rows if flagged(r["over_three_quarters"])]
    if over:
        return "FAIL", ", ".join(f"{r['key']} {r['share']:.2f}" for r in over)
    drop = task_rows[0]["drop"]
    if not np.isfinite(drop):
        return "n/a", f"no T{low} or T{high} success rate"
    if drop < MIN_DROP_PTS:
        return "n/a", f"T{low} -> T{high} drop {drop:.0f} points, below {MIN_DROP_PTS:g}"
    done = [r for r in task_rows if r["share_state"] == "ok"]
    alone = [r["key"] for r in task_rows if r["share_state"] == "conflict"]
    if done and len(done) + len(alone) == len(task_rows):
        top = max(done, key=lambda r: r["share"])
        return "pass", (f"largest share: {top['key']} {top['share']:.2f}"
                        + (f"; cannot be applied alone: {', '.join(alone)}" if alone else ""))
    missing = [r["key"] for r in task_rows if r["share_state"] not in ("ok", "conflict")]
    return "n/a", "not evaluated: " + ", ".join(missing or alone)


def _share_text(r) -> str:
    if r["share_state"] == "ok":
        t = f"{r['share']:.2f}"
        return f"\\textbf{{{t}}}$^\\dagger$" if flagged(r["over_three_quarters"]) else t
    return "n/a$^\\ddagger$" if r["share_state"] == "conflict" else "n/a"


def _num_text(x) -> str:
    """A tier value in LaTeX: ``{:g}``, powers of ten as ``4$\\times$10$^{-6}$``."""
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        return _text(x)
    t = f"{x:g}"
    if "e" in t:
        m, e = t.split("e")
        return f"{m}$\\times$10$^{{{int(e)}}}$"
    return t


def _value_text(v: str) -> str:
    x = json.loads(v)
    if isinstance(x, list):
        return "[" + ", ".join(_num_text(y) for y in x) + "]"
    return _num_text(x)


def stressor_latex(df: pd.DataFrame, cells: pd.DataFrame, method: str,
                   region: str | None = None) -> str:
    """The stressor table as LaTeX, with each task's check verdict in the caption.

    Parameters
    ----------
    df : pandas.DataFrame
        :func:`stressor_frame`'s rows (its ``attrs`` give the tiers).
    cells : pandas.DataFrame
        :func:`oneocean.reporting.cells.load_cell_frames`' rows, for the caption.
    method : str
        The method (its label is named in the caption).
    region : str, optional
        The region, named in the caption and the label.

    Returns
    -------
    str
        The ``table*`` (label ``tab:stressors_<method>[:<region>]``).
    """
    from .. import registry

    low, high = df.attrs.get("low", LOW_TIER), df.attrs.get("high", HIGH_TIER)
    lo_p, hi_p, plus, minus = (f"T{low}", f"T{high}", f"T{low}_plus_key",
                               f"T{high}_minus_key")
    header = ["Task", "Tier key", f"T{low} $\\to$ T{high}", f"T{low} SR (\\%)",
              f"T{low} + key SR (\\%)", "Share", f"T{high} $-$ key SR (\\%)",
              f"T{high} SR (\\%)"]

    def rate(r, p):
        return T._state_text(r[f"{p}_state"], T._ci(r[f"{p}_sr"], r[f"{p}_lo"], r[f"{p}_hi"],
                                                    "{:.0f}"))

    rows, last = [], None
    for _, r in df.iterrows():
        first = r["task"] != last
        if first and last is not None:
            rows.append(("rule",))
        last = r["task"]
        rows.append([_text(r["task"]) if first else "", f"\\texttt{{{_text(r['key'])}}}",
                     f"{_value_text(r['low_value'])} $\\to$ {_value_text(r['high_value'])}",
                     rate(r, lo_p) if first else "", rate(r, plus), _share_text(r),
                     rate(r, minus), rate(r, hi_p) if first else ""])
    verdicts = []
    for task, g in df.groupby("task", sort=False):
        check, note = g["check"].iloc[0], g["check_note"].iloc[0]
        verdicts.append(f"{_text(task)} {check}" + (f" ({_text(note)})" if note else ""))
    label = registry.method_spec(method).label.lower()
    sel = cells[cells["method"] == method]

    def counts(prefixes):
        return sorted({int(n) for p in prefixes for n, st in zip(df[f"{p}_n"], df[f"{p}_state"])
                       if st == "ok"})

    ladder_n, key_n = counts((lo_p, hi_p)), counts((plus, minus))
    episodes = ""
    if ladder_n and key_n and ladder_n != key_n:
        episodes = (f" Episodes per cell: {'/'.join(map(str, ladder_n))} in the ladder's cells, "
                    f"{'/'.join(map(str, key_n))} in the key cells.")
    caption = (
        T._protocol(sel, region, f"Which stressors drive the ladder: the {_text(label)} "
                                 f"method with one tier key changed at a time") + episodes
        + f" Tier key: a parameter of the task's tier table whose Tier-{low} and Tier-{high} "
        f"values differ (T{low} $\\to$ T{high}: the two values). T{low} and T{high} SR: the "
        f"ladder's cells. T{low} + key: Tier {low} with that one key at its Tier-{high} value; "
        f"T{high} $-$ key: Tier {high} with that one key back at its Tier-{low} value. Success "
        "rates with their Wilson 95\\% intervals. Share: the part of the task's "
        f"T{low} $\\to$ T{high} drop the key alone produces at Tier {low}, "
        f"(SR$_{{T{low}}}$ $-$ SR$_{{T{low}+\\mathrm{{key}}}}$) / "
        f"(SR$_{{T{low}}}$ $-$ SR$_{{T{high}}}$); n/a when the drop is below "
        f"{MIN_DROP_PTS:g} point or a cell is missing. Shares above 3/4 in bold with "
        "$^\\dagger$: the protocol requires that no single key applied alone to Tier "
        f"{low} produce more than three quarters of the drop (the tiers tighten several "
        "stressors jointly, not one knob)."
        + (f" $^\\ddagger$: the key cannot be applied alone (the task cannot build Tier {low} "
           "with it and the tier's other keys; reason below)."
           if (df["share_state"] == "conflict").any() else "")
        + " Check per task: " + "; ".join(verdicts) + "." + " --: not run." + _reasons(sel))
    return booktabs(header, rows, caption, T._label(f"tab:stressors_{method}", region),
                    align="ll" + "l" + "r" * 5, wide=True)


def stressor_table(cell_files, out_tex, method: str = "heuristic", low: int = LOW_TIER,
                   high: int = HIGH_TIER, region: str | None = None) -> pd.DataFrame:
    """Write the stressor table (:func:`stressor_frame`) and its numbers as Parquet beside it.

    Parameters
    ----------
    cell_files : iterable of path-like or pandas.DataFrame
        Rollout cell files, or :func:`oneocean.reporting.cells.load_cell_frames`' rows.
    out_tex : path-like
        The ``.tex`` file.
    method : str, default "heuristic"
        The method.
    low : int, default ``LOW_TIER``
        The easy tier.
    high : int, default ``HIGH_TIER``
        The hard tier.
    region : str, optional
        The region, named in the caption and the label.

    Returns
    -------
    pandas.DataFrame
        :func:`stressor_frame`'s rows.
    """
    cells = C.load_cell_frames(cell_files)
    df = stressor_frame(cells, method, low, high)
    T._write(df, stressor_latex(df, cells, method, region), out_tex,
             {"table": "tier_stressors", "method": method, "low": int(low),
              "high": int(high), "max_share": MAX_SHARE, "min_drop_pts": MIN_DROP_PTS,
              "region": region})
    return df
