"""The paper's tables (oneocean.reporting.tables) against the cell files they come from: rates and their
Wilson bounds, seeded bootstraps (deterministic, bracketing), n/a cells, bold best values,
macros over the hosted tasks only, forcing conditions read from each cell's record."""

from __future__ import annotations

import glob
import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from oneocean.reporting import cells as C
from oneocean.reporting import stats as S
from oneocean.reporting import tables as T
from oneocean.engine.recording import read_metrics_meta, write_metrics
from oneocean.errors import ConfigError
from oneocean.reporting.cells import load_cells, macro_rate
from oneocean.reporting.stats import stratified_macro, wilson

#: Each synthetic task's metric column and team size.
METRIC = {"G2G": "final_error_m", "SK": "rms_error_m", "RF": "cross_track_error_m",
          "AS": "coverage_fraction", "PI": "inspection_score", "SPC": "cleanup_rate",
          "FH": "containment_success"}
AGENTS = {"G2G": 1, "SK": 1, "RF": 1, "AS": 1, "PI": 1, "SPC": 10, "FH": 8}
N_EP = 10
TIDE = {"amplitude_ms": 0.5, "period_s": 44712.0, "phase_rad": 0.0}


def write_cell(path, task, tier, method, success, *, currents=True, gain=1.0, tide=None,
               applicable=True, seed=1000, rng=None, candidate=None, tier_gain=None):
    """A cell file as ``oneocean.tasks.rollout_to_file`` writes it (standard columns, the
    task's metric, its record); ``applicable=False``: zero rows. Returns the frame."""
    rng = rng or np.random.default_rng(0)
    success = np.asarray(success, dtype=bool) if applicable else np.zeros(0, dtype=bool)
    n = success.size
    metric = rng.uniform(0.2, 1.0, n)
    if task == "SK":                 # NaN where the vehicle never held station
        metric = np.where(success, metric, np.nan)
    df = pd.DataFrame({
        "task": [task] * n, "tier": np.full(n, tier, np.int64),
        "method": [method] * n, "n_agents": np.full(n, AGENTS[task], np.int64),
        "currents": np.full(n, currents, bool), "episode": np.arange(n, dtype=np.int64),
        "seed": np.full(n, seed, np.int64),
        "candidate": (np.arange(n, dtype=np.int64) * 3 if candidate is None
                      else np.asarray(candidate, np.int64)),
        "success": success, "T_s": rng.uniform(100.0, 900.0, n),
        "E": rng.uniform(1000.0, 5000.0, n) * AGENTS[task],
        "coll_ratio": (rng.uniform(0.0, 0.1, n) if AGENTS[task] > 1 else np.zeros(n)),
        "violations": np.zeros(n, np.int64), "primary": metric, METRIC[task]: metric})
    tier_params = {"time_limit_s": 900}
    if tier_gain is not None:
        tier_params["current_gain"] = tier_gain
    meta = {"task": task, "tier": int(tier), "method": method, "dynamics": "6dof",
            "vehicle": "remus100", "n_agents": AGENTS[task], "episodes": N_EP, "seed": seed,
            "current_gain": gain * (tier_gain or 1.0), "tide": tide, "currents": currents,
            "tier_params": tier_params, "applicable": bool(applicable),
            "reason": "" if applicable else f"{task} tier {tier}: no such shelf"}
    write_metrics(df, path, meta=meta)
    return df


