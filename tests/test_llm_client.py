"""The LLM planner's backend against a scripted OpenAI-compatible server on loopback:
client, response cache, plan validation, fallback and per-episode accounting."""

from __future__ import annotations

import json
import math
import os
import socket

import pytest
from fake_llm_server import FakeLLMServer, answer, assignment, raw, sleep, status

from oneocean.errors import ConfigError
from oneocean.methods.llm import (
    ClientConfig,
    LLMClient,
    LLMError,
    PlanInvalid,
    Planner,
    ResponseCache,
    assignment_schema,
    build_messages,
    cache_key,
    episode_totals,
    validate_plan,
)

N, K = 4, 3
FALLBACK = [2, 2, 1, 0]
SUMMARY = "SPC: 4 agents, 3 sources. agent 0 at (1.0, 2.0) ... (test summary)"


def make_planner(base_url, cache_dir=None, timeout_s=5.0, api_key_env="", environ=None):
    cfg = ClientConfig(base_url=base_url, model="fake-7b", api_key_env=api_key_env,
                       timeout_s=timeout_s, max_tokens=64)
    cache = ResponseCache(cache_dir) if cache_dir is not None else None
    return Planner(LLMClient(cfg, cache=cache, environ=environ if environ is not None else {}))


def closed_port() -> int:
    """A loopback port with nothing listening (bound, then released)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# --- a valid answer ---------------------------------------------------------------------------

def test_valid_answer_gives_its_assignment_and_usage_tokens(tmp_path):
    with FakeLLMServer([assignment([1, 0, 2, 1], prompt_tokens=123, completion_tokens=17)]) as srv:
        planner = make_planner(srv.base_url, tmp_path / "cache")
        got, rec = planner.plan(SUMMARY, N, K, FALLBACK)
    assert got == [1, 0, 2, 1]
    assert rec.outcome == "valid" and rec.valid and not rec.used_fallback
    assert rec.fallback_reason is None and rec.error is None
    assert (rec.prompt_tokens, rec.completion_tokens) == (123, 17)
    assert rec.cached is False and rec.latency_s > 0 and rec.calls == 1
    # what reached the server: one POST to /v1/chat/completions with the configured settings
    assert len(srv.requests) == 1
    req = srv.requests[0]
    assert req["path"] == "/v1/chat/completions"
    body = req["body"]
    assert body["model"] == "fake-7b"
    assert body["temperature"] == 0.0
    assert body["max_tokens"] == 64
    assert body["messages"] == build_messages(SUMMARY, N, K)
    prompt = body["messages"][1]["content"]
    assert SUMMARY in prompt and "4 agents" in prompt and "[0, 3)" in prompt
    assert "Authorization" not in req["headers"]  # no key configured


def test_fenced_json_answer_is_accepted(tmp_path):
    text = 'Here is the plan:\n```json\n{"assignment": [0, 1, 2, 0], "reason": "nearest"}\n```\n'
    with FakeLLMServer([answer(text)]) as srv:
        got, rec = make_planner(srv.base_url).plan(SUMMARY, N, K, FALLBACK)
    assert got == [0, 1, 2, 0] and rec.valid


def test_answer_without_usage_is_valid_with_no_token_counts():
    with FakeLLMServer([assignment([0, 0, 1, 1], usage=False)]) as srv:
        got, rec = make_planner(srv.base_url).plan(SUMMARY, N, K, FALLBACK)
    assert got == [0, 0, 1, 1] and rec.valid
    assert rec.prompt_tokens is None and rec.completion_tokens is None


# --- the cache --------------------------------------------------------------------------------

def test_second_identical_call_is_a_cache_hit_without_a_request(tmp_path):
    with FakeLLMServer([assignment([1, 2, 0, 1], prompt_tokens=90, completion_tokens=11),
                        status(500)]) as srv:
        planner = make_planner(srv.base_url, tmp_path / "cache")
        first, rec1 = planner.plan(SUMMARY, N, K, FALLBACK)
        assert len(srv.requests) == 1
        second, rec2 = planner.plan(SUMMARY, N, K, FALLBACK)
        assert len(srv.requests) == 1  # nothing reached the server
    assert first == second == [1, 2, 0, 1]
    assert rec1.cached is False and rec2.cached is True
    assert rec1.latency_s > 0 and rec2.latency_s == rec1.latency_s  # the fetch-time latency
    assert (rec2.prompt_tokens, rec2.completion_tokens) == (90, 11)  # the stored usage
    assert rec2.valid


def test_cache_survives_a_new_client_and_a_new_server_url(tmp_path):
    """Reruns are free: another process (new client) against another URL for the same model
    hits the cache; the key does not depend on the base URL."""
    with FakeLLMServer([assignment([2, 1, 0, 0])]) as srv:
        make_planner(srv.base_url, tmp_path / "cache").plan(SUMMARY, N, K, FALLBACK)
    got, rec = make_planner(f"http://127.0.0.1:{closed_port()}/v1", tmp_path / "cache") \
        .plan(SUMMARY, N, K, FALLBACK)
    assert got == [2, 1, 0, 0] and rec.cached and rec.valid
    stored = json.loads(next((tmp_path / "cache").glob("*.json")).read_text())
    assert rec.latency_s == stored["latency_s"] > 0  # replayed exactly from the file


def test_cache_record_without_a_valid_latency_is_a_miss(tmp_path):
    cache = ResponseCache(tmp_path / "cache")
    base = {"text": "x", "prompt_tokens": 1, "completion_tokens": 1}
    for i, extra in enumerate([{}, {"latency_s": -1.0}, {"latency_s": True},
                               {"latency_s": "0.5"}]):
        cache.put(f"{i:064d}", {**base, **extra})
        assert cache.get(f"{i:064d}") is None, extra
    cache.put("f" * 64, {**base, "latency_s": 0.25})
    assert cache.get("f" * 64)["latency_s"] == 0.25


def test_changed_prompt_misses_and_files_are_written_atomically(tmp_path):
    cache_dir = tmp_path / "cache"
    with FakeLLMServer([assignment([0, 1, 2, 0]), assignment([1, 1, 1, 1])]) as srv:
        planner = make_planner(srv.base_url, cache_dir)
        a, _ = planner.plan(SUMMARY, N, K, FALLBACK)
        b, rec = planner.plan(SUMMARY + " agent 3 moved.", N, K, FALLBACK)
        assert len(srv.requests) == 2
    assert (a, b) == ([0, 1, 2, 0], [1, 1, 1, 1]) and not rec.cached
    names = sorted(p.name for p in cache_dir.iterdir())
    keys = sorted(cache_key("fake-7b", build_messages(s, N, K), 0.0, 64) + ".json"
                  for s in (SUMMARY, SUMMARY + " agent 3 moved."))
    assert names == keys  # one file per key, no temporary file left behind
    stored = json.loads((cache_dir / keys[0]).read_text())
    assert stored["schema"] == 1 and stored["model"] == "fake-7b"


def test_cache_key_changes_with_each_input():
    msgs = build_messages(SUMMARY, N, K)
    base = cache_key("m", msgs, 0.0, 64)
    assert base == cache_key("m", [dict(reversed(list(m.items()))) for m in msgs], 0, 64)
    assert len({base, cache_key("m2", msgs, 0.0, 64), cache_key("m", msgs, 0.5, 64),
                cache_key("m", msgs, 0.0, 65), cache_key("m", msgs[:1], 0.0, 64)}) == 5


def test_failed_rename_leaves_no_temp_file_and_no_entry(tmp_path, monkeypatch):
    cache = ResponseCache(tmp_path / "cache")

    def broken_replace(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", broken_replace)
    with pytest.raises(ConfigError, match="could not be written: disk full"):
        cache.put("ab" * 32, {"text": "x", "prompt_tokens": 1, "completion_tokens": 1})
    assert list((tmp_path / "cache").iterdir()) == []


def test_corrupt_cache_file_is_a_miss_and_is_replaced(tmp_path):
    cache_dir = tmp_path / "cache"
    key = cache_key("fake-7b", build_messages(SUMMARY, N, K), 0.0, 64)
    cache_dir.mkdir()
    (cache_dir / f"{key}.json").write_text('{"text": "half')
    with FakeLLMServer([assignment([0, 0, 0, 0])]) as srv:
        got, rec = make_planner(srv.base_url, cache_dir).plan(SUMMARY, N, K, FALLBACK)
        assert len(srv.requests) == 1
    assert got == [0, 0, 0, 0] and not rec.cached
    assert ResponseCache(cache_dir).get(key)["text"] == '{"assignment": [0, 0, 0, 0]}'


# --- bad output and bad endpoints: exactly the fallback, never a raise -------------------------

BAD_CASES = {
    "malformed_json": (answer('{"assignment": [1, 0, 2,'), "invalid", "not_json"),
    "prose_only": (answer("I would send agent 0 to source 1."), "invalid", "not_json"),
    "wrong_length": (assignment([1, 0, 2]), "invalid", "schema"),
    "too_long": (assignment([1, 0, 2, 1, 0]), "invalid", "schema"),
    "out_of_range": (assignment([1, 0, 3, 1]), "invalid", "schema"),
    "negative": (assignment([1, -1, 0, 1]), "invalid", "schema"),
    "not_integers": (assignment([1, 0.5, 0, 1]), "invalid", "schema"),
    "booleans": (assignment([True, False, True, False]), "invalid", "schema"),
    "no_assignment_key": (answer('{"plan": [1, 0, 2, 1]}'), "invalid", "schema"),
    "http_500": (status(500), "error", "http"),
    "http_429": (status(429, '{"error": "rate limited"}'), "error", "http"),
    "body_not_json": (raw("<html>oops</html>"), "error", "bad_response"),
    "body_without_choices": (raw('{"object": "chat.completion"}'), "error", "bad_response"),
}


@pytest.mark.parametrize("case", sorted(BAD_CASES))
def test_bad_case_gives_exactly_the_fallback(case, tmp_path):
    behaviour, outcome, reason = BAD_CASES[case]
    with FakeLLMServer([behaviour]) as srv:
        got, rec = make_planner(srv.base_url, tmp_path / "cache").plan(SUMMARY, N, K, FALLBACK)
        assert len(srv.requests) == 1
    assert got == FALLBACK
    assert rec.outcome == outcome and rec.fallback_reason == reason and rec.used_fallback
    assert rec.error and "\n" not in rec.error
    assert rec.cached is False


def test_http_error_message_names_status_and_url(tmp_path):
    with FakeLLMServer([status(429, '{"error": "rate limited"}')]) as srv:
        _, rec = make_planner(srv.base_url).plan(SUMMARY, N, K, FALLBACK)
    assert rec.error == (f"llm: HTTP 429 from {srv.base_url}/chat/completions: "
                         '{"error": "rate limited"}')


def test_timeout_gives_the_fallback_within_the_timeout(tmp_path):
    with FakeLLMServer([sleep(2.0, then=assignment([0, 1, 2, 0]))]) as srv:
        planner = make_planner(srv.base_url, tmp_path / "cache", timeout_s=0.3)
        got, rec = planner.plan(SUMMARY, N, K, FALLBACK)
    assert got == FALLBACK
    assert (rec.outcome, rec.fallback_reason) == ("error", "timeout")
    assert rec.error == f"llm: no answer from {srv.base_url}/chat/completions within 0.3 s"
    assert 0.3 <= rec.latency_s < 1.5
    assert not (tmp_path / "cache").exists() or not list((tmp_path / "cache").iterdir())


def test_connection_refused_gives_the_fallback():
    url = f"http://127.0.0.1:{closed_port()}/v1"
    got, rec = make_planner(url).plan(SUMMARY, N, K, FALLBACK)
    assert got == FALLBACK
    assert (rec.outcome, rec.fallback_reason) == ("error", "connection")
    assert rec.error.startswith(f"llm: cannot reach {url}/chat/completions:")
    assert "\n" not in rec.error


def test_client_raises_only_llm_error():
    client = LLMClient(ClientConfig(base_url=f"http://127.0.0.1:{closed_port()}/v1",
                                    model="m"), environ={})
    with pytest.raises(LLMError) as info:
        client.complete(build_messages(SUMMARY, N, K))
    assert info.value.kind == "connection"


def test_errors_are_not_cached_but_invalid_answers_are(tmp_path):
    """A failed request is retried on the next call; an answer (even an invalid one) is the
    model's reproducible output and is replayed from the cache."""
    with FakeLLMServer([status(500), answer("no plan today"), status(500)]) as srv:
        planner = make_planner(srv.base_url, tmp_path / "cache")
        _, rec1 = planner.plan(SUMMARY, N, K, FALLBACK)
        _, rec2 = planner.plan(SUMMARY, N, K, FALLBACK)
        _, rec3 = planner.plan(SUMMARY, N, K, FALLBACK)
        assert len(srv.requests) == 2
    assert [r.fallback_reason for r in (rec1, rec2, rec3)] == ["http", "not_json", "not_json"]
    assert [r.cached for r in (rec1, rec2, rec3)] == [False, False, True]


