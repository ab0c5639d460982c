"""Paper tables: LaTeX (booktabs) with 95 % intervals, the numbers beside each ``.tex`` as
Parquet.

Every table of the results is a pure function of the rollout cell files (one Parquet row per
episode, each file with its own record, :func:`oneocean.engine.recording.read_metrics_meta`;
read into one row per cell by :func:`oneocean.reporting.cells.load_cell_frames`): a
``*_frame`` function returns the numbers, a ``*_table`` function writes the LaTeX atomically
and the same numbers as Parquet next to it (``<name>.parquet``, with a record of the table's
protocol), and returns the frame.

* :func:`ladder_spec_table` (Table II): the task ladder from the registry and tier tables.
* :func:`headline_table` (Table III): one row per method; Tier-2/3 macro SR, E, Coll and the
  Tier-3 key metrics.
* :func:`task_success_table` (Table V): per task, SR of every method at every tier.
* :func:`difficulty_table`: one method's SR per tier and the drops between tiers.
* :func:`ablation_table`: one method's SR under each forcing condition at one tier.

Intervals (95 %, :mod:`oneocean.reporting.stats`): a rate has its Wilson score interval
(:func:`~oneocean.reporting.stats.rate_ci`); a macro (unweighted mean over tasks of their SR)
the stratified bootstrap of :func:`oneocean.reporting.cells.macro_rate` (episodes resampled
within each task, tasks in one canonical order: the same numbers as the ladder table); a mean
its seeded percentile bootstrap (:func:`~oneocean.reporting.stats.mean_ci`); a mean pooled over
the episodes of several tasks a stratified bootstrap
(:func:`~oneocean.reporting.stats.pooled_mean_ci`); a difference of two rates the bootstrap of
the difference, both cells resampled independently (:func:`~oneocean.reporting.stats.diff_ci`).
Every bootstrap is seeded (:data:`oneocean.reporting.stats.BOOT_SEED`), so the table bytes are
reproducible. Rows follow :func:`oneocean.registry.task_ids`, methods
:func:`oneocean.registry.method_names`.

Cells: the main tables use the *data-grounded* cells only (currents on, gain g = 1 on the
data currents, no synthetic tide); the forcing ablations (currents off, g != 1, a tide) have
their own table. A cell the region cannot host (``applicable: false``, zero episodes) is shown
as "n/a", never 0, and left out of the macros (which then average the tasks the region
hosts); a cell that was not run is "--". Bold marks the best value where "best" is
meaningful (compared as displayed; the privileged oracle, :data:`PRIVILEGED`, is not a
competitor).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Literal, Mapping

import numpy as np
import pandas as pd

from ..io import write_text_atomic
from .cells import CURRENTS_OFF, DATA_GROUNDED, load_cell_frames, macro_rate
from .latex import booktabs, fit_width
from .stats import diff_ci, mean_ci, pooled_mean_ci, rate_ci

Best = Literal["max", "min"]

#: Methods never marked best (the oracle is a privileged solvability check, not a baseline).
PRIVILEGED = ("oracle",)

#: Table labels of the vehicles (others: their name).
VEHICLE_LABEL = {"remus100": "REMUS 100", "bluerov2_heavy": "BlueROV2 Heavy"}

#: Table III's key metrics at its metric tier: (key, task, column, header, format).
#: ``success`` is a rate (Wilson); the others are means (seeded bootstrap, NaN skipped).
HEADLINE_METRICS = (
    ("G2G_sr", "G2G", "success", "G2G SR (\\%)", "{:.1f}"),
    ("RF_sr", "RF", "success", "RF SR (\\%)", "{:.1f}"),
    ("SK_rms", "SK", "rms_error_m", "SK RMS (m)", "{:.2f}"),
    ("AS_coverage", "AS", "coverage_fraction", "AS cov.", "{:.3f}"),
    ("PI_score", "PI", "inspection_score", "PI score", "{:.2f}"),
    ("SPC_cleanup", "SPC", "cleanup_rate", "SPC cleanup", "{:.2f}"),
)


def to_booktabs(df: pd.DataFrame, caption: str, label: str,
                best: Mapping[str, Best] | None = None, precision: int = 2,
                column_format: str | None = None, na_rep: str = "--") -> str:
    """Render ``df`` as a booktabs table; columns in ``best`` get their best value in bold.

    Parameters
    ----------
    df : pandas.DataFrame
        The table; the index is not shown.
    caption : str
        The LaTeX caption.
    label : str
        The LaTeX label.
    best : mapping of str to {"max", "min"}, optional
        Numeric columns whose maximum (or minimum) is set in bold (every tied value).
    precision : int, default 2
        Decimals of floats.
    column_format : str, optional
        The tabular's column spec (default: ``l`` per column).
    na_rep : str, default "--"
        Text of missing values.

    Returns
    -------
    str
        The LaTeX table (``table`` environment, placement ``t``), fitted to the line width
        (:func:`fit_width`).
    """
    styler = df.style.format(precision=precision, na_rep=na_rep)
    for col, how in (best or {}).items():
        if col in df.columns and pd.api.types.is_numeric_dtype(df[col]) and df[col].notna().any():
            target = df[col].max() if how == "max" else df[col].min()
            styler = styler.apply(
                lambda s, t=target: ["font-weight: bold" if v == t else "" for v in s],
                subset=[col])
    return fit_width(styler.hide(axis="index").to_latex(
        hrules=True, caption=caption, label=label, convert_css=True, position="t",
        column_format=column_format or "l" * len(df.columns)))


def _escape(text: str) -> str:
    return str(text).replace("_", r"\_").replace("%", r"\%").replace("&", r"\&")


def dataset_variants_frame(metadata_files) -> pd.DataFrame:
    """The dataset-variants table as data: one row per variant.

    Parameters
    ----------
    metadata_files : iterable of path-like
        The per-variant metadata JSON files of the ocean product.

    Returns
    -------
    pandas.DataFrame
        Display columns (variant, extent in degrees lon/lat, grid size, resolution in
        degrees, time coverage, depth count, mean and maximum surface current speed in m/s,
        the maximum with tides, ocean fraction, source), rows ordered tiny, scene, public.
    """
    rows = []
    for path in metadata_files:
        with open(path) as fh:
            m = json.load(fh)
        s = m["summary"]
        ext = s["extent"]
        rows.append({
            "Variant": m["variant"],
            "Extent (lon, lat)": (f"{ext['west']:.2f}..{ext['east']:.2f}, "
                                  f"{ext['south']:.2f}..{ext['north']:.2f}"),
            "Grid (ny x nx)": f"{s['ny']} x {s['nx']}",
            "Res. (deg)": s["resolution_deg"],
            "Time": f"{s['time_start'][:16]} to {s['time_end'][:16]} ({s['n_times']})",
            "Depths": s["n_depths"],
            "Mean |u| (m/s)": s["mean_speed_ms"],
            "Max |u| (m/s)": s["max_speed_ms"],
            "Max |u+tide| (m/s)": s.get("max_total_speed_ms"),
            "Ocean frac.": s["ocean_fraction"],
            "Source": _escape(s["source"]),
        })
    order = {"tiny": 0, "scene": 1, "public": 2}
    return pd.DataFrame(rows).sort_values("Variant", key=lambda c: c.map(order))


def dataset_variants_table(metadata_files, out_tex) -> None:
    """Write the dataset-variants table (:func:`dataset_variants_frame`) as LaTeX, atomically.

    Parameters
    ----------
    metadata_files : iterable of path-like
        The per-variant metadata JSON files.
    out_tex : path-like
        The ``.tex`` file.
    """
    df = dataset_variants_frame(metadata_files)
    tex = to_booktabs(
        df.assign(**{"Res. (deg)": df["Res. (deg)"].map(lambda r: f"{r:.4f}")}),
        caption="Dataset variants of the ocean-environment product (same schema; extent, "
                "resolution, time coverage and depth differ). Speeds are surface ocean currents; "
                "the last speed column adds the tidal currents.",
        label="tab:dataset_variants", precision=3, column_format="llllllrrrrl")
    write_text_atomic(out_tex, tex)


# ------------------------------------------------------------------------------ cells

def _data_grounded(cells: pd.DataFrame) -> pd.DataFrame:
    return cells[cells["condition"] == DATA_GROUNDED]


def _forcing_only(cells: pd.DataFrame) -> pd.DataFrame:
    """The cells without an ablation of their information or tier (the forcing conditions:
    data-grounded, currents off, other gains, a tide)."""
    return cells[~cells["ablation"].astype(bool)] if "ablation" in cells else cells


def _tasks(cells: pd.DataFrame) -> list[str]:
    return list(dict.fromkeys(cells["task"]))      # cells are in registry order


def _methods(cells: pd.DataFrame) -> list[str]:
    from .. import registry

    present = set(cells["method"])
    return [m for m in registry.method_names() if m in present]


def _cell(cells: pd.DataFrame, task: str, method: str, tier: int):
    """The one cell row of (task, method, tier) in ``cells`` (None if absent)."""
    sel = cells[(cells["task"] == task) & (cells["method"] == method) & (cells["tier"] == tier)]
    return None if sel.empty else sel.iloc[0]


# ------------------------------------------------------------------------------ LaTeX

def _num(v, fmt: str) -> str:
    return fmt.format(v) if v is not None and np.isfinite(v) else "--"


class _Signed:
    """A format with an explicit sign and a math minus (``+2.0``, ``$-$2.0``)."""

    @staticmethod
    def format(v) -> str:
        t = f"{v:+.1f}"
        if t == "-0.0":
            t = "+0.0"
        return "$-$" + t[1:] if t.startswith("-") else t


_SIGNED = _Signed()


def _ci(v, lo, hi, fmt: str = "{:.1f}") -> str:
    if v is None or not np.isfinite(v):
        return "--"
    return f"{fmt.format(v)} [{fmt.format(lo)}, {fmt.format(hi)}]"


def _state_text(state: str, text: str) -> str:
    return {"n/a": "n/a", "missing": "--"}.get(state, text)


def _bold_best(values, texts, higher: bool, fmt: str, eligible=None) -> list[str]:
    """Bold the texts whose value, as displayed (``fmt``), is the best among the eligible
    finite values; nothing when fewer than two are eligible."""
    eligible = [True] * len(values) if eligible is None else list(eligible)
    shown = [float(fmt.format(v)) if ok and v is not None and np.isfinite(v) else None
             for v, ok in zip(values, eligible)]
    finite = [s for s in shown if s is not None]
    if len(finite) < 2:
        return list(texts)
    best = max(finite) if higher else min(finite)
    return [f"\\textbf{{{t}}}" if s is not None and s == best else t
            for s, t in zip(shown, texts)]


def _seeds_episodes(cells: pd.DataFrame) -> str:
    """``"evaluation seed 1000, 50 episodes per cell"`` from the cells' records."""
    seeds = sorted({int(s) for s in cells["seed"] if s is not None and not pd.isna(s)})
    ns = sorted(set(cells.loc[cells["applicable"] & (cells["n"] > 0), "n"]))
    parts = []
    if seeds:
        parts.append(("evaluation seed " if len(seeds) == 1 else "evaluation seeds ")
                     + ", ".join(str(s) for s in seeds))
    if ns:
        parts.append(f"{ns[0]} episodes per cell" if len(ns) == 1
                     else f"{ns[0]}--{ns[-1]} episodes per cell")
    return ", ".join(parts)