@pytest.fixture(scope="module")
def region(tmp_path_factory):
    """A small region: 7 tasks; heuristic at tiers 1-3, oracle and bc at tiers 2-3; AS not
    hostable at tiers 2-3; the heuristic's Tier-3 forcing ablation: currents off for every
    task, doubled currents for two tasks, a synthetic tide for one."""
    root = tmp_path_factory.mktemp("cells")
    rng = np.random.default_rng(7)
    files, frames = [], {}
    p = {"heuristic": {1: 0.95, 2: 0.7, 3: 0.4}, "oracle": {2: 1.0, 3: 0.95},
         "bc": {2: 0.5, 3: 0.3}}
    for task in METRIC:
        for method, tiers in p.items():
            for tier, q in tiers.items():
                f = root / f"{task}_{method}_t{tier}.parquet"
                ok = not (task == "AS" and tier >= 2)
                frames[(task, tier, method, "data-grounded")] = write_cell(
                    f, task, tier, method, rng.random(N_EP) < q, applicable=ok, rng=rng)
                files.append(f)
        f = root / f"{task}_heuristic_t3_off.parquet"
        frames[(task, 3, "heuristic", "currents-off")] = write_cell(
            f, task, 3, "heuristic", rng.random(N_EP) < 0.9, currents=False,
            applicable=task != "AS", rng=rng)
        files.append(f)
    for task in ("SK", "SPC"):
        f = root / f"{task}_heuristic_t3_x2.parquet"
        frames[(task, 3, "heuristic", "gain-2")] = write_cell(
            f, task, 3, "heuristic", rng.random(N_EP) < 0.2, gain=2.0, rng=rng)
        files.append(f)
    f = root / "FH_heuristic_t3_tide.parquet"
    frames[("FH", 3, "heuristic", "tide")] = write_cell(
        f, "FH", 3, "heuristic", rng.random(N_EP) < 0.3, tide=TIDE, rng=rng)
    files.append(f)
    return files, frames


def _pct_wilson(s):
    lo, hi = wilson(int(np.sum(s)), len(s))
    return 100.0 * np.mean(s), 100.0 * lo, 100.0 * hi


# ------------------------------------------------------------------------------ cells

def test_cells_identity_conditions_and_order(region, tmp_path):
    files, _ = region
    cells = C.load_cell_frames(files)
    assert len(cells) == len(files)
    got = cells.groupby("condition").size().to_dict()
    tide_id = "tide-0.5ms-44712s"
    assert got == {"data-grounded": 7 * 7, "currents-off": 7, "gain-2": 2, tide_id: 1}
    # canonical order: registry task order, then method order, tier, condition
    assert list(dict.fromkeys(cells["task"])) == ["G2G", "SK", "RF", "AS", "PI", "SPC", "FH"]
    sk3 = cells[(cells["task"] == "SK") & (cells["tier"] == 3)]
    assert list(zip(sk3["method"], sk3["condition"])) == [
        ("heuristic", "data-grounded"), ("heuristic", "gain-2"),
        ("heuristic", "currents-off"), ("oracle", "data-grounded"), ("bc", "data-grounded")]
    shuffled = C.load_cell_frames(list(reversed(files)))
    assert list(shuffled["file"]) == list(cells["file"])
    # the same columns as cells.load_cells for the same files
    lc = load_cells(files[:3])
    lf = C.load_cell_frames(files[:3])
    for col in ("task", "tier", "method", "currents", "applicable", "n", "k"):
        assert list(lc[col]) == list(lf[col]), col
    # a tier's own current gain is divided out: the run's g
    f = write_cell(tmp_path / "g.parquet", "G2G", 2, "heuristic", [1, 0], gain=1.0,
                   tier_gain=1.5)
    c = C.load_cell_frames([tmp_path / "g.parquet"]).iloc[0]
    assert c["current_gain"] == 1.0 and c["condition"] == "data-grounded"
    assert len(f) == 2


def test_cells_refuse_duplicates_and_unknown_tasks(region, tmp_path):
    files, _ = region
    dup = tmp_path / "dup.parquet"
    write_cell(dup, "G2G", 1, "heuristic", [True] * 3)
    with pytest.raises(ConfigError, match="two cell files for the same cell"):
        C.load_cell_frames(files + [dup])
    bad = tmp_path / "bad.parquet"
    pd.DataFrame({"task": ["NOPE"], "tier": [1], "method": ["heuristic"], "n_agents": [1],
                  "success": [True]}).to_parquet(bad)
    with pytest.raises(ConfigError, match="'NOPE'"):
        T.task_success_ci_frame([bad])


# ------------------------------------------------------------------------------ intervals

