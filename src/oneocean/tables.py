"""Paper tables: LaTeX (booktabs) via pandas ``Styler.to_latex``, best value per column in bold."""

from __future__ import annotations

import json
from typing import Literal, Mapping

import pandas as pd

from .io import write_text_atomic

Best = Literal["max", "min"]


def to_booktabs(df: pd.DataFrame, caption: str, label: str,
                best: Mapping[str, Best] | None = None, precision: int = 2,
                column_format: str | None = None, na_rep: str = "--") -> str:
    """Render ``df`` as a booktabs table; columns in ``best`` get their best value in bold."""
    styler = df.style.format(precision=precision, na_rep=na_rep)
    for col, how in (best or {}).items():
        if col in df.columns and pd.api.types.is_numeric_dtype(df[col]) and df[col].notna().any():
            target = df[col].max() if how == "max" else df[col].min()
            styler = styler.apply(
                lambda s, t=target: ["font-weight: bold" if v == t else "" for v in s],
                subset=[col])
    return styler.hide(axis="index").to_latex(
        hrules=True, caption=caption, label=label, convert_css=True, position="t",
        column_format=column_format or "l" * len(df.columns))


def _escape(text: str) -> str:
    return str(text).replace("_", r"\_").replace("%", r"\%").replace("&", r"\&")


def dataset_variants_frame(metadata_files) -> pd.DataFrame:
    """One row per variant from the per-variant metadata JSON files."""
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
    df = dataset_variants_frame(metadata_files)
    tex = to_booktabs(
        df.assign(**{"Res. (deg)": df["Res. (deg)"].map(lambda r: f"{r:.4f}")}),
        caption="Dataset variants of the ocean-environment product (same schema; extent, "
                "resolution, time coverage and depth differ). Speeds are surface ocean currents; "
                "the last speed column adds the tidal currents.",
        label="tab:dataset_variants", precision=3, column_format="llllllrrrrl")
    write_text_atomic(out_tex, tex)


def task_success_frame(cell_files) -> pd.DataFrame:
    """Per-task success rate (%) by method and tier from per-episode rollout tables, plus a
    macro (unweighted mean over tasks) row.

    Rows follow :func:`oneocean.registry.task_ids` (the paper's order, then registered extras)
    with the registry's family labels; columns follow the registry's method order, labelled
    with each method's ``short`` label. A task or method in the rollouts that is not
    registered is a ConfigError (never silently dropped).
    """
    from . import registry
    from .ladder import load_cells

    cells = load_cells(cell_files)
    cells = cells[cells["currents"]]          # the ablation cells have their own table
    # a cell the region cannot host is n/a (NaN), never 0 %
    hits = cells.assign(k=cells["k"].where(cells["applicable"]))
    g = hits.groupby(["task", "method", "tier"])
    sr = (g["k"].sum(min_count=1) / g["n"].sum() * 100.0).unstack(["method", "tier"])
    n = cells.groupby("task")["n_agents"].first()
    specs = {t: registry.task_spec(t) for t in sr.index}            # unknown task: error
    methods = {m: registry.method_spec(m) for m in sr.columns.get_level_values(0)}
    sr = sr.loc[[t for t in registry.task_ids() if t in specs]]
    m_order = {m: i for i, m in enumerate(registry.method_names())}
    sr = sr[sorted(sr.columns, key=lambda c: (m_order[c[0]], c[1]))]
    sr.columns = [f"{methods[m].short} T{t}" for m, t in sr.columns]
    out = sr.reset_index().rename(columns={"task": "Task"})
    out.insert(0, "Family", out["Task"].map(lambda t: registry.family_label(specs[t].family)))
    out.insert(2, "N", out["Task"].map(n).astype(int))
    macro = {"Family": "", "Task": "Macro", "N": pd.NA, **sr.mean(axis=0).to_dict()}
    return pd.concat([out, pd.DataFrame([macro])], ignore_index=True)


def task_success_table(cell_files, out_tex) -> None:
    df = task_success_frame(cell_files)
    sr_cols = [c for c in df.columns if c not in ("Family", "Task", "N")]
    body = df.copy()
    body["N"] = body["N"].map(lambda v: "" if pd.isna(v) else str(int(v)))
    tex = to_booktabs(
        body, caption="Per-task success rate (\\%) by tier (core backend, evaluation seed; "
        "episodes per cell in the manifest). n/a: the region cannot host the cell (reason in "
        "the cell file and the ladder table). Macro is the unweighted mean over the tasks "
        "the region hosts.", label="tab:task_success", precision=1,
        column_format="llr" + "r" * len(sr_cols), na_rep="n/a")
    write_text_atomic(out_tex, tex)