def _protocol(cells: pd.DataFrame, region: str | None, what: str) -> str:
    head = what + (f", region {_escape(region)}" if region else "")
    rest = _seeds_episodes(cells)
    return head + (f" ({rest})." if rest else ".")


def _na_note(cells: pd.DataFrame) -> str:
    na = cells[~cells["applicable"]]
    if na.empty:
        return ""
    per = {}
    for _, c in na.iterrows():
        per.setdefault(c["task"], set()).add(int(c["tier"]))
    what = "; ".join(f"{t} at " + ", ".join(f"T{k}" for k in sorted(ks))
                     for t, ks in per.items())
    return (f" n/a: the region cannot host the cell ({what}; the reasons are recorded in the "
            "cell files); macros average the tasks the region hosts.")


def _hosted(macro: pd.DataFrame, total: int) -> str:
    """``" (T2, T3: 9 of the 10 tasks)"`` for the tiers whose macros average fewer tasks
    than the table has (``macro``: rows with ``tier`` and ``tasks``)."""
    per: dict[int, set] = {}
    for k, n in zip(macro["tier"], macro["tasks"]):
        per.setdefault(int(k), set()).add(int(n))
    short: dict[str, list[int]] = {}
    for k, ns in sorted(per.items()):
        if min(ns) < total:
            short.setdefault(", ".join(map(str, sorted(ns))), []).append(k)
    if not short:
        return ""
    return " (" + "; ".join(", ".join(f"T{k}" for k in ks) + f": {n} of the {total} tasks"
                            for n, ks in short.items()) + ")"


def _write(frame: pd.DataFrame, tex: str, out_tex, meta: dict) -> None:
    from ..engine.recording import write_metrics

    write_text_atomic(out_tex, tex)
    write_metrics(frame, Path(out_tex).with_suffix(".parquet"), meta={"stage": "paper_table",
                                                                      **meta})


def _label(base: str, region: str | None) -> str:
    return base if not region else f"{base}:{region}"


def _family_rows(tasks: list[str], body: dict[str, list[str]]) -> list:
    """Rows grouped under family headings (tasks in the given order)."""
    from .. import registry

    rows, last = [], None
    for t in tasks:
        fam = registry.family_label(registry.task_spec(t).family)
        if fam != last:
            rows.append(("group", _escape(fam)))
            last = fam
        rows.append(body[t])
    return rows


# ------------------------------------------------------------------------------ Table II