def test_bootstraps_are_seeded_and_bracket_the_estimate():
    rng = np.random.default_rng(3)
    x = rng.normal(5.0, 2.0, 40)
    assert S.mean_ci(x) == S.mean_ci(x) != S.mean_ci(x, seed=1)   # seeded: its own seed
    m, lo, hi = S.mean_ci(np.r_[x, np.nan])          # NaN skipped
    assert m == pytest.approx(x.mean()) and lo < m < hi
    assert all(math.isnan(v) for v in S.mean_ci([np.nan]))
    groups = [x[:10], x[10:], np.array([np.nan, 1.0])]
    pm, plo, phi = S.pooled_mean_ci(groups)
    assert pm == pytest.approx(np.r_[x, 1.0].mean()) and plo < pm < phi
    assert S.pooled_mean_ci(groups) == (pm, plo, phi)
    assert S.pooled_mean_ci(groups, seed=1) != (pm, plo, phi)
    assert all(math.isnan(v) for v in S.pooled_mean_ci([[], [np.nan]]))
    a, b = rng.random(30) < 0.8, rng.random(30) < 0.4
    d, dlo, dhi = S.diff_ci([(a, b)])
    assert d == pytest.approx(100 * (a.mean() - b.mean())) and dlo < d < dhi
    assert S.diff_ci([(a, b)]) == (d, dlo, dhi)
    assert S.diff_ci([(np.ones(5, bool), np.ones(7, bool))]) == (0.0, 0.0, 0.0)
    # a macro drop: the mean of the tasks' drops; empty pairs skipped
    d2 = S.diff_ci([(a, b), (b, a), (a, np.zeros(0, bool))])
    assert d2[0] == pytest.approx(0.0) and d2[1] < 0 < d2[2]
    assert S.rate_ci([True, False, True, True]) == pytest.approx(_pct_wilson([1, 0, 1, 1]))


# ------------------------------------------------------------------------------ Table V

def test_task_success_numbers_na_and_macro(region, tmp_path):
    files, frames = region
    long = T.task_success_table(files, tmp_path / "ts.tex")
    idx = long.set_index(["task", "method", "tier"])
    for (task, tier, method, cond), df in frames.items():
        if cond != "data-grounded":
            continue
        r = idx.loc[(task, method, tier)]
        assert r["n"] == len(df)
        if task == "AS" and tier >= 2:         # not hostable: n/a, never 0
            assert not r["applicable"] and math.isnan(r["sr"]) and r["reason"]
            continue
        assert (r["sr"], r["lo"], r["hi"]) == pytest.approx(_pct_wilson(df["success"]))
    # macro: over the hosted tasks only, the ladder's stratified bootstrap
    cells = load_cells(f for f in files if read_metrics_meta(f)["currents"]
                       and read_metrics_meta(f)["current_gain"] == 1.0
                       and read_metrics_meta(f)["tide"] is None)
    for method, tier in (("heuristic", 1), ("heuristic", 3), ("bc", 2)):
        m = idx.loc[("Macro", method, tier)]
        hosted = [t for t in METRIC if not (t == "AS" and tier >= 2)]
        assert m["tasks"] == len(hosted)
        srs = [100 * frames[(t, tier, method, "data-grounded")]["success"].mean()
               for t in hosted]
        assert m["sr"] == pytest.approx(np.mean(srs))
        ref = macro_rate(cells, method, tier)
        assert (m["sr"], m["lo"], m["hi"]) == pytest.approx((ref["sr"], ref["lo"], ref["hi"]))
        assert m["lo"] <= m["sr"] <= m["hi"]
    # the currents-off, doubled and tide cells are not in Table V
    h3 = idx.loc[("SK", "heuristic", 3)]
    assert h3["sr"] == 100 * frames[("SK", 3, "heuristic", "data-grounded")]["success"].mean()
    # Parquet beside the tex: the same numbers; the tex shows n/a and bolds per task and tier
    pq = pd.read_parquet(tmp_path / "ts.parquet")
    pd.testing.assert_frame_equal(pq, long, check_dtype=False)
    assert read_metrics_meta(tmp_path / "ts.parquet")["table"] == "task_success"
    tex = (tmp_path / "ts.tex").read_text()
    assert "\\toprule" in tex and "\\bottomrule" in tex and "evaluation seed 1000" in tex
    as_line = next(ln for ln in tex.splitlines() if ln.startswith("AS &"))
    assert as_line.count("n/a") == 6                 # 3 methods x T2, T3
    assert "T2, T3: 6 of the 7 tasks" in tex and "AS at T2, T3" in tex
    # bold: the best non-oracle SR per task and tier, as displayed
    for task in ("G2G", "FH"):
        line = next(ln for ln in tex.splitlines() if ln.startswith(f"{task} &"))
        cells_txt = line.rstrip(" \\").split(" & ")[2:]
        header = next(ln for ln in tex.splitlines() if ln.startswith("Task &"))
        cols = header.rstrip(" \\").split(" & ")[2:]
        for tier in (2, 3):
            h = round(100 * frames[(task, tier, "heuristic", "data-grounded")]["success"].mean())
            b = round(100 * frames[(task, tier, "bc", "data-grounded")]["success"].mean())
            txt = dict(zip(cols, cells_txt))
            assert txt[f"Heur T{tier}"].startswith("\\textbf") == (h >= b)
            assert txt[f"BC T{tier}"].startswith("\\textbf") == (b >= h)
            assert not txt[f"Oracle T{tier}"].startswith("\\textbf")


