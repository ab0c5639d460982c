"""The planning suite's tables (Tables IV and VI) against the cell files they come from."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from oneocean.engine.recording import write_metrics
from oneocean.reporting.planning import (cost_frame, load_suite, omitted_note, performance_frame,
                                         planning_tables)
from oneocean.reporting.stats import mean_ci, wilson

METRIC = {"SPC": "cleanup_rate", "AS": "coverage_fraction", "PI": "inspection_score"}


def _cell(path, task, method, success, metric, *, calls=None, latency=None, tokens=None,
          fallbacks=None, label=None):
    n = len(success)
    df = pd.DataFrame({"task": task, "method": method, "episode": np.arange(n),
                       "success": np.asarray(success, bool), "T_s": np.arange(n) + 100.0,
                       "E": np.full(n, 50.0), METRIC[task]: np.asarray(metric, float)})
    if calls is not None:
        df["llm_calls"] = np.asarray(calls, np.int64)
        df["llm_fallbacks"] = np.asarray(fallbacks, np.int64)
        df["llm_latency_s"] = np.asarray(latency, float)
        df["llm_prompt_tokens"] = np.asarray(tokens, np.int64)
        df["llm_output_tokens"] = np.asarray(tokens, np.int64) // 10
        df["llm_total_tokens"] = df["llm_prompt_tokens"] + df["llm_output_tokens"]
    meta = {"task": task, "method": method, "applicable": True}
    if label:
        meta["label"] = label
    write_metrics(df, path, meta=meta)
    return path


@pytest.fixture
def suite(tmp_path):
    files = []
    rng = np.random.default_rng(0)
    for task in ("SPC", "AS", "PI"):
        files.append(_cell(tmp_path / f"{task}_h.parquet", task, "heuristic",
                           [1, 1, 1, 0] * 2, rng.uniform(0.5, 1, 8)))
        files.append(_cell(tmp_path / f"{task}_b.parquet", task, "bc",
                           [1, 0, 0, 0] * 2, rng.uniform(0.0, 0.5, 8)))
    # an LLM only on SPC, 8 episodes: 3 calls each, 1 fallback in each of the first 4
    files.append(_cell(tmp_path / "SPC_llm.parquet", "SPC", "llm_fake", [1] * 8,
                       np.full(8, 0.9), calls=[3] * 8, latency=[0.3] * 4 + [0.9] * 4,
                       tokens=[100] * 8, fallbacks=[1] * 4 + [0] * 4, label="LLM-Fake"))
    return files


def test_performance_rows_and_intervals(suite):
    df = load_suite(suite)
    perf = performance_frame(df).set_index("method")
    assert list(perf.index) == ["heuristic", "bc", "llm_fake"]   # registry order, then others
    h = perf.loc["heuristic"]
    assert h["SPC_sr"] == pytest.approx(75.0)
    lo, hi = wilson(6, 8)
    assert (h["SPC_sr_lo"], h["SPC_sr_hi"]) == pytest.approx((100 * lo, 100 * hi))
    assert h["sr_avg"] == pytest.approx(75.0)
    assert h["sr_avg_lo"] < 75.0 < h["sr_avg_hi"]
    d = df[(df["method"] == "heuristic") & (df["task"] == "AS")]
    assert h["AS_metric"] == pytest.approx(d["coverage_fraction"].mean())
    assert perf.loc["bc", "sr_avg"] == pytest.approx(25.0)
    # the LLM ran only SPC: its average is over the tasks it has, its AS cells are empty
    assert perf.loc["llm_fake", "sr_avg"] == pytest.approx(100.0)
    assert perf.loc["llm_fake", "AS_n"] == 0 and np.isnan(perf.loc["llm_fake", "AS_sr"])
    assert perf.loc["llm_fake", "label"] == "LLM-Fake"


def test_cost_uses_the_first_episodes_only(suite):
    cost = cost_frame(load_suite(suite), cost_episodes=4).set_index("method")
    llm = cost.loc["llm_fake"]
    assert llm["calls"] == pytest.approx(3.0)
    assert llm["latency_s"] == pytest.approx(0.3)            # episodes 4..7 (0.9 s) excluded
    assert llm["ms_per_call"] == pytest.approx(100.0)
    assert llm["fallbacks"] == 4 and llm["fallback_pct"] == pytest.approx(100.0 / 3)
    assert llm["total_tokens"] == pytest.approx(110.0)
    assert cost.loc["heuristic", "calls"] == 0 and cost.loc["heuristic", "ms_per_call"] == 0
    assert np.isnan(cost.loc["heuristic", "fallback_pct"])
    assert cost.loc["heuristic", "sr_avg"] == pytest.approx(75.0)
    assert cost.loc["heuristic", "episodes"] == 12


def test_mean_ci_is_seeded_and_brackets_the_mean():
    x = np.linspace(0, 1, 30)
    a, b = mean_ci(x), mean_ci(x)
    assert a == b
    assert a[1] < a[0] < a[2]
    assert np.isnan(mean_ci([])[0])


def test_latex_tables_say_why_llm_rows_are_absent(tmp_path, suite):
    no_llm = [f for f in suite if "llm" not in f.name]
    perf, cost = planning_tables(no_llm, tmp_path / "p.tex", tmp_path / "c.tex", tier=2,
                                 gain=2.0, episodes=8, cost_episodes=4, configured_llms=[])
    tex = (tmp_path / "p.tex").read_text()
    assert "no LLM rows" in tex and "LLM-" not in tex
    assert list(perf["method"]) == ["heuristic", "bc"]
    assert "\\textbf{75.0 [" in tex                       # best SR avg in bold, with interval
    back = pd.read_parquet(tmp_path / "p.parquet")
    pd.testing.assert_frame_equal(back, perf)
    assert omitted_note(["llm_x"]) == ""
    planning_tables(suite, tmp_path / "p2.tex", tmp_path / "c2.tex", tier=2, gain=2.0,
                    episodes=8, cost_episodes=4, configured_llms=["llm_fake"])
    assert "LLM-Fake" in (tmp_path / "c2.tex").read_text()
    # the LLM played 8 SPC episodes and none elsewhere, as configured: no note; with 40
    # configured, the caption states what it played
    assert "played" not in (tmp_path / "p2.tex").read_text()
    planning_tables(suite, tmp_path / "p4.tex", tmp_path / "c4.tex", tier=2, gain=2.0,
                    episodes=40, cost_episodes=4, configured_llms=["llm_fake"])
    assert "LLM-Fake played 8 episodes per task." in (tmp_path / "p4.tex").read_text()
    assert "Not applicable" not in (tmp_path / "p2.tex").read_text()
    # a cell the region cannot host: no rows, named in the caption
    na = tmp_path / "AS_llm_na.parquet"
    write_metrics(pd.read_parquet(suite[2]).iloc[:0], na,
                  meta={"task": "AS", "method": "heuristic", "applicable": False,
                        "reason": "no shelf"})
    planning_tables([na] + suite[:2] + suite[4:6], tmp_path / "p3.tex", tmp_path / "c3.tex",
                    tier=2, gain=2.0, episodes=8, cost_episodes=4, configured_llms=[])
    assert "Not applicable in this region" in (tmp_path / "p3.tex").read_text()
    assert "AS (heuristic)" in (tmp_path / "p3.tex").read_text()


def test_cost_episodes_are_the_first_episodes_of_the_performance_run():
    """The cost table reads episodes 0..19 of the 40-episode cells: the same episodes and
    results a 20-episode run gives (candidates are drawn per index; each episode is computed
    on its own), so no separate cost run is needed."""
    import oneocean.engine as E
    from oneocean.tasks import Cell
    from oneocean.testing import make_test_grid

    grid = E.load_grid(make_test_grid(nt=5, nz=3, ny=30, nx=40, dt_s=3600.0))
    for task, n_agents in (("PI", None), ("SPC", 3)):
        cell = Cell(grid, task, 1, n_agents=n_agents, current_gain=2.0)
        long = cell.run("heuristic", 4, 1000, "6dof")
        short = cell.run("heuristic", 2, 1000, "6dof")
        pd.testing.assert_frame_equal(long.iloc[:2].reset_index(drop=True), short)