def ladder_spec_frame(tasks=None) -> pd.DataFrame:
    """Table II as data: one row per task, from the registry and the tier tables.

    Parameters
    ----------
    tasks : sequence of str, optional
        The tasks, in order (default: :func:`oneocean.registry.task_ids`).

    Returns
    -------
    pandas.DataFrame
        ``family, task, label, agents_default, agents_lo, agents_hi, vehicle, primary,
        primary_higher, calibration_seeds`` (JSON list) and per tier k
        ``T<k>_time_limit_s`` (s), ``T<k>_band_lo``, ``T<k>_band_hi`` (the current band:
        quantiles of the region's own speeds, ``current_band``; NaN where a table lacks
        the key), ``T<k>_ms_lo``, ``T<k>_ms_hi`` (an absolute band in m s-1,
        ``current_ms``, where a task's table has one instead) and ``T<k>_params`` (every
        tier parameter, canonical JSON; ``""`` for a tier the task lacks).
    """
    from .. import registry
    from ..tasks.tiers import load_task_table

    tasks = list(registry.task_ids() if tasks is None else tasks)
    tables = {t: load_task_table(t) for t in tasks}
    tiers = sorted({k for tb in tables.values() for k in tb["tiers"]})
    rows = []
    for t in tasks:
        s, tb = registry.task_spec(t), tables[t]
        row = {"family": registry.family_label(s.family), "task": t, "label": s.label,
               "agents_default": s.agents_default, "agents_lo": s.agents_range[0],
               "agents_hi": s.agents_range[1], "vehicle": str(tb.get("vehicle", "")),
               "primary": s.primary, "primary_higher": bool(s.higher_is_better[s.primary]),
               "calibration_seeds": json.dumps((tb.get("calibration") or {}).get("seeds", []))}
        for k in tiers:
            p = tb["tiers"].get(k)
            band = (p or {}).get("current_band") or (math.nan, math.nan)
            ms = (p or {}).get("current_ms") or (math.nan, math.nan)
            row[f"T{k}_time_limit_s"] = float((p or {}).get("time_limit_s", math.nan))
            row[f"T{k}_band_lo"], row[f"T{k}_band_hi"] = float(band[0]), float(band[1])
            row[f"T{k}_ms_lo"], row[f"T{k}_ms_hi"] = float(ms[0]), float(ms[1])
            row[f"T{k}_params"] = "" if p is None else json.dumps(p, sort_keys=True)
        rows.append(row)
    return pd.DataFrame(rows)


def _tier_cell(row, k: int) -> str:
    if not row[f"T{k}_params"]:
        return "--"
    tl = row[f"T{k}_time_limit_s"]
    lo, hi = row[f"T{k}_band_lo"], row[f"T{k}_band_hi"]
    mlo, mhi = row.get(f"T{k}_ms_lo", math.nan), row.get(f"T{k}_ms_hi", math.nan)
    if np.isfinite(lo):
        band = f"{100 * lo:.0f}--{100 * hi:.0f}"
    elif np.isfinite(mlo):
        band = f"{mlo:g}--{mhi:g}\\,m/s"
    else:
        band = "--"
    return f"{_num(tl, '{:.0f}')}; {band}"


def ladder_spec_latex(df: pd.DataFrame) -> str:
    """Table II as LaTeX: tasks grouped by family, each tier's time limit and current band.

    Parameters
    ----------
    df : pandas.DataFrame
        :func:`ladder_spec_frame`'s rows.

    Returns
    -------
    str
        The ``table*`` (label ``tab:task_ladder``).
    """
    tiers = sorted(int(c[1:].split("_")[0]) for c in df.columns if c.endswith("_params"))
    header = ["ID", "Task", "Agents", "Vehicle", "Primary metric"] + [f"Tier {k}" for k in tiers]
    body = {}
    for _, r in df.iterrows():
        lo, hi, d = r["agents_lo"], r["agents_hi"], r["agents_default"]
        agents = str(d) if lo == hi else f"{d} ({lo}--{hi})"
        arrow = "$\\uparrow$" if r["primary_higher"] else "$\\downarrow$"
        body[r["task"]] = [_escape(r["task"]), _escape(r["label"]), agents,
                           _escape(VEHICLE_LABEL.get(r["vehicle"], r["vehicle"]) or "--"),
                           f"\\texttt{{{_escape(r['primary'])}}} {arrow}"] + [
            _tier_cell(r, k) for k in tiers]
    seeds = sorted({s for v in df["calibration_seeds"] for s in json.loads(v)})
    caption = ("The task ladder. Agents: default (range). Primary metric: $\\uparrow$ higher "
               "is better, $\\downarrow$ lower. Each tier: time limit (s); current band, the "
               "percentiles of the region's own current speeds an episode's current must lie "
               "between (the data are never rescaled), or an absolute band in m/s (the "
               "transits G2G and RF, whose vehicle cruises at 1.25 m/s). The task-specific stressors "
               "(tolerances, route length or area, coordination) tighten monotonically with "
               "the tier (the tier tables). Every non-oracle method senses through the same "
               "sensor models in every tier."
               + (f" Calibrated on seeds {', '.join(map(str, seeds))} only; the evaluation seed "
                  "is held out." if seeds else ""))
    align = "lllll" + "l" * len(tiers)
    return booktabs(header, _family_rows(list(df["task"]), body), caption, "tab:task_ladder",
                  align=align, wide=True)


def ladder_spec_table(out_tex, tasks=None) -> pd.DataFrame:
    """Write Table II (no cell files needed) and its numbers as Parquet.

    Parameters
    ----------
    out_tex : path-like
        The ``.tex`` file; the numbers go beside it as ``.parquet``.
    tasks : sequence of str, optional
        As :func:`ladder_spec_frame`.

    Returns
    -------
    pandas.DataFrame
        :func:`ladder_spec_frame`'s rows.
    """
    df = ladder_spec_frame(tasks)
    _write(df, ladder_spec_latex(df), out_tex, {"table": "task_ladder"})
    return df


# ------------------------------------------------------------------------------ Table V