def test_task_success_bytes_are_reproducible(region, tmp_path):
    files, _ = region
    T.task_success_table(files, tmp_path / "a.tex", region="r1")
    T.task_success_table(list(reversed(files)), tmp_path / "b.tex", region="r1")
    assert (tmp_path / "a.tex").read_bytes() == (tmp_path / "b.tex").read_bytes()
    assert (tmp_path / "a.parquet").read_bytes() == (tmp_path / "b.parquet").read_bytes()
    assert "tab:task_success:r1" in (tmp_path / "a.tex").read_text()


def test_task_success_frame_keeps_its_shape(region):
    files, frames = region
    df = T.task_success_frame(files)
    assert list(df["Task"]) == ["G2G", "SK", "RF", "AS", "PI", "SPC", "FH", "Macro"]
    assert list(df.columns[:3]) == ["Family", "Task", "N"]
    assert list(df.columns[3:]) == ["Heur T1", "Heur T2", "Heur T3", "Oracle T2", "Oracle T3",
                                    "BC T2", "BC T3"]
    assert list(df["N"][:7]) == [AGENTS[t] for t in METRIC]
    row = df.set_index("Task")
    assert math.isnan(row.loc["AS", "BC T3"])                       # n/a, not 0
    assert row.loc["SPC", "Heur T2"] == 100 * frames[
        ("SPC", 2, "heuristic", "data-grounded")]["success"].mean()
    assert row.loc["Macro", "Heur T3"] == pytest.approx(row.loc[list(METRIC), "Heur T3"].mean())


# ------------------------------------------------------------------------------ Table III

