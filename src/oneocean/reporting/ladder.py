"""The difficulty ladder's report: the protocol's checks and the ladder as Markdown.

:func:`run_checks` (the protocol's checks, :class:`Check`), :func:`ladder_markdown` and
:func:`write_ladder` (the ladder table per (task, tier, method) with its macros, the current
each tier met, the checks' verdicts, the replicate seeds) and :func:`splice_readme` (the
README's ladder block). Pure functions of the cell files the workflow writes
(``results/rollouts/...parquet``), read and turned into rates by :mod:`oneocean.reporting.cells`
(:func:`~oneocean.reporting.cells.load_cells`, :func:`~oneocean.reporting.cells.ladder_frame`,
:func:`~oneocean.reporting.cells.macro_rate`); the workflow's ``table_ladder`` rule writes the
Markdown, so the README's ladder table is the workflow's own output (``oneocean
ladder-readme`` splices it in).

Intervals: Wilson score interval for a rate (per cell); for a macro (the unweighted mean of the
tasks' success rates) a stratified bootstrap that resamples episodes within each task (seeded,
so the table bytes are reproducible; :mod:`oneocean.reporting.stats`). A cell the region
cannot host (``applicable: false``) has no rate: it is shown as n/a with its reason and left
out of the macros, which then say how many tasks they average.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from .cells import _data_and_off, ladder_frame, load_cells, macro_rate


@dataclass(frozen=True)
class Check:
    """One protocol check's outcome (:func:`run_checks`).

    Attributes
    ----------
    name : str
        What is checked.
    measured : str
        The measured value(s), as text.
    target : str
        The target, as text (``"reported"``: no target).
    passed : bool or None
        The verdict; None when it could not be evaluated (missing cells) or is only
        reported.
    """

    name: str
    measured: str
    target: str
    passed: bool | None   # None: could not be evaluated (missing cells), or only reported


def run_checks(cells: pd.DataFrame) -> list[Check]:
    """The protocol's checks on the evaluation cells, reported as measured.

    Heuristic Tier-2 macro SR in [60, 90] %, Tier-3 macro in [20, 50] %, heuristic SR
    non-increasing T1 -> T3 with T1 > T3 per task, oracle >= 90 % in every cell with a 95 %
    Wilson lower bound >= 80 %, the heuristic at least 10 points below the oracle at Tier 3 in
    every task (what it lacks is information); the currents-off gap of the heuristic's Tier-3
    macro is reported, not a target (``passed`` None).

    Parameters
    ----------
    cells : pandas.DataFrame
        :func:`~oneocean.reporting.cells.load_cells`' rows.

    Returns
    -------
    list of Check
        The checks, in that order.
    """
    out: list[Check] = []
    lad = ladder_frame(cells)
    h = lad[(lad["method"] == "heuristic") & lad["currents"]]
    for tier, (a, b) in ((2, (60.0, 90.0)), (3, (20.0, 50.0))):
        m = macro_rate(cells, "heuristic", tier)
        ok = None if m["tasks"] == 0 else bool(a <= m["sr"] <= b)
        out.append(Check(f"heuristic Tier-{tier} macro SR", _fmt_macro(m), f"{a:g}-{b:g} %",
                         ok))
    bad, seen = [], 0
    for task, g in h.groupby("task", sort=False):
        g = g[g["applicable"]].sort_values("tier")
        if len(g) < 2:
            continue
        seen += 1
        srs = g["sr"].to_numpy()
        if np.any(np.diff(srs) > 1e-9) or not srs[0] > srs[-1]:
            bad.append(f"{task} " + "/".join(f"{v:.0f}" for v in srs))
    out.append(Check("heuristic SR non-increasing T1->T3 per task, T1 > T3",
                     "all" if not bad else "; ".join(bad), f"{seen} tasks",
                     None if seen == 0 else not bad))
    o = lad[(lad["method"] == "oracle") & lad["currents"] & lad["applicable"]]
    if o.empty:
        out.append(Check("oracle >= 90 % and Wilson lower bound >= 80 % in every cell",
                         "no oracle cells", "every cell", None))
    else:
        fails = o[(o["sr"] < 90.0) | (o["lo"] < 80.0)]
        what = ("all" if fails.empty else "; ".join(
            f"{r.task} T{r.tier} {r.sr:.0f} [{r.lo:.0f}]" for r in fails.itertuples()))
        out.append(Check("oracle >= 90 % and Wilson lower bound >= 80 % in every cell",
                         f"{len(o) - len(fails)}/{len(o)} cells pass" + (
                             "" if fails.empty else f" (fail: {what})"), "every cell",
                         fails.empty))
    t3 = lad[lad["currents"] & lad["applicable"] & (lad["tier"] == 3)]
    pairs = t3.pivot_table(index="task", columns="method", values="sr", sort=False)
    if not {"heuristic", "oracle"} <= set(pairs.columns):
        out.append(Check("heuristic <= oracle - 10 points at Tier 3, per task",
                         "no Tier-3 cells of both", "every task", None))
    else:
        pairs = pairs.dropna(subset=["heuristic", "oracle"])
        close = pairs[pairs["heuristic"] > pairs["oracle"] - 10.0]
        what = "; ".join(f"{t} {r.heuristic:.0f} vs {r.oracle:.0f}"
                         for t, r in close.iterrows())
        out.append(Check("heuristic <= oracle - 10 points at Tier 3, per task",
                         f"{len(pairs) - len(close)}/{len(pairs)} tasks" + (
                             f" (not: {what})" if what else ""), "every task", close.empty))
    on = macro_rate(cells, "heuristic", 3, True)
    off = macro_rate(cells, "heuristic", 3, False)
    if off["tasks"] == 0 or on["tasks"] == 0:
        out.append(Check("currents off: heuristic Tier-3 macro", "no currents-off cells",
                         "reported", None))
    else:
        d = off["sr"] - on["sr"]
        out.append(Check("currents off: heuristic Tier-3 macro",
                         f"{d:+.1f} points ({on['sr']:.1f} -> {off['sr']:.1f} %)",
                         "reported", None))
    return out


def _fmt_macro(m: dict) -> str:
    if m["tasks"] == 0:
        return "n/a"
    s = f"{m['sr']:.1f} % [{m['lo']:.1f}, {m['hi']:.1f}]"
    return s + (f" over {m['tasks']} tasks ({m['na']} n/a)" if m["na"] else "")


def _fmt_cell(r) -> str:
    if not r["applicable"]:
        return "n/a"
    return f"{r['sr']:.0f} [{r['lo']:.0f}, {r['hi']:.0f}]"


def _ladder_table(cells: pd.DataFrame) -> tuple[list[str], list[str]]:
    """The ladder's Markdown table rows and its n/a notes."""
    from .. import registry

    lad = ladder_frame(cells)
    methods = [m for m in registry.method_names() if m in set(lad["method"])]
    tiers = sorted(set(lad["tier"]))
    order = [t for t in registry.task_ids() if t in set(lad["task"])]
    cols = [(m, t, True) for m in methods for t in tiers]
    off_tiers = sorted(set(lad.loc[~lad["currents"], "tier"]))
    cols += [(m, t, False) for m in methods for t in off_tiers
             if ((lad["method"] == m) & (lad["tier"] == t) & ~lad["currents"]).any()]
    head = ["Task", "Vehicle"] + [f"{m} T{t}" + ("" if cur else " (currents off)")
                                  for m, t, cur in cols]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    notes = []
    for task in order:
        row = [task, ""]
        for m, t, cur in cols:
            sel = lad[(lad["task"] == task) & (lad["method"] == m) & (lad["tier"] == t)
                      & (lad["currents"] == cur)]
            if sel.empty:
                row.append("")
                continue
            r = sel.iloc[0]
            row[1] = r["vehicle"] or row[1]
            row.append(_fmt_cell(r))
            if not r["applicable"]:
                notes.append(f"{task} T{t} {m}: {r['reason']}")
        lines.append("| " + " | ".join(row) + " |")
    macro = ["Macro", ""]
    for m, t, cur in cols:
        macro.append(_fmt_macro(macro_rate(cells, m, t, cur)))
    lines.append("| " + " | ".join(macro) + " |")
    return lines, notes