def task_success_ci_frame(cell_files) -> pd.DataFrame:
    """Table V as data, long: one row per (task, method, tier), then the macro rows.

    A method without a cell of every task the table has at a tier (e.g. a baseline trained
    only on the single-vehicle tasks) has no macro row at that tier: its mean would be over
    other tasks than the rest of the row's.

    Parameters
    ----------
    cell_files : iterable of path-like or pandas.DataFrame
        Rollout cell files, or :func:`~oneocean.reporting.cells.load_cell_frames`' rows; only the
        data-grounded cells are used.

    Returns
    -------
    pandas.DataFrame
        Per cell (registry orders, then tier): ``family, task, n_agents, method, label, tier,
        sr, lo, hi`` (%, Wilson 95 %), ``n`` (episodes), ``applicable``, ``tasks`` (1),
        ``reason``; then per (method, tier) a ``task == "Macro"`` row: the unweighted mean
        over the tasks the region hosts with its stratified-bootstrap interval, ``tasks`` =
        how many it averages.
    """
    from .. import registry

    cells = _data_grounded(load_cell_frames(cell_files))
    rows = []
    for _, c in cells.iterrows():
        sr, lo, hi = rate_ci(c["success"]) if c["applicable"] else (math.nan,) * 3
        rows.append({"family": registry.family_label(registry.task_spec(c["task"]).family),
                     "task": c["task"], "n_agents": c["n_agents"], "method": c["method"],
                     "label": registry.method_spec(c["method"]).short, "tier": int(c["tier"]),
                     "sr": sr, "lo": lo, "hi": hi, "n": int(c["n"]),
                     "applicable": bool(c["applicable"]), "tasks": 1,
                     "reason": str(c["reason"] or "")})
    for m in _methods(cells):
        for k in sorted(set(cells.loc[cells["method"] == m, "tier"])):
            sel = cells[(cells["method"] == m) & (cells["tier"] == k)]
            if set(sel["task"]) != set(cells.loc[cells["tier"] == k, "task"]):
                continue
            mac = macro_rate(cells, m, k)
            rows.append({"family": "", "task": "Macro", "n_agents": pd.NA, "method": m,
                         "label": registry.method_spec(m).short, "tier": int(k),
                         "sr": mac["sr"], "lo": mac["lo"], "hi": mac["hi"],
                         "n": int(sel["n"].sum()), "applicable": mac["tasks"] > 0,
                         "tasks": int(mac["tasks"]), "reason": ""})
    cols = ["family", "task", "n_agents", "method", "label", "tier", "sr", "lo", "hi", "n",
            "applicable", "tasks", "reason"]
    out = pd.DataFrame(rows, columns=cols)
    out["n_agents"] = out["n_agents"].astype("Int64")
    return out


def task_success_frame(cell_files) -> pd.DataFrame:
    """Per-task success rate (%) by method and tier, wide, plus a macro row.

    The point estimates of :func:`task_success_ci_frame`; the macro is the unweighted mean over
    the tasks the region hosts. Rows follow :func:`oneocean.registry.task_ids` (the paper's
    order, then registered extras) with the registry's family labels; columns follow the
    registry's method order, labelled with each method's ``short`` label (``"Heur T2"``). A task
    or method in the rollouts that is not registered is a ConfigError (never silently dropped).
    A cell the region cannot host is NaN (n/a), never 0 %.

    Parameters
    ----------
    cell_files : iterable of path-like or pandas.DataFrame
        Rollout cell files, or :func:`~oneocean.reporting.cells.load_cell_frames`' rows (used as
        they are).

    Returns
    -------
    pandas.DataFrame
        ``Family, Task, N`` (agents) and one column per (method, tier), ``"<short> T<k>"``.

    Raises
    ------
    ConfigError
        A task or method that is not registered.
    """
    from .. import registry

    long = task_success_ci_frame(cell_files)
    per = long[long["task"] != "Macro"]
    sr = per.pivot(index="task", columns=["method", "tier"], values="sr")
    sr = sr.loc[list(dict.fromkeys(per["task"]))]
    m_order = {m: i for i, m in enumerate(registry.method_names())}
    sr = sr[sorted(sr.columns, key=lambda c: (m_order[c[0]], c[1]))]
    sr.columns = [f"{registry.method_spec(m).short} T{t}" for m, t in sr.columns]
    first = per.drop_duplicates("task").set_index("task")
    out = sr.reset_index().rename(columns={"task": "Task"})
    out.insert(0, "Family", out["Task"].map(first["family"]))
    out.insert(2, "N", out["Task"].map(first["n_agents"]).astype(int))
    mac = long[long["task"] == "Macro"]
    mac = {f"{registry.method_spec(m).short} T{t}": v
           for m, t, v in zip(mac["method"], mac["tier"], mac["sr"])}
    macro = {"Family": "", "Task": "Macro", "N": pd.NA,
             **{c: mac.get(c, math.nan) for c in sr.columns}}
    return pd.concat([out, pd.DataFrame([macro])], ignore_index=True)


def task_success_latex(long: pd.DataFrame, cells: pd.DataFrame, region: str | None = None,
                       privileged=PRIVILEGED) -> str:
    """Table V as LaTeX: SR [Wilson 95 %] per task, method and tier, and the macro row.

    Parameters
    ----------
    long : pandas.DataFrame
        :func:`task_success_ci_frame`'s rows.
    cells : pandas.DataFrame
        The data-grounded :func:`~oneocean.reporting.cells.load_cell_frames` rows, for the caption
        (seeds, episodes, n/a cells).
    region : str, optional
        The region, named in the caption and the label.
    privileged : sequence of str, default ``PRIVILEGED``
        Methods never set in bold.

    Returns
    -------
    str
        The ``table*`` (label ``tab:task_success[:<region>]``).
    """
    from .. import registry

    per = long[long["task"] != "Macro"]
    tasks = list(dict.fromkeys(per["task"]))
    tiers = sorted(set(long["tier"]))
    methods = list(dict.fromkeys(long["method"]))
    cols = [(m, k) for k in tiers for m in methods
            if ((long["method"] == m) & (long["tier"] == k)).any()]
    header = ["Task", "N"] + [f"{registry.method_spec(m).short} T{k}" for m, k in cols]
    idx = long.set_index(["task", "method", "tier"])

    def texts(task, fmt):
        vals, out = [], []
        for m, k in cols:
            if (task, m, k) not in idx.index:
                vals.append(math.nan)
                out.append("--")
                continue
            r = idx.loc[(task, m, k)]
            vals.append(r["sr"])
            out.append(_ci(r["sr"], r["lo"], r["hi"], fmt) if r["applicable"] else "n/a")
        for k in tiers:     # best non-privileged method per task and tier
            pos = [i for i, (m, kk) in enumerate(cols) if kk == k]
            bold = _bold_best([vals[i] for i in pos], [out[i] for i in pos], True, fmt,
                              [cols[i][0] not in privileged for i in pos])
            for i, t in zip(pos, bold):
                out[i] = t
        return out

    body = {}
    for t in tasks:
        n = per.loc[per["task"] == t, "n_agents"].iloc[0]
        body[t] = [_escape(t), str(int(n))] + texts(t, "{:.0f}")
    rows = _family_rows(tasks, body)
    if (long["task"] == "Macro").any():
        rows += [("rule",), ["Macro", ""] + texts("Macro", "{:.1f}")]
    over = _hosted(long[long["task"] == "Macro"], len(tasks))
    have = set(zip(long.loc[long["task"] == "Macro", "method"],
                   long.loc[long["task"] == "Macro", "tier"]))
    part = per.groupby(["method", "tier"], sort=False)["task"].nunique()
    part = [f"{_escape(registry.method_spec(m).short)} T{k}: {n} of the {len(tasks)} tasks"
            for (m, k), n in part.items() if (m, k) not in have]
    no_macro = (" No macro for a method run on only some of the tasks ("
                + "; ".join(part) + ").") if part else ""
    caption = (_protocol(cells, region, "Success rate (\\%) per task, method and tier")
               + " Each cell: SR with its Wilson 95\\% interval; N: agents. Macro: the "
               "unweighted mean over the tasks the region hosts" + over + ", with a "
               "stratified-bootstrap 95\\% interval (episodes resampled within each task, "
               "seeded). Best non-oracle method per task and tier in bold (the oracle is a "
               "privileged solvability check, not a baseline)." + no_macro + _na_note(cells))
    return booktabs(header, rows, caption, _label("tab:task_success", region),
                  align="lr" + "r" * len(cols), wide=True)