def test_headline_numbers(region, tmp_path):
    files, frames = region
    df = T.headline_table(files, tmp_path / "h.tex", region="r1")
    assert list(df["method"]) == ["heuristic", "oracle", "bc"]
    h = df.set_index("method").loc["heuristic"]
    for tier in (2, 3):
        hosted = [t for t in METRIC if t != "AS"]
        fr = {t: frames[(t, tier, "heuristic", "data-grounded")] for t in hosted}
        assert h[f"T{tier}_sr"] == pytest.approx(np.mean([100 * fr[t]["success"].mean()
                                                          for t in hosted]))
        assert h[f"T{tier}_sr_tasks"] == 6
        # E: mean over every episode of the tier (not of the currents-off or x2 cells)
        e = np.concatenate([fr[t]["E"].to_numpy() for t in hosted])
        assert h[f"T{tier}_E"] == pytest.approx(e.mean())
        assert h[f"T{tier}_E_lo"] < h[f"T{tier}_E"] < h[f"T{tier}_E_hi"]
        # Coll: percent, multi-agent tasks only (SPC, FH)
        c = np.concatenate([fr[t]["coll_ratio"].to_numpy() for t in ("SPC", "FH")]) * 100
        assert h[f"T{tier}_coll"] == pytest.approx(c.mean()) and h[f"T{tier}_coll_tasks"] == 2
        assert h[f"T{tier}_coll_lo"] < h[f"T{tier}_coll"] < h[f"T{tier}_coll_hi"]
    f3 = {t: frames[(t, 3, "heuristic", "data-grounded")] for t in METRIC}
    assert (h["G2G_sr"], h["G2G_sr_lo"], h["G2G_sr_hi"]) == pytest.approx(
        _pct_wilson(f3["G2G"]["success"]))
    sk = f3["SK"]["rms_error_m"]
    assert sk.isna().any() and h["SK_rms"] == pytest.approx(sk.mean())   # NaN skipped
    assert (h["SK_rms"], h["SK_rms_lo"], h["SK_rms_hi"]) == S.mean_ci(sk.to_numpy())
    assert h["SPC_cleanup"] == pytest.approx(f3["SPC"]["cleanup_rate"].mean())
    assert h["PI_score"] == pytest.approx(f3["PI"]["inspection_score"].mean())
    assert h["AS_coverage_state"] == "n/a" and math.isnan(h["AS_coverage"])
    pq = pd.read_parquet(tmp_path / "h.parquet")
    pd.testing.assert_frame_equal(pq, df, check_dtype=False)
    tex = (tmp_path / "h.tex").read_text()
    lines = {ln.split(" & ")[0]: ln.rstrip(" \\").split(" & ")
             for ln in tex.splitlines() if " & " in ln}
    header = lines["Method"]
    col = header.index("T3 AS cov.")
    assert lines["Heur"][col] == lines["BC"][col] == "n/a"
    assert "multi-agent tasks only (SPC, FH)" in tex and "tab:headline:r1" in tex
    # bold: T2 SR best of heuristic / BC (the oracle is never bold); E: the lower
    sr = header.index("T2 SR (\\%)")
    better = "Heur" if df.loc[0, "T2_sr"] >= df.loc[2, "T2_sr"] else "BC"
    assert lines[better][sr].startswith("\\textbf")
    assert not lines["Oracle"][sr].startswith("\\textbf")
    e = header.index("T3 E")
    lower = "Heur" if round(df.loc[0, "T3_E"]) <= round(df.loc[2, "T3_E"]) else "BC"
    assert lines[lower][e].startswith("\\textbf")


# ------------------------------------------------------------------------------ difficulty

def test_difficulty_drops(region, tmp_path):
    files, frames = region
    df = T.difficulty_table(files, tmp_path / "d.tex")
    r = df.set_index("task")
    assert list(r.index) == list(METRIC) + ["Macro"]
    g = {k: frames[("SK", k, "heuristic", "data-grounded")]["success"] for k in (1, 2, 3)}
    assert (r.loc["SK", "T2_sr"], r.loc["SK", "T2_lo"], r.loc["SK", "T2_hi"]) == \
        pytest.approx(_pct_wilson(g[2]))
    d = r.loc["SK", "drop_T2_T3"]
    assert d == pytest.approx(100 * (g[2].mean() - g[3].mean()))
    assert (d, r.loc["SK", "drop_T2_T3_lo"], r.loc["SK", "drop_T2_T3_hi"]) == S.diff_ci(
        [(g[2].to_numpy(), g[3].to_numpy())])
    assert r.loc["SK", "drop_T2_T3_lo"] <= d <= r.loc["SK", "drop_T2_T3_hi"]
    # AS: hosted at T1 only
    assert r.loc["AS", "T1_state"] == "ok" and r.loc["AS", "T2_state"] == "n/a"
    assert math.isnan(r.loc["AS", "drop_T1_T2"])
    # macro SRs over the hosted tasks; the macro drop over the tasks hosted at both tiers
    assert r.loc["Macro", "T1_tasks"] == 7 and r.loc["Macro", "T2_tasks"] == 6
    both = [t for t in METRIC if t != "AS"]
    drops = [100 * (frames[(t, 1, "heuristic", "data-grounded")]["success"].mean()
                    - frames[(t, 2, "heuristic", "data-grounded")]["success"].mean())
             for t in both]
    assert r.loc["Macro", "drop_T1_T2"] == pytest.approx(np.mean(drops))
    assert r.loc["Macro", "drop_T1_T2_tasks"] == 6
    assert r.loc["Macro", "drop_T1_T2_lo"] <= r.loc["Macro", "drop_T1_T2"] <= \
        r.loc["Macro", "drop_T1_T2_hi"]
    pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "d.parquet"), df,
                                  check_dtype=False)
    tex = (tmp_path / "d.tex").read_text()
    as_line = next(ln for ln in tex.splitlines() if ln.startswith("AS &"))
    assert as_line.count("n/a") == 4
    # BC: only T2 and T3 -> one drop column
    bc = T.difficulty_frame(files, "bc")
    assert "drop_T2_T3" in bc and "drop_T1_T2" not in bc and "T1_sr" not in bc