def current_markdown(cells: pd.DataFrame, method: str = "heuristic") -> list[str]:
    """Each tier's current in absolute terms, as Markdown table lines.

    Per task and tier, the median [10th, 90th percentile] over ``method``'s episodes of the
    true current speed the agents met (m/s, mean over agents and steps) and the median as a
    percentage of the vehicle's speed limit.

    Parameters
    ----------
    cells : pandas.DataFrame
        :func:`~oneocean.reporting.cells.load_cells`' rows (data-current cells with a ``current``
        array are used).
    method : str, default "heuristic"
        The method whose episodes are summarised.

    Returns
    -------
    list of str
        The table's lines; empty without such cells.
    """
    from .. import registry
    from ..engine.dynamics import load_vehicle

    sel = _data_and_off(cells)
    sel = sel[(sel["method"] == method) & sel["currents"] & sel["applicable"]]
    sel = sel[sel["current"].map(len) > 0] if "current" in sel else sel.iloc[0:0]
    if sel.empty:
        return []
    tiers = sorted(set(sel["tier"]))
    vmax: dict[str, float] = {}
    lines = ["| Task | Vehicle (speed limit) | " + " | ".join(f"T{t}" for t in tiers) + " |",
             "|" + "---|" * (len(tiers) + 2)]
    for task in [t for t in registry.task_ids() if t in set(sel["task"])]:
        g = sel[sel["task"] == task]
        veh = str(g["vehicle"].iloc[0])
        if veh and veh not in vmax:
            vmax[veh] = load_vehicle(veh).v_max
        vm = vmax.get(veh, math.nan)
        row = [task, f"{veh} ({vm:.2f} m/s)" if veh else ""]
        for t in tiers:
            c = g[g["tier"] == t]
            if c.empty:
                row.append("")
                continue
            v = c["current"].iloc[0]
            med, p10, p90 = (float(x) for x in np.quantile(v, [0.5, 0.1, 0.9]))
            row.append(f"{med:.2f} [{p10:.2f}, {p90:.2f}] m/s, {100.0 * med / vm:.0f} %")
        lines.append("| " + " | ".join(row) + " |")
    return lines