# --- accounting --------------------------------------------------------------------------------

def test_episode_accounting_totals_are_exact(tmp_path):
    script = [
        assignment([0, 1, 2, 0], prompt_tokens=100, completion_tokens=12),  # call 1: valid
        # call 2: same prompt as call 1 -> cache hit, no request
        answer('{"assignment": [0, 1', prompt_tokens=80, completion_tokens=5),  # call 3
        status(500),                                                           # call 4
        assignment([2, 2, 2, 2], usage=False),                                 # call 5
        assignment([9, 9, 9, 9], prompt_tokens=70, completion_tokens=9),       # call 6
        sleep(2.0),                                                            # call 7
    ]
    with FakeLLMServer(script) as srv:
        planner = make_planner(srv.base_url, tmp_path / "cache", timeout_s=0.3)
        summaries = ["s1", "s1", "s3", "s4", "s5", "s6", "s7"]
        outs = [planner.plan(s, N, K, FALLBACK)[0] for s in summaries]
        assert len(srv.requests) == 6
    assert outs == [[0, 1, 2, 0], [0, 1, 2, 0], FALLBACK, FALLBACK, [2, 2, 2, 2], FALLBACK,
                    FALLBACK]
    totals = planner.totals()
    rec = planner.records
    assert rec[1].cached and rec[1].latency_s == rec[0].latency_s  # hit: the fetch latency
    assert totals == {
        "calls": 7,
        "valid": 3,
        "invalid": 2,
        "errors": 2,
        "fallbacks": 4,
        "fallback_reasons": {"http": 1, "not_json": 1, "schema": 1, "timeout": 1},
        "cached_calls": 1,
        "uncached_calls": 6,
        # every call's latency, the cache hit at its fetch-time latency: same on a rerun
        "latency_s": math.fsum(r.latency_s for r in rec),
        "mean_latency_s": pytest.approx(math.fsum(r.latency_s for r in rec) / 7, rel=1e-12),
        # replies 1, 2 (cached copy of 1), 3 and 6 carry usage; 5 has none; 4 and 7 no reply
        "prompt_tokens": 100 + 100 + 80 + 70,
        "output_tokens": 12 + 12 + 5 + 9,
        "total_tokens": 350 + 38,
        "replies_without_usage": 1,
    }
    assert totals["latency_s"] >= 0.3  # the timed-out call counts its wait
    assert episode_totals(planner.records) == totals
    planner.reset()
    assert planner.totals()["calls"] == 0 and planner.totals()["mean_latency_s"] is None