# ------------------------------------------------------------------------------ ablation

def test_ablation_conditions_from_the_records(region, tmp_path):
    files, frames = region
    df = T.ablation_table(files, tmp_path / "a.tex")
    macro = df[df["task"] == "Macro"]
    tide_id = "tide-0.5ms-44712s"
    assert list(macro["condition"]) == ["data-grounded", "gain-2", tide_id, "currents-off"]
    r = df.set_index(["task", "condition"])
    for (task, tier, method, cond), f in frames.items():
        if tier != 3 or method != "heuristic":
            continue
        cid = tide_id if cond == "tide" else cond
        row = r.loc[(task, cid)]
        if task == "AS":
            assert not row["applicable"] and math.isnan(row["sr"])
        else:
            assert (row["sr"], row["lo"], row["hi"]) == pytest.approx(_pct_wilson(f["success"]))
            assert row["same_episodes"]
    # each condition's macro over its own hosted tasks
    m = macro.set_index("condition")
    assert m.loc["gain-2", "tasks"] == 2 and m.loc[tide_id, "tasks"] == 1
    assert m.loc["currents-off", "tasks"] == 6 and m.loc["data-grounded", "tasks"] == 6
    off = [100 * frames[(t, 3, "heuristic", "currents-off")]["success"].mean()
           for t in METRIC if t != "AS"]
    assert m.loc["currents-off", "sr"] == pytest.approx(np.mean(off))
    x2 = [frames[(t, 3, "heuristic", "gain-2")]["success"].to_numpy() for t in ("SK", "SPC")]
    assert (m.loc["gain-2", "sr"], m.loc["gain-2", "lo"], m.loc["gain-2", "hi"]) == \
        pytest.approx(stratified_macro(x2))
    assert m.loc["gain-2", "current_gain"] == 2.0
    assert json.loads(m.loc[tide_id, "tide"]) == TIDE
    tex = (tmp_path / "a.tex").read_text()
    header = next(ln for ln in tex.splitlines() if ln.startswith("Task &"))
    assert header.split(" & ")[1:] == [
        "Data-grounded SR (\\%)", "Currents $\\times$2 SR (\\%)",
        "+ tide (0.5 m/s, 12.4 h) SR (\\%)", "Currents off SR (\\%) \\\\"]
    g2g = next(ln for ln in tex.splitlines() if ln.startswith("G2G &"))
    assert g2g.split(" & ")[2] == "--"               # no doubled cell: not run, not n/a
    assert "A = 0.5" in tex and "checked" in tex
    assert read_metrics_meta(tmp_path / "a.parquet")["tier"] == 3


def test_ablation_with_only_data_and_off_cells(region, tmp_path):
    files, _ = region
    keep = [f for f in files if "x2" not in f.name and "tide" not in f.name]
    df = T.ablation_frame(keep)
    assert list(df.loc[df["task"] == "Macro", "condition"]) == ["data-grounded",
                                                                 "currents-off"]
    # another tier, another method
    t2 = T.ablation_frame(keep, tier=2, method="bc")
    assert list(t2.loc[t2["task"] == "Macro", "condition"]) == ["data-grounded"]


# ------------------------------------------------------------------------------ Table II