def task_success_table(cell_files, out_tex, region: str | None = None) -> pd.DataFrame:
    """Write Table V and its numbers as Parquet beside the ``.tex``.

    The workflow's ``table_task_success`` rule.

    Parameters
    ----------
    cell_files : iterable of path-like or pandas.DataFrame
        Rollout cell files, or :func:`~oneocean.reporting.cells.load_cell_frames`' rows (used as
        they are).
    out_tex : path-like
        The ``.tex`` file.
    region : str, optional
        The region, named in the caption and the label.

    Returns
    -------
    pandas.DataFrame
        :func:`task_success_ci_frame`'s rows (what the Parquet holds).
    """
    cells = _data_grounded(load_cell_frames(cell_files))
    long = task_success_ci_frame(cells)
    _write(long, task_success_latex(long, cells, region), out_tex,
           {"table": "task_success", "region": region})
    return long


# ------------------------------------------------------------------------------ Table III

def _by_task(sel: pd.DataFrame, column: str, scale: float = 1.0) -> list[np.ndarray]:
    """The applicable cells' values of ``column`` (times ``scale``), one array per task, tasks
    in canonical (sorted id) order as the macros stratify them."""
    app = sel[sel["applicable"] & (sel["n"] > 0)].sort_values("task", kind="stable")
    return [c[column].to_numpy(dtype=np.float64) * scale for c in app["episodes"]]


def headline_frame(cell_files, tiers=(2, 3), metric_tier: int = 3,
                   metrics=HEADLINE_METRICS) -> pd.DataFrame:
    """Table III as data: one row per method (registry order) with data-grounded cells.

    Columns:

    * per tier k of ``tiers``: ``T<k>_sr`` (macro SR over the tasks the region hosts,
      stratified bootstrap; ``T<k>_sr_tasks``), ``T<k>_E`` (mean E over every episode of the
      tier, stratified bootstrap) and ``T<k>_coll`` (mean Coll = ``coll_ratio`` x 100 over the
      episodes of the multi-agent tasks, ``n_agents > 1``; ``T<k>_coll_tasks``);
    * at ``metric_tier``, per key metric of ``metrics`` (:data:`HEADLINE_METRICS`): a rate
      (Wilson) or a mean of the finite values (seeded bootstrap; SK's ``rms_error_m``, the
      station-keeping RMS over the episode's window, is defined for every episode, so its
      mean includes the failures), with ``<key>_state``: ``ok``, ``n/a`` (the region cannot
      host the cell) or ``missing``.

    Every value has ``_lo`` / ``_hi`` (95 %). A method without a cell of every task the
    table has at tier k has no ``T<k>`` aggregates (NaN, ``_tasks`` 0): they would average
    other tasks than the other methods'.

    Parameters
    ----------
    cell_files : iterable of path-like or pandas.DataFrame
        Rollout cell files, or :func:`~oneocean.reporting.cells.load_cell_frames`' rows; only the
        data-grounded cells are used.
    tiers : sequence of int, default (2, 3)
        The tiers with macro SR, E and Coll columns.
    metric_tier : int, default 3
        The tier of the key metrics.
    metrics : sequence of tuple, default ``HEADLINE_METRICS``
        ``(key, task, column, header, format)`` per key metric.

    Returns
    -------
    pandas.DataFrame
        One row per method: ``method, label`` and the columns above. E is the team energy
        proxy, m2 s-1; Coll is in %.
    """
    from .. import registry

    cells = _data_grounded(load_cell_frames(cell_files))
    rows = []
    for m in _methods(cells):
        cm = cells[cells["method"] == m]
        row = {"method": m, "label": registry.method_spec(m).short}
        for k in tiers:
            sel = cm[cm["tier"] == k]
            if set(sel["task"]) != set(cells.loc[cells["tier"] == k, "task"]):
                # run on only some of the tier's tasks: no aggregate over other tasks than
                # the other methods' (Table V shows its per-task rates)
                for key in ("sr", "E", "coll"):
                    row[f"T{k}_{key}"] = row[f"T{k}_{key}_lo"] = row[f"T{k}_{key}_hi"] = math.nan
                row[f"T{k}_sr_tasks"] = row[f"T{k}_coll_tasks"] = 0
                continue
            mac = macro_rate(cells, m, k)
            row[f"T{k}_sr"], row[f"T{k}_sr_lo"], row[f"T{k}_sr_hi"] = (
                mac["sr"], mac["lo"], mac["hi"])
            row[f"T{k}_sr_tasks"] = int(mac["tasks"])
            row[f"T{k}_E"], row[f"T{k}_E_lo"], row[f"T{k}_E_hi"] = pooled_mean_ci(
                _by_task(sel, "E"))
            multi = sel[sel["n_agents"] > 1]
            row[f"T{k}_coll"], row[f"T{k}_coll_lo"], row[f"T{k}_coll_hi"] = pooled_mean_ci(
                _by_task(multi, "coll_ratio", 100.0))
            row[f"T{k}_coll_tasks"] = int((multi["applicable"] & (multi["n"] > 0)).sum())
        for key, task, col, _, _ in metrics:
            c = _cell(cm, task, m, metric_tier)
            if c is None or not c["applicable"] or c["n"] == 0:
                state, vals = ("missing" if c is None else "n/a"), (math.nan,) * 3
            else:
                ep = c["episodes"]
                state = "ok"
                vals = (rate_ci(ep["success"].to_numpy(dtype=bool)) if col == "success"
                        else mean_ci(ep[col].to_numpy(dtype=np.float64)))
            row[key], row[f"{key}_lo"], row[f"{key}_hi"] = vals
            row[f"{key}_state"] = state
        rows.append(row)
    return pd.DataFrame(rows)


