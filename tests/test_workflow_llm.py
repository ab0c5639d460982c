"""The LLM planner end to end through the workflow, against a loopback fake endpoint."""

import copy
import json

import pandas as pd
import pytest

from fake_llm_server import FakeLLMServer, rotate, status
from oneocean.engine.recording import read_metrics_meta
from workflow_helpers import SMALL_CONFIG, run_workflow

pytestmark = pytest.mark.slow

REGION = SMALL_CONFIG["region"]["name"]


def _config(base_url: str) -> dict:
    cfg = copy.deepcopy(SMALL_CONFIG)
    cfg["rollouts"]["methods"] = ["heuristic"]
    cfg["planning"] = {"tasks": ["SPC"], "tier": 1, "episodes": 3, "cost_episodes": 2,
                       "methods": ["heuristic"]}
    cfg["llm"] = {"models": [{"name": "fake", "label": "LLM-Fake", "base_url": base_url,
                              "model": "fake-model", "timeout_s": 5}]}
    return cfg


def test_llm_planner_through_the_workflow(tmp_path):
    variant = SMALL_CONFIG["rollouts"]["variant"]
    cell = tmp_path / f"results/planning/{REGION}/{variant}/SPC/llm_fake.parquet"
    cost = tmp_path / f"results/tables/{REGION}/planning_cost.parquet"
    with FakeLLMServer([rotate(1)]) as srv:
        run_workflow(tmp_path, targets=("planning",), config=_config(srv.base_url))
        n_requests = len(srv.requests)
    df = pd.read_parquet(cell)
    meta = read_metrics_meta(cell)
    assert meta["model"]["model"] == "fake-model" and "api_key" not in json.dumps(meta)
    assert len(df) == 3 and n_requests == df["llm_calls"].sum() > 0
    assert (df["llm_valid"] == df["llm_calls"]).all() and (df["llm_fallbacks"] == 0).all()
    assert (df["llm_uncached"] == df["llm_calls"]).all()
    c = pd.read_parquet(cost).set_index("method")
    assert list(c.index) == ["heuristic", "llm_fake"]
    assert c.loc["llm_fake", "calls"] == df["llm_calls"].iloc[:2].mean()
    assert c.loc["llm_fake", "label"] == "LLM-Fake"
    assert c.loc["heuristic", "calls"] == 0
    tex = (tmp_path / f"results/tables/{REGION}/planning_cost.tex").read_text()
    assert "LLM-Fake" in tex and "no LLM rows" not in tex
    before = cost.read_bytes()

    # a rerun of the LLM cells is served by the response cache: no request reaches the
    # endpoint (it now fails every call), and the tables are byte-identical
    with FakeLLMServer([status(500)]) as srv:
        run_workflow(tmp_path, targets=("planning",), config=_config(srv.base_url),
                     forcerun=("planning_llm_cell",))
        assert srv.requests == []
    again = pd.read_parquet(cell)
    assert (again["llm_cached"] == again["llm_calls"]).all()
    assert cost.read_bytes() == before

    # an unreachable endpoint mid-run: every call falls back to the heuristic's plan and is
    # counted, never a crash; the fallback reproduces the heuristic's cell
    cfg = _config("http://127.0.0.1:9/v1")
    cfg["llm"]["cache_dir"] = str(tmp_path / "empty_cache")
    run_workflow(tmp_path, targets=("planning",), config=cfg, forcerun=("planning_llm_cell",))
    down = pd.read_parquet(cell)
    assert (down["llm_errors"] == down["llm_calls"]).all() and down["llm_calls"].sum() > 0
    heur = pd.read_parquet(cell.with_name("heuristic.parquet"))
    for col in ("success", "T_s", "E", "cleanup_rate"):
        pd.testing.assert_series_equal(down[col], heur[col])