def _check_lines(cells: pd.DataFrame, skip_missing: bool = False) -> list[str]:
    """The checks' Markdown table (``skip_missing``: leave out checks without cells)."""
    out = ["| Check | Measured | Target | Verdict |", "|---|---|---|---|"]
    for c in run_checks(cells):
        if skip_missing and c.passed is None and c.measured.startswith("no "):
            continue
        v = (("reported" if c.target == "reported" else "n/a") if c.passed is None
             else ("pass" if c.passed else "FAIL"))
        out.append(f"| {c.name} | {c.measured} | {c.target} | {v} |")
    return out


def ladder_markdown(cells: pd.DataFrame, region: str, seed: int | None = None,
                    replicate: pd.DataFrame | None = None) -> str:
    """The ladder as Markdown: the table, the n/a reasons and the checks' verdicts.

    The table gives SR % [95 % Wilson CI] per task x tier x method and macro rows with
    bootstrap intervals. Then, per replicate seed (``replicate``: cells of other held-out
    seeds), the same table and checks of its methods and the macro's change from the
    evaluation seed.

    Parameters
    ----------
    cells : pandas.DataFrame
        :func:`~oneocean.reporting.cells.load_cells`' rows of the evaluation seed.
    region : str
        The region's name, for the heading line.
    seed : int, optional
        The evaluation seed, for the text.
    replicate : pandas.DataFrame, optional
        :func:`~oneocean.reporting.cells.load_cells`' rows of the replicate seeds.

    Returns
    -------
    str
        The Markdown, ending with a newline.
    """
    lines, notes = _ladder_table(cells)
    out = [f"Region `{region}`" + (f", evaluation seed {seed}" if seed is not None else "")
           + ": success rate % [95 % CI] (Wilson per cell; macro: stratified bootstrap).", "",
           *lines, ""]
    if notes:
        out += ["Not applicable in this region:", ""] + [f"- {n}" for n in sorted(set(notes))]
        out.append("")
    cur = current_markdown(cells)
    if cur:
        out += ["The current each tier's episodes met (heuristic cells): median [10th, 90th "
                "percentile] of the true current speed at the agents, m/s, and the median as a "
                "share of the vehicle's speed limit.", "", *cur, ""]
    out += _check_lines(cells)
    if replicate is not None and len(replicate):
        for rs in sorted(set(int(x) for x in replicate["seed"].dropna())):
            rep = replicate[replicate["seed"] == rs]
            lines, _ = _ladder_table(rep)
            out += ["", f"Replicate: the same ladder on held-out seed {rs} (other episodes, "
                    "the same tiers): success rate % [95 % CI].", "", *lines, ""]
            out += _check_lines(rep, skip_missing=True)
            diffs = []
            for m in sorted(set(rep["method"])):
                for t in sorted(set(rep["tier"])):
                    a = macro_rate(cells, m, t)
                    b = macro_rate(rep, m, t)
                    if a["tasks"] and b["tasks"]:
                        diffs.append(f"{m} T{t} {a['sr']:.1f} -> {b['sr']:.1f} "
                                     f"({b['sr'] - a['sr']:+.1f})")
            if diffs:
                out += ["", f"Macro SR, seed {seed} -> seed {rs}: " + "; ".join(diffs) + "."]
    return "\n".join(out) + "\n"