def headline_latex(df: pd.DataFrame, cells: pd.DataFrame, tiers=(2, 3), metric_tier: int = 3,
                   metrics=HEADLINE_METRICS, region: str | None = None,
                   privileged=PRIVILEGED) -> str:
    """Table III as LaTeX: one row per method, best non-privileged value per column in bold.

    Parameters
    ----------
    df : pandas.DataFrame
        :func:`headline_frame`'s rows.
    cells : pandas.DataFrame
        The data-grounded :func:`~oneocean.reporting.cells.load_cell_frames` rows, for the caption.
    tiers : sequence of int, default (2, 3)
        As :func:`headline_frame`.
    metric_tier : int, default 3
        As :func:`headline_frame`.
    metrics : sequence of tuple, default ``HEADLINE_METRICS``
        As :func:`headline_frame`; the task's ``higher_is_better`` decides the bold.
    region : str, optional
        The region, named in the caption and the label.
    privileged : sequence of str, default ``PRIVILEGED``
        Methods never set in bold.

    Returns
    -------
    str
        The ``table*`` (label ``tab:headline[:<region>]``).
    """
    from .. import registry

    header = ["Method"]
    cols = [[_escape(v) for v in df["label"]]]
    eligible = [m not in privileged for m in df["method"]]

    def add(name, key, higher, fmt, state=None):
        header.append(name)
        vals = df[key].tolist()
        texts = [_ci(v, lo, hi, fmt) for v, lo, hi in
                 zip(vals, df[f"{key}_lo"], df[f"{key}_hi"])]
        if state is not None:
            texts = [_state_text(s, t) for s, t in zip(df[state], texts)]
        cols.append(_bold_best(vals, texts, higher, fmt, eligible))

    for k in tiers:
        add(f"T{k} SR (\\%)", f"T{k}_sr", True, "{:.1f}")
    for k in tiers:
        add(f"T{k} E", f"T{k}_E", False, "{:.0f}")
    for k in tiers:
        add(f"T{k} Coll (\\%)", f"T{k}_coll", False, "{:.2f}")
    for key, task, col, name, fmt in metrics:
        higher = True if col == "success" else registry.task_spec(task).higher_is_better.get(
            col, True)
        add(f"T{metric_tier} {name}", key, higher, fmt, f"{key}_state")
    n = len(df)
    rows = [[c[i] for c in cols] for i in range(n)]
    multi = sorted(set(cells.loc[cells["n_agents"] > 1, "task"]),
                   key=list(registry.task_ids()).index)
    over = _hosted(pd.DataFrame({"tier": [k for k in tiers for _ in range(n)],
                                 "tasks": [v for k in tiers for v in df[f"T{k}_sr_tasks"]]}),
                   len(set(cells["task"])))
    caption = (
        _protocol(cells, region, "Headline results per method")
        + " SR: macro success rate, the unweighted mean over the tasks the region hosts"
        + over + ", with a stratified-bootstrap 95\\% interval (episodes resampled within each "
        "task). E (m$^2$\\,s$^{-1}$): mean over every episode of the tier; Coll: mean share of "
        "steps with two agents closer than 2 m, in \\%, over the episodes of the multi-agent "
        f"tasks only ({', '.join(multi) if multi else 'none'}); both with stratified seeded "
        f"bootstrap 95\\% intervals. Tier-{metric_tier} key metrics: G2G and RF success rates "
        "(Wilson 95\\%); SK station RMS (m, over every episode, failures included), AS "
        "scan coverage, PI inspection score and SPC cleanup rate: means with seeded-bootstrap "
        "95\\% intervals. Best non-oracle value per column in bold (oracle: privileged, not a "
        "baseline); currents-off and other forcing ablations excluded." + _na_note(cells))
    return booktabs(header, rows, caption, _label("tab:headline", region), wide=True)


def headline_table(cell_files, out_tex, tiers=(2, 3), metric_tier: int = 3,
                   region: str | None = None) -> pd.DataFrame:
    """Write Table III and its numbers (:func:`headline_frame`) as Parquet.

    Parameters
    ----------
    cell_files : iterable of path-like or pandas.DataFrame
        Rollout cell files, or :func:`~oneocean.reporting.cells.load_cell_frames`' rows (used as
        they are).
    out_tex : path-like
        The ``.tex`` file; the numbers go beside it as ``.parquet``.
    tiers : sequence of int, default (2, 3)
        As :func:`headline_frame`.
    metric_tier : int, default 3
        As :func:`headline_frame`.
    region : str, optional
        The region, named in the caption and the label.

    Returns
    -------
    pandas.DataFrame
        :func:`headline_frame`'s rows.
    """
    cells = _data_grounded(load_cell_frames(cell_files))
    df = headline_frame(cells, tiers, metric_tier)
    _write(df, headline_latex(df, cells, tiers, metric_tier, region=region), out_tex,
           {"table": "headline", "tiers": list(tiers), "metric_tier": int(metric_tier),
            "region": region})
    return df


# ------------------------------------------------------------------------------ difficulty

def difficulty_frame(cell_files, method: str = "heuristic") -> pd.DataFrame:
    """The difficulty ladder of one method as data: one row per task, then a ``Macro`` row.

    Tasks in registry order, those with data-grounded cells of ``method``.

    Per tier k: ``T<k>_sr, T<k>_lo, T<k>_hi`` (Wilson; macro: stratified bootstrap over the
    hosted tasks, ``T<k>_tasks``), ``T<k>_n`` (episodes), ``T<k>_state`` (``ok``, ``n/a``,
    ``missing``). Per pair of consecutive tiers a < b: ``drop_T<a>_T<b>`` = SR(a) - SR(b) in
    points (positive: tier b is harder) with ``_lo`` / ``_hi`` from a seeded bootstrap of the
    difference (both cells resampled independently); the macro drop is the mean over the
    tasks hosted at both tiers (``drop_T<a>_T<b>_tasks``), a stratified bootstrap.

    Parameters
    ----------
    cell_files : iterable of path-like or pandas.DataFrame
        Rollout cell files, or :func:`~oneocean.reporting.cells.load_cell_frames`' rows (used as
        they are).
    method : str, default "heuristic"
        The method.

    Returns
    -------
    pandas.DataFrame
        ``family, task`` and the columns above (rates and drops in %, points).
    """
    from .. import registry

    cells = _data_grounded(load_cell_frames(cell_files))
    cells = cells[cells["method"] == method]
    tiers = sorted(set(cells["tier"]))
    pairs = list(zip(tiers[:-1], tiers[1:]))
    tasks = _tasks(cells)
    rows = []

    def usable(c):
        return c is not None and c["applicable"] and c["n"] > 0

    for t in tasks:
        row = {"family": registry.family_label(registry.task_spec(t).family), "task": t}
        for k in tiers:
            c = _cell(cells, t, method, k)
            row[f"T{k}_sr"], row[f"T{k}_lo"], row[f"T{k}_hi"] = (
                rate_ci(c["success"]) if usable(c) else (math.nan,) * 3)
            row[f"T{k}_n"] = 0 if c is None else int(c["n"])
            row[f"T{k}_tasks"] = int(usable(c))
            row[f"T{k}_state"] = "missing" if c is None else ("ok" if usable(c) else "n/a")
        for a, b in pairs:
            ca, cb = _cell(cells, t, method, a), _cell(cells, t, method, b)
            ok = usable(ca) and usable(cb)
            key = f"drop_T{a}_T{b}"
            row[key], row[f"{key}_lo"], row[f"{key}_hi"] = (
                diff_ci([(ca["success"], cb["success"])]) if ok else (math.nan,) * 3)
            row[f"{key}_tasks"] = int(ok)
        rows.append(row)
    if tasks:
        row = {"family": "", "task": "Macro"}
        for k in tiers:
            mac = macro_rate(cells, method, k)
            row[f"T{k}_sr"], row[f"T{k}_lo"], row[f"T{k}_hi"] = mac["sr"], mac["lo"], mac["hi"]
            row[f"T{k}_n"] = int(cells.loc[cells["tier"] == k, "n"].sum())
            row[f"T{k}_tasks"] = int(mac["tasks"])
            row[f"T{k}_state"] = "ok" if mac["tasks"] else "n/a"
        for a, b in pairs:
            both = []
            for t in sorted(tasks):      # canonical order, as the macros stratify
                ca, cb = _cell(cells, t, method, a), _cell(cells, t, method, b)
                if usable(ca) and usable(cb):
                    both.append((ca["success"], cb["success"]))
            key = f"drop_T{a}_T{b}"
            row[key], row[f"{key}_lo"], row[f"{key}_hi"] = diff_ci(both)
            row[f"{key}_tasks"] = len(both)
        rows.append(row)
    return pd.DataFrame(rows)