# --- configuration and the API key ------------------------------------------------------------

def test_api_key_from_the_named_env_var_is_sent_as_bearer(monkeypatch):
    monkeypatch.setenv("ONEOCEAN_TEST_LLM_KEY", "sk-test-123")
    with FakeLLMServer([assignment([0, 0, 0, 0])]) as srv:
        cfg = ClientConfig(base_url=srv.base_url, model="m", api_key_env="ONEOCEAN_TEST_LLM_KEY")
        client = LLMClient(cfg)
        got, _ = Planner(client).plan(SUMMARY, N, K, FALLBACK)
    assert got == [0, 0, 0, 0]
    assert srv.requests[0]["headers"]["Authorization"] == "Bearer sk-test-123"
    assert "sk-test-123" not in repr(client) and "sk-test-123" not in repr(cfg)


def test_missing_key_env_var_is_a_one_line_config_error(monkeypatch):
    monkeypatch.delenv("ONEOCEAN_TEST_LLM_KEY", raising=False)
    cfg = ClientConfig(base_url="http://127.0.0.1:1/v1", model="m",
                       api_key_env="ONEOCEAN_TEST_LLM_KEY")
    with pytest.raises(ConfigError) as info:
        LLMClient(cfg)
    msg = str(info.value)
    assert "ONEOCEAN_TEST_LLM_KEY" in msg and "not set" in msg and "\n" not in msg


