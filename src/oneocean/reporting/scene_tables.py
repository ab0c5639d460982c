"""The scene backend's tables: Table VII (per scene, Tier 2 and 3) and core vs scene.

Inputs are the cell files of the workflow's ``scene_cells`` jobs
(``results/scene_rollouts/<region>/<variant>/<scene>/<backend>/<task>/tier<k>/<method>.parquet``),
each recording its backend, scene and the scene's metadata.

Table VII (``scene_backend.tex``) follows the paper's shape for route following (RF): per
scene and tier, the success rate with its Wilson 95 % interval, the waypoints reached (% of the
route's waypoints, mean over episodes) and the mean cross-track error (m), then the mean over
scenes with every scene weighted equally. Success is the task's own rule, the same as the
core's: every waypoint in order, a mean cross-track error within ``xte_max_m`` and the energy
allocation; the column "all WP" gives the paper's scene-table rule (every waypoint reached,
no cross-track or energy bound). ``scene_vs_core.tex`` sets the two backends side by side on
the compare scene (same tasks, tiers, methods, seed and episodes: the same scenarios), so a
difference is the execution substrate's. ``scene_backend.md`` holds both plus every scene's
success rate per task, tier and method.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from ..io import write_text_atomic
from .cells import read_cell
from .latex import booktabs
from .stats import finite_mean, rate_ci
from .tables import _ci, _escape, _num

#: The scene table's task (the paper's Table VII: route following).
TABLE7_TASK = "RF"


def load_scene_cells(cell_files) -> pd.DataFrame:
    """Read scene cell files into one row per file (:func:`oneocean.reporting.cells.read_cell`).

    Parameters
    ----------
    cell_files : iterable of path-like
        The ``scene_cells`` jobs' Parquet files.

    Returns
    -------
    pandas.DataFrame
        ``scene`` (from the record, else the path), ``label`` (:func:`short_label`),
        ``backend`` (``core`` or ``mujoco``), ``task, tier, method, applicable, reason``,
        ``n`` (episodes), ``success`` (bool array), ``episodes`` (the per-episode
        DataFrame), ``n_waypoints`` (the tier's, None if it has none) and ``file``.
    """
    rows = []
    for f in cell_files:
        df, c = read_cell(f)
        meta = c["meta"]
        rows.append({"scene": meta.get("scene", Path(f).parts[-5]),
                     "label": short_label(meta.get("scene_meta") or {}, meta.get("scene", "")),
                     "backend": meta.get("backend", "core"),
                     **{k: c[k] for k in ("task", "tier", "method", "applicable", "reason")},
                     "n": int(len(df)), "success": df["success"].to_numpy(dtype=bool),
                     "episodes": df,
                     "n_waypoints": (meta.get("tier_params") or {}).get("n_waypoints"),
                     "file": str(f)})
    return pd.DataFrame(rows)


#: Short names of the scene kinds in tables (the stand-ins of the paper's scenes).
KIND_NAMES = {"dam": "Dam", "open_water": "OpenWater", "pier_harbor": "PierHarbor",
              "simple_underwater": "SimpleUnderwater"}


def short_label(scene_meta: dict, name: str) -> str:
    """The ``"Dam*"``-style table label of a scene (``*``: a stand-in, said in the caption).

    Parameters
    ----------
    scene_meta : dict
        The scene's metadata (its ``kind`` is looked up in :data:`KIND_NAMES`).
    name : str
        The scene's name; added in parentheses when it differs from its kind.

    Returns
    -------
    str
        The label, e.g. ``"Dam*"`` or ``"Dam* (<name>)"``.
    """
    kind = scene_meta.get("kind", "")
    base = KIND_NAMES.get(kind, name) + "*"
    return base if name in ("", kind) else f"{base} ({name})"


def table7_frame(cells: pd.DataFrame, method: str = "heuristic",
                 task: str = TABLE7_TASK) -> pd.DataFrame:
    """Table VII as data: one row per scene and tier (MuJoCo backend), then the means.

    Parameters
    ----------
    cells : pandas.DataFrame
        :func:`load_scene_cells`' rows.
    method : str, default "heuristic"
        The method.
    task : str, default ``TABLE7_TASK``
        The task (route following, ``"RF"``).

    Returns
    -------
    pandas.DataFrame
        ``scene, label, tier, n, sr, sr_lo, sr_hi`` (%, Wilson 95 %), ``wp_pct`` (waypoints
        reached, % of the route, mean over episodes), ``all_wp_pct`` (% of episodes reaching
        every waypoint), ``cte_m`` (mean of the primary metric: for RF the mean cross-track
        error, m), ``contact_pct`` (% of episodes with a violation: a MuJoCo contact with a
        structure or the seafloor, or the boundary band), ``viol`` (violation steps per
        episode), ``reason``; then per tier one ``scene = "mean"`` row (each hosted scene
        weighted equally, no interval) and, with two or more scenes, one ``scene = "spread"``
        row: ``sr`` = the highest scene's success minus the lowest's (points), ``reason`` =
        ``"<highest> - <lowest>"`` (tied scenes joined with ``/``). Empty without such cells.
    """
    sel = cells[(cells["backend"] == "mujoco") & (cells["task"] == task)
                & (cells["method"] == method)]
    rows = []
    for (scene, tier), g in sel.groupby(["scene", "tier"], sort=False):
        c = g.iloc[0]
        ep = c["episodes"]
        if not c["applicable"] or c["n"] == 0:
            rows.append({"scene": scene, "label": c["label"], "tier": tier, "n": 0,
                         "sr": math.nan, "sr_lo": math.nan, "sr_hi": math.nan,
                         "wp_pct": math.nan, "all_wp_pct": math.nan, "cte_m": math.nan,
                         "contact_pct": math.nan, "viol": math.nan, "reason": c["reason"]})
            continue
        sr, lo, hi = rate_ci(c["success"])
        if "waypoints_reached" in ep and c["n_waypoints"]:
            nwp = float(c["n_waypoints"])
            wp = ep["waypoints_reached"].to_numpy(dtype=float)
            wp_pct, all_wp = 100.0 * finite_mean(wp / nwp), 100.0 * float(np.mean(wp >= nwp))
        else:
            wp_pct = all_wp = math.nan
        rows.append({"scene": scene, "label": c["label"], "tier": tier, "n": int(c["n"]),
                     "sr": sr, "sr_lo": lo, "sr_hi": hi, "wp_pct": wp_pct,
                     "all_wp_pct": all_wp, "cte_m": finite_mean(ep["primary"]),
                     "contact_pct": 100.0 * float(np.mean(ep["violations"].to_numpy() > 0)),
                     "viol": finite_mean(ep["violations"]), "reason": ""})
    out = pd.DataFrame(rows)
    if out.empty:
        return out
    means = []
    for tier, g in out.groupby("tier", sort=True):
        ok = g[g["n"] > 0]
        means.append({"scene": "mean", "label": "Mean over scenes", "tier": tier,
                      "n": int(ok["n"].sum()), "sr": finite_mean(ok["sr"]), "sr_lo": math.nan,
                      "sr_hi": math.nan, "wp_pct": finite_mean(ok["wp_pct"]),
                      "all_wp_pct": finite_mean(ok["all_wp_pct"]),
                      "cte_m": finite_mean(ok["cte_m"]),
                      "contact_pct": finite_mean(ok["contact_pct"]),
                      "viol": finite_mean(ok["viol"]), "reason": ""})
        if len(ok) >= 2:      # the spread between scenes: max - min success, scenes named
            hi_v, lo_v = float(ok["sr"].max()), float(ok["sr"].min())
            hi_n = "/".join(ok.loc[ok["sr"] == hi_v, "label"])   # ties: every scene named
            lo_n = "/".join(ok.loc[ok["sr"] == lo_v, "label"])
            means.append({"scene": "spread", "label": "Spread (max - min)", "tier": tier,
                          "n": int(ok["n"].sum()), "sr": hi_v - lo_v,
                          "sr_lo": math.nan, "sr_hi": math.nan, "wp_pct": math.nan,
                          "all_wp_pct": math.nan, "cte_m": math.nan, "contact_pct": math.nan,
                          "viol": math.nan,
                          "reason": f"{hi_n} - {lo_n}"})
    return pd.concat([out, pd.DataFrame(means)], ignore_index=True)


def table7_latex(df: pd.DataFrame, region: str, method: str, episodes: str,
                 task: str = TABLE7_TASK) -> str:
    """Table VII as LaTeX.

    Parameters
    ----------
    df : pandas.DataFrame
        :func:`table7_frame`'s rows.
    region : str
        The region, named in the caption and the label.
    method : str
        The method, named in the caption.
    episodes : str
        Episode counts for the caption, e.g. ``"50 episodes per cell"``.
    task : str, default ``TABLE7_TASK``
        The task; another than RF has no waypoint columns and its primary metric last.

    Returns
    -------
    str
        The ``table*`` (label ``tab:scene_backend:<region>``).
    """
    from ..registry import task_spec

    tiers = sorted(df["tier"].unique())
    prim = "CTE (m)" if task == TABLE7_TASK else _escape(str(task_spec(task).metrics[0]))
    header = ["Scene"] + [f"T{k} {h}" for k in tiers for h in ("SR (\\%)", "WP (\\%)",
                                                              "all WP (\\%)", prim,
                                                              "contact (\\%)")]
    rows = []
    for scene in dict.fromkeys(df["scene"]):
        g = df[df["scene"] == scene]
        label = g["label"].iloc[0]
        r = [_escape(label)]
        for k in tiers:
            c = g[g["tier"] == k]
            if c.empty or (c["n"].iloc[0] == 0 and scene not in ("mean", "spread")):
                r += ["n/a"] * 5
                continue
            c = c.iloc[0]
            if scene == "spread":
                r += [_num(c["sr"], "{:.1f}"), _escape(c["reason"]), "", "", ""]
                continue
            sr = (_num(c["sr"], "{:.1f}") if scene == "mean"
                  else _ci(c["sr"], c["sr_lo"], c["sr_hi"]))
            r += [sr, _num(c["wp_pct"], "{:.1f}"), _num(c["all_wp_pct"], "{:.1f}"),
                  _num(c["cte_m"], "{:.2f}"), _num(c["contact_pct"], "{:.1f}")]
        if scene == "mean":
            rows.append(("rule",))
        rows.append(r)
    what = ("route following" if task == TABLE7_TASK else
            f"{_escape(task_spec(task).label)} ({task}; no route-following cells: WP columns "
            f"n/a, last column its primary metric)")
    caption = (f"Scene backend (MuJoCo; *: stand-ins for the paper's packaged scenes), "
               f"{what} with the {_escape(method)} method, region {_escape(region)} "
               f"({episodes}). SR: the task's own success rule, as on the core (every waypoint "
               f"in order, mean cross-track error within its bound, within the energy "
               f"allocation), with its Wilson 95\\% interval; WP: waypoints reached (\\% of the "
               f"route); all WP: episodes reaching every waypoint (the paper's scene-table "
               f"rule); CTE: mean cross-track error; contact: episodes with a violation (a "
               f"MuJoCo contact with a structure or the seafloor, or the boundary band). The "
               f"routes are drawn on each scene's structures (over the dam's spillway crest, "
               f"beside the piers, along the basin walls; open water: anywhere). The mean "
               f"weights every scene equally; the spread is the highest scene's SR minus the "
               f"lowest's (points), the two scenes named.")
    return booktabs(header, rows, caption, f"tab:scene_backend:{region}", wide=True)


def compare_frame(cells: pd.DataFrame, scene: str) -> pd.DataFrame:
    """Core vs MuJoCo on one scene as data: one row per task, tier, method and backend.

    Parameters
    ----------
    cells : pandas.DataFrame
        :func:`load_scene_cells`' rows.
    scene : str
        The compare scene's name.

    Returns
    -------
    pandas.DataFrame
        ``task, tier, method, backend, n, sr, sr_lo, sr_hi`` (%, Wilson 95 %) and means over
        episodes of ``primary`` (the task's primary metric), ``T_s`` (s), ``E`` (team energy
        proxy, m2 s-1) and ``violations`` (per episode); NaN for a cell without episodes.
    """
    sel = cells[cells["scene"] == scene]
    rows = []
    for (task, tier, method, backend), g in sel.groupby(["task", "tier", "method", "backend"],
                                                        sort=False):
        c = g.iloc[0]
        ep = c["episodes"]
        if not c["applicable"] or c["n"] == 0:
            rows.append({"task": task, "tier": tier, "method": method, "backend": backend,
                         "n": 0, "sr": math.nan, "sr_lo": math.nan, "sr_hi": math.nan,
                         "primary": math.nan, "T_s": math.nan, "E": math.nan,
                         "violations": math.nan})
            continue
        sr, lo, hi = rate_ci(c["success"])
        rows.append({"task": task, "tier": tier, "method": method, "backend": backend,
                     "n": int(c["n"]), "sr": sr, "sr_lo": lo, "sr_hi": hi,
                     "primary": finite_mean(ep["primary"]), "T_s": finite_mean(ep["T_s"]),
                     "E": finite_mean(ep["E"]), "violations": finite_mean(ep["violations"])})
    return pd.DataFrame(rows)


def compare_latex(df: pd.DataFrame, region: str, scene: str, label: str, episodes: str) -> str:
    """The core-vs-scene table as LaTeX.

    Parameters
    ----------
    df : pandas.DataFrame
        :func:`compare_frame`'s rows.
    region : str
        The region, named in the caption and the label.
    scene : str
        The compare scene's name (not shown: the caption names ``label``).
    label : str
        The scene's table label (:func:`short_label`).
    episodes : str
        Episode counts for the caption.

    Returns
    -------
    str
        The ``table*`` (label ``tab:scene_vs_core:<region>``).
    """
    from ..registry import task_spec

    header = ["Task (primary metric)", "Tier", "Method", "Core SR (\\%)", "Scene SR (\\%)", "Core primary",
              "Scene primary", "Core contacts / rejections", "Scene contacts"]
    rows = []
    # no compare cells (a frame without columns): a table without rows
    keys = (list(dict.fromkeys(zip(df["task"], df["tier"], df["method"])))
            if "task" in df.columns else [])
    for task, tier, method in keys:
        g = df[(df["task"] == task) & (df["tier"] == tier) & (df["method"] == method)]
        by = {b: g[g["backend"] == b].iloc[0] for b in ("core", "mujoco")
              if (g["backend"] == b).any()}
        core, mj = by.get("core"), by.get("mujoco")

        def sr(c):
            return "--" if c is None or c["n"] == 0 else _ci(c["sr"], c["sr_lo"], c["sr_hi"])

        def val(c, k, fmt="{:.2f}"):
            return "--" if c is None or c["n"] == 0 else _num(c[k], fmt)

        prim = _escape(str(task_spec(task).metrics[0]))
        rows.append([f"{task} ({prim})", f"T{tier}", _escape(method), sr(core), sr(mj),
                     val(core, "primary"), val(mj, "primary"), val(core, "violations", "{:.1f}"),
                     val(mj, "violations", "{:.1f}")])
    caption = (f"Core vs scene backend on the same scene ({_escape(label)}), region "
               f"{_escape(region)} ({episodes}): the same episodes (scenario and seed), the same "
               f"judge and metrics; only the physics differs (the core's rigid-body model with "
               f"its feasibility check vs MuJoCo rigid bodies with fluid forces and physical "
               f"contacts). Primary: the task's primary metric, mean over episodes; contacts "
               f"and rejections: mean per episode.")
    return booktabs(header, rows, caption, f"tab:scene_vs_core:{region}", wide=True)


def _episodes_text(cells: pd.DataFrame) -> str:
    ns = sorted(set(cells.loc[cells["n"] > 0, "n"]))
    return (f"{ns[0]} episodes per cell" if len(ns) == 1 else
            f"{ns[0]}--{ns[-1]} episodes per cell" if ns else "no episodes")


def write_scene_tables(cell_files, out_tex, out_compare, out_md, region: str,
                       compare: str, method: str = "heuristic") -> None:
    """Write Table VII, the core-vs-scene table and the Markdown summary (atomically).

    Table VII is of RF if the cells have it, else of their first task.

    Parameters
    ----------
    cell_files : iterable of path-like
        The ``scene_cells`` jobs' Parquet files.
    out_tex : path-like
        Table VII (``scene_backend.tex``).
    out_compare : path-like
        The core-vs-scene table (``scene_vs_core.tex``).
    out_md : path-like
        The Markdown summary (``scene_backend.md``, :func:`scene_markdown`).
    region : str
        The region.
    compare : str
        The scene run on both backends.
    method : str, default "heuristic"
        Table VII's method.
    """
    cells = load_scene_cells(cell_files)
    eps = _episodes_text(cells)
    tasks = list(dict.fromkeys(cells["task"])) if len(cells) else []
    task = TABLE7_TASK if TABLE7_TASK in tasks else (tasks[0] if tasks else TABLE7_TASK)
    t7 = table7_frame(cells, method, task)
    write_text_atomic(out_tex, table7_latex(t7, region, method, eps, task) if not t7.empty
                      else "% no scene cells of the method\n")
    cmp_df = compare_frame(cells, compare)
    label = next(iter(cells.loc[cells["scene"] == compare, "label"]), compare)
    write_text_atomic(out_compare, compare_latex(cmp_df, region, compare, label, eps))
    write_text_atomic(out_md, scene_markdown(cells, t7, cmp_df, region, compare, method, eps,
                                             task))


def scene_markdown(cells, t7, cmp_df, region, compare, method, eps,
                   task: str = TABLE7_TASK) -> str:
    """The scene backend's Markdown summary.

    Table VII, every MuJoCo cell's success rate per scene, task, tier and method, and the
    core-vs-scene comparison.

    Parameters
    ----------
    cells : pandas.DataFrame
        :func:`load_scene_cells`' rows.
    t7 : pandas.DataFrame
        :func:`table7_frame`'s rows.
    cmp_df : pandas.DataFrame
        :func:`compare_frame`'s rows.
    region : str
        The region, in the heading.
    compare : str
        The compare scene's name.
    method : str
        Table VII's method.
    eps : str
        Episode counts for the text.
    task : str, default ``TABLE7_TASK``
        Table VII's task.

    Returns
    -------
    str
        The Markdown, ending with a newline.
    """
    lines = [f"# Scene backend: {region}", "",
             f"MuJoCo scenes (*: stand-ins for the paper's packaged scenes), {eps}. Success is "
             "each task's own rule, the same as on the core; violations are contacts with the "
             "seafloor or a structure and entries into the scene's boundary band (the core: "
             "rejected moves).", "",
             f"## {task} per scene ({method})", "",
             "| Scene | Tier | SR % [95 % CI] | WP % | all WP % | "
             + ("CTE m" if task == TABLE7_TASK else "primary")
             + " | contact % | violations / ep |", "|---|---|---|---|---|---|---|---|"]
    for _, r in t7.iterrows():
        if r["scene"] == "spread":
            lines.append(f"| {r['label']} | {r['tier']} | {_num(r['sr'], '{:.1f}')} "
                         f"({r['reason']}) | | | | | |")
            continue
        sr = (_num(r["sr"], "{:.1f}") if r["scene"] == "mean"
              else _ci(r["sr"], r["sr_lo"], r["sr_hi"]))
        lines.append(f"| {r['label']} | {r['tier']} | {sr} | {_num(r['wp_pct'], '{:.1f}')} | "
                     f"{_num(r['all_wp_pct'], '{:.1f}')} | {_num(r['cte_m'], '{:.2f}')} | "
                     f"{_num(r['contact_pct'], '{:.1f}')} | {_num(r['viol'], '{:.1f}')} |")
    lines += ["", "## Success rate per scene, task, tier and method (MuJoCo)", "",
              "| Scene | Task | Tier | Method | SR % [95 % CI] | n |", "|---|---|---|---|---|---|"]
    mj = cells[cells["backend"] == "mujoco"]
    for _, c in mj.iterrows():
        txt = (_ci(*rate_ci(c["success"])) if c["n"] else f"n/a ({c['reason']})")
        lines.append(f"| {c['label']} | {c['task']} | {c['tier']} | {c['method']} | {txt} | "
                     f"{c['n']} |")
    lines += ["", f"## Core vs scene on {compare} (the same episodes)", "",
              "| Task | Tier | Method | core SR % [95 % CI] | scene SR % [95 % CI] | core primary | "
              "scene primary | core T s | scene T s | core violations | scene violations |",
              "|---|---|---|---|---|---|---|---|---|---|---|"]
    keys = list(dict.fromkeys(zip(cmp_df["task"], cmp_df["tier"], cmp_df["method"])))
    for t_, k_, m_ in keys:
        g = cmp_df[(cmp_df["task"] == t_) & (cmp_df["tier"] == k_) & (cmp_df["method"] == m_)]
        by = {b: g[g["backend"] == b].iloc[0] for b in ("core", "mujoco")
              if (g["backend"] == b).any()}
        row = []
        for k, fmt in (("sr", None), ("primary", "{:.2f}"), ("T_s", "{:.0f}"),
                       ("violations", "{:.1f}")):
            for b in ("core", "mujoco"):
                r = by.get(b)
                if r is None or r["n"] == 0:
                    row.append("n/a")
                elif fmt is None:
                    row.append(_ci(r["sr"], r["sr_lo"], r["sr_hi"]))
                else:
                    row.append(_num(r[k], fmt))
        lines.append(f"| {t_} | {k_} | {m_} | " + " | ".join(row) + " |")
    return "\n".join(lines) + "\n"