def difficulty_latex(df: pd.DataFrame, cells: pd.DataFrame, method: str,
                     region: str | None = None) -> str:
    """The difficulty-ladder table as LaTeX: SR per tier and the drops between tiers.

    Parameters
    ----------
    df : pandas.DataFrame
        :func:`difficulty_frame`'s rows.
    cells : pandas.DataFrame
        The data-grounded :func:`~oneocean.reporting.cells.load_cell_frames` rows, for the caption.
    method : str
        The method (its label is named in the caption).
    region : str, optional
        The region, named in the caption and the label.

    Returns
    -------
    str
        The ``table*`` (label ``tab:difficulty_<method>[:<region>]``).
    """
    from .. import registry

    tiers = sorted(int(c[1:].split("_")[0]) for c in df.columns
                   if c.startswith("T") and c.endswith("_state"))
    drops = [c for c in df.columns if c.startswith("drop_") and c.count("_") == 2]
    header = ["Task"] + [f"T{k} SR (\\%)" for k in tiers] + [
        f"$\\Delta$ T{d.split('_')[1][1:]}$\\to$T{d.split('_')[2][1:]} (pts)" for d in drops]
    body, macro = {}, None
    for _, r in df.iterrows():
        fmt = "{:.1f}" if r["task"] == "Macro" else "{:.0f}"
        line = [_escape(r["task"])] + [
            _state_text(r[f"T{k}_state"], _ci(r[f"T{k}_sr"], r[f"T{k}_lo"], r[f"T{k}_hi"], fmt))
            for k in tiers] + [_ci(r[d], r[f"{d}_lo"], r[f"{d}_hi"], _SIGNED)
                               if np.isfinite(r[d]) else "n/a" for d in drops]
        if r["task"] == "Macro":
            macro = line
        else:
            body[r["task"]] = line
    rows = _family_rows([t for t in df["task"] if t != "Macro"], body)
    if macro is not None:
        rows += [("rule",), macro]
    label = registry.method_spec(method).label
    caption = (
        _protocol(cells[cells["method"] == method], region,
                  f"Difficulty ladder of the {_escape(label.lower())} method")
        + " Success rate per tier with its Wilson 95\\% interval; $\\Delta$: the drop in "
        "success rate from one tier to the next, in percentage points (positive: the higher "
        "tier is harder), with a seeded bootstrap 95\\% interval of the difference (both cells "
        "resampled independently). Macro: unweighted means over the tasks the region hosts "
        "(a macro drop over the tasks hosted at both tiers), stratified-bootstrap 95\\% "
        "intervals." + _na_note(cells[cells["method"] == method]))
    return booktabs(header, rows, caption, _label(f"tab:difficulty_{method}", region),
                  wide=True)


def difficulty_table(cell_files, out_tex, method: str = "heuristic",
                     region: str | None = None) -> pd.DataFrame:
    """Write the difficulty-ladder table of ``method`` and its numbers as Parquet.

    Parameters
    ----------
    cell_files : iterable of path-like or pandas.DataFrame
        Rollout cell files, or :func:`~oneocean.reporting.cells.load_cell_frames`' rows (used as
        they are).
    out_tex : path-like
        The ``.tex`` file; the numbers go beside it as ``.parquet``.
    method : str, default "heuristic"
        The method.
    region : str, optional
        The region, named in the caption and the label.

    Returns
    -------
    pandas.DataFrame
        :func:`difficulty_frame`'s rows.
    """
    cells = _data_grounded(load_cell_frames(cell_files))
    df = difficulty_frame(cells, method)
    _write(df, difficulty_latex(df, cells, method, region), out_tex,
           {"table": "difficulty", "method": method, "region": region})
    return df


# ------------------------------------------------------------------------------ ablation

def _condition_note(cond: str, label: str, tide: str | None, gain: float) -> str:
    if cond == DATA_GROUNDED:
        return "data-grounded: the product's currents as they are (g = 1)"
    if cond == CURRENTS_OFF:
        return "currents off: g = 0, no tides"
    parts = []
    if gain != 1.0:
        parts.append(f"g = {gain:g} on the data currents u, v")
    if tide is not None:
        t = json.loads(tide)
        parts.append("a synthetic tide $c_{tide}(t) = A[\\sin(\\omega t + \\phi), "
                     f"\\cos(\\omega t + \\phi)]$ with A = {t.get('amplitude_ms')} m\\,s$^{{-1}}$, "
                     f"period {t.get('period_s')} s, $\\phi$ = {t.get('phase_rad', 0.0)}")
    return f"{label.lower()}: " + ", ".join(parts)