def test_ladder_spec_table(tmp_path):
    from oneocean import registry
    from oneocean.tasks.tiers import load_task_table

    df = T.ladder_spec_table(tmp_path / "ladder.tex")
    assert list(df["task"]) == list(registry.task_ids())
    r = df.set_index("task")
    for t in ("SK", "FT", "AS"):
        tb, s = load_task_table(t), registry.task_spec(t)
        assert r.loc[t, "vehicle"] == tb["vehicle"] and r.loc[t, "primary"] == s.primary
        assert (r.loc[t, "agents_lo"], r.loc[t, "agents_hi"]) == s.agents_range
        for k, p in tb["tiers"].items():
            assert r.loc[t, f"T{k}_time_limit_s"] == p["time_limit_s"]
            assert [r.loc[t, f"T{k}_band_lo"], r.loc[t, f"T{k}_band_hi"]] == p["current_band"]
            assert json.loads(r.loc[t, f"T{k}_params"]) == p
    tex = (tmp_path / "ladder.tex").read_text()
    assert "FT & Formation transit & 10 (2--10) & REMUS 100" in tex
    assert "1800; 67--100" in tex
    assert "\\emph{Coordination / Pollution}" in tex
    pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "ladder.parquet"), df,
                                  check_dtype=False)
    T.ladder_spec_table(tmp_path / "again.tex")
    assert (tmp_path / "again.tex").read_bytes() == (tmp_path / "ladder.tex").read_bytes()


# ------------------------------------------------------------------------------ real cells

REAL = Path(__file__).parents[1] / "results/rollouts/synthetic_coast/scene"


@pytest.mark.skipif(not REAL.is_dir(), reason="no rollout cells of synthetic_coast")
def test_tables_on_the_real_cells(tmp_path):
    # the workflow's table inputs: the data cells and the forcing ablations (not the
    # team-size sweep, whose cells differ only in N)
    files = sorted(f for f in glob.glob(str(REAL / "*/tier*/*.parquet"))
                   if "_n" not in Path(f).name and "_seed" not in Path(f).name)
    cells = C.load_cell_frames(files)

    def cell(task, tier, method, off=False):
        return pd.read_parquet(REAL / task / f"tier{tier}" /
                               f"{method}{'_currents-off' if off else ''}.parquet")

    long = T.task_success_table(cells, tmp_path / "ts.tex", region="synthetic_coast")
    idx = long.set_index(["task", "method", "tier"])
    d = cell("SK", 3, "heuristic")
    assert idx.loc[("SK", "heuristic", 3), "sr"] == 100 * d["success"].mean()
    lo, hi = wilson(int(d["success"].sum()), len(d))
    assert idx.loc[("SK", "heuristic", 3), "lo"] == pytest.approx(100 * lo)
    mac = macro_rate(load_cells(files), "heuristic", 3)       # as in the ladder table
    assert idx.loc[("Macro", "heuristic", 3), ["sr", "lo", "hi"]].tolist() == \
        pytest.approx([mac["sr"], mac["lo"], mac["hi"]])

    h = T.headline_table(cells, tmp_path / "h.tex").set_index("method")
    spc = cell("SPC", 3, "bc")
    assert h.loc["bc", "SPC_cleanup"] == pytest.approx(spc["cleanup_rate"].mean())
    assert h.loc["heuristic", "SK_rms"] == pytest.approx(d["rms_error_m"].mean())
    multi = [t for t in ("FT", "SPC", "UPL", "FH")]
    coll = np.concatenate([cell(t, 2, "heuristic")["coll_ratio"].to_numpy() for t in multi])
    assert h.loc["heuristic", "T2_coll"] == pytest.approx(100 * coll.mean())

    dif = T.difficulty_table(cells, tmp_path / "d.tex").set_index("task")
    a, b = cell("DPT", 2, "heuristic"), cell("DPT", 3, "heuristic")
    assert dif.loc["DPT", "drop_T2_T3"] == pytest.approx(
        100 * (a["success"].mean() - b["success"].mean()))

    abl = T.ablation_table(cells, tmp_path / "a.tex").set_index(["task", "condition"])
    off = cell("FT", 3, "heuristic", off=True)
    assert abl.loc[("FT", "currents-off"), "sr"] == 100 * off["success"].mean()
    assert abl.loc[("FT", "currents-off"), "same_episodes"]
    for name in ("ts", "h", "d", "a"):
        tex = (tmp_path / f"{name}.tex").read_text()
        assert tex.startswith("\\begin{table") and "\\bottomrule" in tex
        assert (tmp_path / f"{name}.parquet").is_file()