@pytest.mark.parametrize("kw, key", [
    ({"base_url": "127.0.0.1:8000/v1"}, "llm.base_url"),
    ({"model": " "}, "llm.model"),
    ({"timeout_s": 0}, "llm.timeout_s"),
    ({"max_tokens": 0}, "llm.max_tokens"),
    ({"temperature": -1}, "llm.temperature"),
])
def test_bad_client_config_is_a_config_error(kw, key):
    args = {"base_url": "http://127.0.0.1:8000/v1", "model": "m", **kw}
    with pytest.raises(ConfigError, match=key):
        ClientConfig(**args)


# --- validation as a pure function ------------------------------------------------------------

def test_validate_plan_values():
    schema = assignment_schema(3, 2)
    assert validate_plan('{"assignment": [0, 1, 1]}', schema) == {"assignment": [0, 1, 1]}
    assert validate_plan(' {"assignment": [1.0, 0, 1]} ', schema) == {"assignment": [1, 0, 1]}
    assert validate_plan("```\n{\"assignment\": [0, 0, 0]}\n```", schema)["assignment"] == [0, 0, 0]
    assert validate_plan('{"assignment": [0, 2, 1]}', schema) == PlanInvalid(
        "schema", "at assignment/1: 2 is greater than the maximum of 1")
    assert validate_plan('{"assignment": [0, 1]}', schema) == PlanInvalid(
        "schema", "at assignment: [0, 1] is too short")
    assert validate_plan("", schema).reason == "not_json"


def test_invalid_fallback_is_the_callers_bug(tmp_path):
    planner = make_planner("http://127.0.0.1:1/v1")
    with pytest.raises(ValueError, match="fallback assignment is invalid"):
        planner.plan(SUMMARY, N, K, [0, 1, 2])
    with pytest.raises(ValueError, match="n_targets must be an integer >= 1"):
        planner.plan(SUMMARY, N, 0, FALLBACK)