def ablation_frame(cell_files, tier: int = 3, method: str = "heuristic") -> pd.DataFrame:
    """The forcing ablation of ``method`` at ``tier`` as data, long.

    One row per (task, condition) with a cell, then per condition a ``Macro`` row. Information and
    tier-override ablation cells are left out. Conditions come from each cell's record
    (:func:`~oneocean.reporting.cells.load_cell_frames`: ``currents`` False = currents off; the
    run's ``current_gain`` g; ``tide``), ordered data-grounded, other gains (ascending), with tide,
    currents off. Columns: ``family, task, condition, condition_label, current_gain, tide, sr, lo,
    hi`` (Wilson; macro: stratified bootstrap over the hosted tasks), ``n``, ``applicable``,
    ``tasks``, ``same_episodes`` (the cell replays the data-grounded cell's episodes: equal
    ``candidate`` draws; None without a data-grounded cell to compare).

    Parameters
    ----------
    cell_files : iterable of path-like or pandas.DataFrame
        Rollout cell files, or :func:`~oneocean.reporting.cells.load_cell_frames`' rows (used as
        they are).
    tier : int, default 3
        The tier.
    method : str, default "heuristic"
        The method.

    Returns
    -------
    pandas.DataFrame
        The columns above; ``sr, lo, hi`` in %.
    """
    from .. import registry

    cells = _forcing_only(load_cell_frames(cell_files))
    cells = cells[(cells["method"] == method) & (cells["tier"] == tier)]
    conds = (cells.drop_duplicates("condition")
             .sort_values("condition_key", kind="stable")[
                 ["condition", "condition_label", "condition_key", "current_gain", "tide",
                  "currents"]])
    rows = []
    for _, c in cells.iterrows():
        sr, lo, hi = rate_ci(c["success"]) if c["applicable"] else (math.nan,) * 3
        base = cells[(cells["task"] == c["task"]) & (cells["condition"] == DATA_GROUNDED)]
        same = None
        if not base.empty and c["n"] and base["n"].iloc[0] and \
                "candidate" in c["episodes"] and "candidate" in base["episodes"].iloc[0]:
            a = c["episodes"]["candidate"].to_numpy()
            b = base["episodes"].iloc[0]["candidate"].to_numpy()
            same = bool(a.shape == b.shape and np.array_equal(a, b))
        rows.append({"family": registry.family_label(registry.task_spec(c["task"]).family),
                     "task": c["task"], "condition": c["condition"],
                     "condition_label": c["condition_label"],
                     "current_gain": float(c["current_gain"]), "tide": c["tide"],
                     "sr": sr, "lo": lo, "hi": hi, "n": int(c["n"]),
                     "applicable": bool(c["applicable"]), "tasks": 1,
                     "same_episodes": same})
    for _, cd in conds.iterrows():
        sub = cells[cells["condition"] == cd["condition"]]
        mac = macro_rate(sub, method, tier, bool(cd["currents"]))
        rows.append({"family": "", "task": "Macro", "condition": cd["condition"],
                     "condition_label": cd["condition_label"],
                     "current_gain": float(cd["current_gain"]), "tide": cd["tide"],
                     "sr": mac["sr"], "lo": mac["lo"], "hi": mac["hi"],
                     "n": int(sub["n"].sum()), "applicable": mac["tasks"] > 0,
                     "tasks": int(mac["tasks"]), "same_episodes": None})
    cols = ["family", "task", "condition", "condition_label", "current_gain", "tide", "sr",
            "lo", "hi", "n", "applicable", "tasks", "same_episodes"]
    out = pd.DataFrame(rows, columns=cols)
    out["same_episodes"] = out["same_episodes"].astype("boolean")
    out["tide"] = out["tide"].astype("string")
    return out


def ablation_latex(df: pd.DataFrame, cells: pd.DataFrame, tier: int, method: str,
                   region: str | None = None) -> str:
    """The forcing-ablation table as LaTeX: SR per task under each condition, and the macros.

    Parameters
    ----------
    df : pandas.DataFrame
        :func:`ablation_frame`'s rows.
    cells : pandas.DataFrame
        :func:`~oneocean.reporting.cells.load_cell_frames` rows (forcing conditions only), for the
        caption.
    tier : int
        The tier.
    method : str
        The method (its label is named in the caption).
    region : str, optional
        The region, named in the caption and the label.

    Returns
    -------
    str
        The ``table`` (label ``tab:ablation_<method>_t<tier>[:<region>]``).
    """
    from .. import registry

    conds = list(dict.fromkeys(df.loc[df["task"] == "Macro", "condition"]))
    labels = dict(zip(df["condition"], df["condition_label"]))
    header = ["Task"] + [f"{labels[c]} SR (\\%)" for c in conds]
    idx = df.set_index(["task", "condition"])
    tasks = [t for t in dict.fromkeys(df["task"]) if t != "Macro"]

    def line(task, fmt):
        out = [_escape(task)]
        for c in conds:
            if (task, c) not in idx.index:
                out.append("--")
                continue
            r = idx.loc[(task, c)]
            out.append(_ci(r["sr"], r["lo"], r["hi"], fmt) if r["applicable"] else "n/a")
        return out

    rows = _family_rows(tasks, {t: line(t, "{:.0f}") for t in tasks})
    if conds:
        rows += [("rule",), line("Macro", "{:.1f}")]
    macro = df[df["task"] == "Macro"]
    ntasks = dict(zip(macro["condition"], macro["tasks"]))
    uneven = len(set(ntasks.values())) > 1
    notes = []
    for c in conds:
        r = df[df["condition"] == c].iloc[0]
        tide = None if pd.isna(r["tide"]) else str(r["tide"])
        notes.append(_condition_note(c, labels[c], tide, float(r["current_gain"]))
                     + (f" (macro over {ntasks[c]} tasks)" if uneven else ""))
    same = df.loc[df["task"] != "Macro", "same_episodes"].dropna()
    replay = ""
    if len(same) and same.all():
        replay = (" Every condition replays the data-grounded cells' episodes (the same "
                  "accepted candidate draws; checked).")
    elif len(same):
        bad = df.loc[(df["task"] != "Macro") & (df["same_episodes"] == False), "task"]  # noqa: E712
        replay = (" Episodes differ from the data-grounded cell's for "
                  + ", ".join(dict.fromkeys(bad)) + ".")
    label = registry.method_spec(method).label
    caption = (
        _protocol(cells[(cells["method"] == method) & (cells["tier"] == tier)], region,
                  f"Forcing ablation of the {_escape(label.lower())} method at Tier {tier}")
        + " Conditions: " + "; ".join(notes) + ". Success rate with its Wilson 95\\% "
        "interval; Macro: the unweighted mean over the tasks the region hosts, "
        "stratified-bootstrap 95\\% interval." + replay
        + _na_note(cells[(cells["method"] == method) & (cells["tier"] == tier)]))
    return booktabs(header, rows, caption, _label(f"tab:ablation_{method}_t{tier}", region))


def ablation_table(cell_files, out_tex, tier: int = 3, method: str = "heuristic",
                   region: str | None = None) -> pd.DataFrame:
    """Write the forcing-ablation table and its numbers as Parquet.

    Every forcing condition with cells of ``method`` at ``tier`` is a column.

    Parameters
    ----------
    cell_files : iterable of path-like or pandas.DataFrame
        Rollout cell files, or :func:`~oneocean.reporting.cells.load_cell_frames`' rows (used as
        they are).
    out_tex : path-like
        The ``.tex`` file; the numbers go beside it as ``.parquet``.
    tier : int, default 3
        The tier.
    method : str, default "heuristic"
        The method.
    region : str, optional
        The region, named in the caption and the label.

    Returns
    -------
    pandas.DataFrame
        :func:`ablation_frame`'s rows.
    """
    cells = _forcing_only(load_cell_frames(cell_files))
    df = ablation_frame(cells, tier, method)
    _write(df, ablation_latex(df, cells, tier, method, region), out_tex,
           {"table": "ablation", "tier": int(tier), "method": method, "region": region})
    return df