def write_ladder(cell_files, out_md, region: str, seed: int | None = None,
                 replicate=()) -> None:
    """Write :func:`ladder_markdown` of the cell files atomically (the ``table_ladder`` rule).

    Parameters
    ----------
    cell_files : iterable of path-like
        The evaluation seed's cell files.
    out_md : path-like
        The Markdown file (``results/tables/<region>/ladder.md``).
    region : str
        The region's name.
    seed : int, optional
        The evaluation seed, for the text.
    replicate : sequence of path-like, default ()
        The replicate seeds' cell files.
    """
    from ..io import write_text_atomic

    rep = load_cells(list(replicate)) if len(replicate) else None
    write_text_atomic(out_md, ladder_markdown(load_cells(list(cell_files)), region, seed,
                                              rep))


def readme_markers(region: str) -> tuple[str, str]:
    """The HTML comments that delimit a region's ladder block in the README.

    Parameters
    ----------
    region : str
        The region's name.

    Returns
    -------
    tuple of str
        ``(begin, end)`` marker lines.
    """
    return (f"<!-- ladder:{region}:begin (generated: oneocean ladder-readme) -->",
            f"<!-- ladder:{region}:end -->")


def splice_readme(readme, ladder_md, region: str) -> bool:
    """Replace a region's ladder block in the README with the workflow's ladder table.

    Parameters
    ----------
    readme : path-like
        The Markdown file holding the block between :func:`readme_markers` of ``region``;
        rewritten atomically only if it changes.
    ladder_md : path-like
        The workflow's ``results/tables/<region>/ladder.md``.
    region : str
        The region's name.

    Returns
    -------
    bool
        True if the README changed.

    Raises
    ------
    ConfigError
        If the README has no block for ``region`` or ``ladder_md`` does not exist.
    """
    from ..errors import ConfigError
    from ..io import write_text_atomic
    from pathlib import Path

    readme, ladder_md = Path(readme), Path(ladder_md)
    text = readme.read_text()
    begin, end = readme_markers(region)
    if begin not in text or end not in text:
        raise ConfigError(f"{readme}: no ladder block for region {region!r} (add the lines "
                          f"{begin!r} and {end!r})")
    if not ladder_md.is_file():
        raise ConfigError(f"{ladder_md}: not found (run snakemake {ladder_md} first)")
    head, rest = text.split(begin, 1)
    _, tail = rest.split(end, 1)
    new = head + begin + "\n" + ladder_md.read_text().rstrip("\n") + "\n" + end + tail
    if new != text:
        write_text_atomic(readme, new)
    return new != text
