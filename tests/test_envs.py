"""The step API (Gymnasium vector env, single-env view, PettingZoo parallel env) and
``evaluate``: same episodes, loop and metrics as the fused rollouts."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from oneocean.errors import ConfigError
from oneocean.evaluate import evaluate, load_policy
from oneocean.tasks import run_cell
from oneocean.tasks.common import OBS_DIM, OBS_FIELDS
from oneocean.testing import make_test_grid

METRIC_COLS = ["success", "T_s", "E", "coll_ratio", "violations", "current_speed_ms", "primary"]


class Replay:
    """A policy that replays recorded actions step by step (E, steps, N, 3)."""

    def __init__(self, act):
        self.act = np.nan_to_num(act)
        self.k = 0

    def __call__(self, obs):
        a = self.act[:, min(self.k, self.act.shape[1] - 1)]
        self.k += 1
        return a


def test_step_api_replaying_the_heuristic_gives_the_fused_metrics(coast):
    """Stepping the loop through the API with the heuristic's own actions reproduces the
    fused rollout's per-episode metrics exactly (same episodes, loop and metrics)."""
    fused, _, act = run_cell(coast, "G2G", 1, "heuristic", episodes=4, seed=2,
                             dynamics="6dof", observations=True)
    df = evaluate(Replay(act), "G2G", 1, coast, episodes=4, seed=2, name="replay")
    pd.testing.assert_frame_equal(df[METRIC_COLS], fused[METRIC_COLS])
    assert (df["method"] == "replay").all() and list(df.columns) == list(fused.columns)


def test_zero_policy_fails_and_reports_metrics(coast):
    """A policy that does nothing reaches no goal: SR 0, T = the time limit, E = 0."""
    df = evaluate(lambda obs: np.zeros(obs.shape[:2] + (3,)), "G2G", 1, coast, episodes=3,
                  seed=0)
    assert not df["success"].any()
    assert (df["E"] == 0.0).all()
    assert (df["T_s"] == df["T_s"].iloc[0]).all() and df["T_s"].iloc[0] > 0


def test_vector_env_contract(coast):
    from gymnasium.vector import AutoresetMode

    from oneocean.envs import OceanVectorEnv

    assert (OceanVectorEnv("G2G", 1, coast, num_envs=3).metadata["autoreset_mode"]
            == AutoresetMode.NEXT_STEP)                  # what RL libraries expect
    env = OceanVectorEnv("G2G", 1, coast, num_envs=3, autoreset_mode="disabled")
    assert env.metadata["autoreset_mode"] == AutoresetMode.DISABLED
    obs, info = env.reset(seed=5)
    assert obs.shape == (3, 1, OBS_DIM + 2) == env.observation_space.shape   # G2G's own 2
    # the briefing of every sub-env's episode: one episode each, the cell's goals
    assert info["_briefing"].all() and [b.goal.shape for b in info["briefing"]] == [(1, 3)] * 3
    obs2, _ = env.reset(seed=5)
    np.testing.assert_array_equal(obs, obs2)            # same seed, same episodes
    # the goal cue is the goal relative to where the vehicle thinks it is: the true offset
    # up to its start fix (0.5 m per horizontal axis, truncated at 3 sigma; depth is measured)
    init = env.cell.reset(3, 5)
    np.testing.assert_array_equal(np.concatenate([b.goal for b in info["briefing"]]),
                                  init["goal"])
    err = obs[:, 0, :3] - (init["goal"] - init["pos0"][:, 0])
    assert np.all(np.abs(err[:, [0, 2]]) <= 1.5) and np.any(np.abs(err[:, [0, 2]]) > 1e-3)
    np.testing.assert_allclose(err[:, 1], 0.0, atol=1e-9)
    a = np.zeros(env.action_space.shape)
    obs, r, term, trunc, info = env.step(a)
    assert r.shape == term.shape == trunc.shape == (3,)
    assert not term.any() and not trunc.any() and info == {}
    assert OBS_FIELDS[0] == "goal_dx_m"
    assert env.obs_fields == OBS_FIELDS + ("energy_j", "energy_frac")


def test_episode_end_reports_metrics_in_info(coast):
    from oneocean.envs import OceanVectorEnv

    env = OceanVectorEnv("G2G", 1, coast, num_envs=2, autoreset_mode="disabled")
    env.reset(seed=0)
    n = env.batch.n_steps
    for k in range(n):
        _, r, term, trunc, info = env.step(np.zeros(env.action_space.shape))
    assert trunc.all() and not term.any() and (r == 0).all()
    assert info["_success"].all() and (info["T_s"] == n * env.batch.dt).all()
    assert info["_is_success"].all() and not info["is_success"].any()


def test_gymnasium_check_env(coast):
    from gymnasium.utils.env_checker import check_env

    from oneocean.envs import OceanEnv

    check_env(OceanEnv("G2G", 1, coast), skip_render_check=True)


def test_pettingzoo_parallel_api(coast):
    from pettingzoo.test import parallel_api_test

    from oneocean.envs import parallel_env

    env = parallel_env("G2G", 1, coast)
    parallel_api_test(env, num_cycles=50)
    obs, _ = env.reset(seed=1)
    assert list(obs) == ["vehicle_0"] and obs["vehicle_0"].shape == (OBS_DIM + 2,)


def test_pettingzoo_multi_agent_team(coast):
    """A team task (FT, 3 vehicles) as a PettingZoo parallel env: one observation and one
    action per vehicle, teammates' offsets in every observation."""
    from pettingzoo.test import parallel_api_test

    from oneocean.envs import parallel_env

    env = parallel_env("FT", 1, coast, n_agents=3)
    parallel_api_test(env, num_cycles=30)
    obs, _ = env.reset(seed=2)
    assert list(obs) == ["vehicle_0", "vehicle_1", "vehicle_2"]
    mates = OBS_FIELDS.index("mate1_dx_m")
    for a in obs.values():
        assert a.shape == (OBS_DIM,) and np.hypot(*a[mates:mates + 2]) > 0  # a teammate
    out = env.step({a: np.zeros(3) for a in env.agents})
    assert all(set(d) == set(obs) for d in out)


def test_bad_policy_specs_fail_in_one_line():
    for spec, what in (("nomodule", "expected 'module:callable'"),
                       ("no_such_pkg_xyz:act", "cannot import"),
                       ("math:no_such_fn", "has no attribute"),
                       ("math:pi", "not callable")):
        with pytest.raises(ConfigError, match=what) as exc:
            load_policy(spec)
        assert "\n" not in str(exc.value)


def test_cli_evaluate_writes_the_cell_table(tmp_path, coast):
    from oneocean.io import write_npz_atomic

    grid = tmp_path / "grid.npz"
    write_npz_atomic(grid, make_test_grid(nt=5, nz=3, ny=30, nx=40, dt_s=3600.0))
    pol = tmp_path / "mypolicy.py"
    pol.write_text("import numpy as np\n"
                   "def act(obs):\n"
                   "    g = obs[..., :3]\n"
                   "    n = np.linalg.norm(g, axis=-1, keepdims=True)\n"
                   "    return 2.0 * g / np.maximum(n, 1e-9)\n")
    out = tmp_path / "mine.parquet"
    r = subprocess.run([sys.executable, "-m", "oneocean.cli", "evaluate", "--task", "G2G",
                        "--tier", "1", "--policy", "mypolicy:act", "--grid", str(grid),
                        "--episodes", "3", "--out", str(out)], cwd=tmp_path,
                       capture_output=True, text=True, env={**__import__("os").environ,
                                                            "PYTHONPATH": str(tmp_path)})
    assert r.returncode == 0, r.stderr
    df = pd.read_parquet(out)
    assert len(df) == 3 and (df["method"] == "act").all() and (df["task"] == "G2G").all()
    assert "SR" in r.stdout
    bad = subprocess.run([sys.executable, "-m", "oneocean.cli", "evaluate", "--task", "G2G",
                          "--tier", "1", "--policy", "mypolicy:nope", "--grid", str(grid),
                          "--out", str(tmp_path / "x.parquet")], cwd=tmp_path,
                         capture_output=True, text=True)
    assert bad.returncode == 2 and not (tmp_path / "x.parquet").exists()
    # the user's file joins Table V beside a workflow cell, with no registration first
    from oneocean.reporting.tables import task_success_table
    from oneocean.tasks import rollout_to_file
    from oneocean.vocab import EVALUATION_SEED

    heur = tmp_path / "heuristic.parquet"
    rollout_to_file(grid, heur, "G2G", 1, "heuristic", 3, EVALUATION_SEED, "6dof")
    long = task_success_table([heur, out], tmp_path / "t5.tex")
    row = long[(long["task"] == "G2G") & (long["method"] == "act")].iloc[0]
    assert row["label"] == "act" and row["n"] == 3
    assert np.isclose(row["sr"], 100.0 * df["success"].mean())
    assert row["lo"] <= row["sr"] <= row["hi"]
    assert "act T1" in (tmp_path / "t5.tex").read_text()


# ---------------------------------------------------------------------------------- RL use
def _toward_goal(obs, speed):
    g = obs[..., 0:3]
    return speed * g / np.maximum(np.linalg.norm(g, axis=-1, keepdims=True), 1e-9)


def _ends(env, steps, seed=3, speed=None):
    """Step ``env`` toward the goal cue; (step, sub-env, T_s) of every episode end and
    the observations."""
    obs, _ = env.reset(seed=seed)
    speed = env.v_max if speed is None else speed
    ends, hist = [], []
    for k in range(steps):
        obs, r, term, trunc, info = env.step(_toward_goal(obs, speed))
        hist.append(obs.copy())
        for j in np.flatnonzero(term | trunc):
            ends.append((k, int(j), float(info["T_s"][j])))
    return ends, np.array(hist), info


def test_next_step_autoreset_resets_on_the_following_step(coast):
    """The step after an episode ends returns the next episode's first observation with
    reward 0 and neither flag; the first episodes are the cell's (disabled mode's), and the
    whole run is reproducible for a seed."""
    from oneocean.envs import OceanVectorEnv

    def make(mode):
        return OceanVectorEnv("G2G", 1, coast, num_envs=2, autoreset_mode=mode, pool=2)

    env = make("next_step")
    n = OceanVectorEnv("G2G", 1, coast, num_envs=2, autoreset_mode="disabled")
    obs0, _ = env.reset(seed=4)
    np.testing.assert_array_equal(obs0, n.reset(seed=4)[0])
    steps = env.cell_steps
    for _ in range(steps):                       # zero action: every episode times out
        obs, r, term, trunc, info = env.step(np.zeros(env.action_space.shape))
    assert trunc.all() and not term.any()
    obs, r, term, trunc, info = env.step(np.full(env.action_space.shape, 9.0))
    assert (r == 0).all() and not term.any() and not trunc.any()
    assert set(info) == {"briefing", "_briefing"} and info["_briefing"].all()   # new episodes
    init = env.cell.reset(4, 4)                  # pool of 2 x 2: episodes 2, 3 come next
    np.testing.assert_allclose(obs[:, 0, [0, 2]],
                               (init["goal"] - init["pos0"][:, 0])[2:4][:, [0, 2]], atol=1.5)
    a, ha, _ = _ends(make("next_step"), 3 * steps)
    b, hb, _ = _ends(make("next_step"), 3 * steps)
    assert a == b and np.array_equal(ha, hb) and len(a) >= 4


def test_same_step_autoreset_returns_the_final_observation_in_info(coast):
    from oneocean.envs import OceanVectorEnv

    env = OceanVectorEnv("G2G", 1, coast, num_envs=2, autoreset_mode="same_step")
    env.reset(seed=0)
    for _ in range(env.cell_steps):
        obs, r, term, trunc, info = env.step(np.zeros(env.action_space.shape))
    assert trunc.all() and info["_final_obs"].all()
    assert info["final_obs"].shape == obs.shape and not np.array_equal(info["final_obs"], obs)
    assert info["final_info"]["_T_s"].all()
    # the new episodes run on: one more step ends nothing
    _, _, term, trunc, _ = env.step(np.zeros(env.action_space.shape))
    assert not (term | trunc).any()


def test_normalized_view_and_norm_bounded_action(coast):
    """The normalised observation is inside its Box and carries v_max and the time left; a
    normalised action's norm is clipped to 1 (x v_max), so every bound is reachable."""
    from oneocean.envs import NORM_FIELDS, OceanVectorEnv, normalize

    env = OceanVectorEnv("FT", 1, coast, num_envs=2, n_agents=3, obs_mode="normalized",
                         action_mode="normalized")
    obs, _ = env.reset(seed=1)
    assert obs.shape == (2, 3, len(NORM_FIELDS)) and env.observation_space.contains(obs)
    assert NORM_FIELDS[-5:] == ("v_max_ms", "time_left", "vx", "vy", "vz")
    assert np.allclose(obs[..., NORM_FIELDS.index("v_max_ms")], env.v_max)
    assert np.allclose(obs[..., NORM_FIELDS.index("time_left")], 1.0)
    assert env.action_space.low.min() == -1.0 and env.action_space.high.max() == 1.0
    v = env._to_velocity(np.broadcast_to([1.0, 0.0, 0.0], env.action_space.shape))
    np.testing.assert_allclose(v[..., 0], env.v_max)
    v = env._to_velocity(np.ones(env.action_space.shape))
    np.testing.assert_allclose(np.linalg.norm(v, axis=-1), env.v_max)
    for _ in range(5):
        obs, *_ = env.step(np.zeros(env.action_space.shape))
    assert np.allclose(obs[..., NORM_FIELDS.index("time_left")], 1.0 - 5 / env.cell_steps)
    raw = np.array([[30.0, 4.0, 40.0, 0.3, -0.1, 12.0, np.nan, np.nan]
                    + [5.0, 0.0] + [np.nan] * 4
                    + [100.0, 200.0, 0.3, 1.0, 0.5, -4.0, 600.0, 10.0, 0.0]    # x .. fix
                    + [np.e - 1.0, np.nan]])                                  # the task's own
    n = normalize(raw[None], 2.0, 1000.0, 1200.0)[0, 0]
    np.testing.assert_allclose(n[:3], np.array([30, 4, 40]) / (np.hypot(50, 4) + 10))
    np.testing.assert_allclose(n[3], np.log1p(np.hypot(50, 4)) / np.log1p(1000.0))
    np.testing.assert_allclose(n[4:9], [0.15, -0.05, 0.12, 1.0, 0.0])
    np.testing.assert_allclose(n[9:11], [5 / 15, 0.0])
    assert n[11:15].tolist() == [0, 0, 0, 0] and n[15] == 2.0 and n[16] == 0.5
    np.testing.assert_allclose(n[17:20], [0.5, 0.25, -2.0])      # ground velocity / v_max
    np.testing.assert_allclose(n[20:], [1.0, 0.0])              # sign(x) log(1 + |x|), NaN 0


def test_dense_reward_terms():
    """Progress toward the cue over the distance at the start (a cue jump counts 0), the
    energy over its scale, the allocation penalty, violations and near-collisions over the
    episode's steps, and 1 on success."""
    from oneocean.envs import dense_reward

    d0 = np.array([[100.0], [100.0], [100.0], [100.0]])
    r = dense_reward(d0, np.array([[50.0], [50.0], [50.0], [50.0]]),
                     np.array([[49.0], [50.0], [90.0], [50.0]]), np.array([0, 2, 0, 0]),
                     np.array([0, 0, 1, 0]), np.array([False, False, True, False]),
                     np.array([False, False, False, True]), np.array([0.0, 10.0, 0.0, 0.0]),
                     np.full(4, 100.0), 200, 2.0)
    np.testing.assert_allclose(r, [0.5 * 1 / 100, -0.5 * 0.1 - 2 / 200, 1.0 - 1 / 200, -1.0])


def test_dense_reward_sums_stay_within_their_weights_and_success_pays_most(coast):
    """Over an episode the progress terms add up to at most PROGRESS_WEIGHT and the energy
    terms to the energy over its scale (the allocation where the task has one): a successful
    episode earns more than a failed one. The metrics and ``is_success`` in info are the
    task's own, whatever the reward."""
    from oneocean.envs import ENERGY_WEIGHT, PROGRESS_WEIGHT, OceanVectorEnv

    env = OceanVectorEnv("G2G", 1, coast, num_envs=3, reward="dense",
                         autoreset_mode="disabled")
    obs, _ = env.reset(seed=2)
    total = np.zeros(3)
    done = np.zeros(3, dtype=bool)
    while not done.all():
        obs, r, term, trunc, info = env.step(_toward_goal(obs, 1.25))
        total += np.where(done, 0.0, r)
        done |= term | trunc
    res = env.batch.results()
    used = res["energy_wh"] * 3600.0
    alloc = env.batch.B.energy_allocation
    expect = (PROGRESS_WEIGHT * (1.0 - res["final_error_m"] / env._d0[:, 0])
              - ENERGY_WEIGHT * used / alloc - (used > alloc) + res["success"])
    np.testing.assert_allclose(total, expect, atol=0.02)
    assert total[res["success"]].min() > max(total[~res["success"]].max(initial=-9), 0.5)


def test_rgb_render_shows_land_water_and_agents(coast):
    from oneocean.envs import OceanEnv
    from oneocean.reporting.render import AGENT_RGB, LAND_RGB

    env = OceanEnv("G2G", 1, coast, render_mode="rgb_array")
    env.reset(seed=0)
    img = env.render()
    assert img.dtype == np.uint8 and img.ndim == 3 and img.shape[2] == 3
    assert max(img.shape[:2]) >= 200
    assert (img == AGENT_RGB).all(-1).sum() >= 9                 # the vehicle's 5 x 5 mark
    land = (img == LAND_RGB.astype(np.uint8)).all(-1).mean()
    assert 0.0 < land < 1.0 and np.isclose(land, np.asarray(coast.land >= 0.5).mean(), atol=0.05)
    assert OceanEnv("G2G", 1, coast).render() is None           # no render mode: nothing


def test_bad_env_options_fail_in_one_line(coast):
    from oneocean.envs import OceanVectorEnv

    for kw, what in (({"autoreset_mode": "sometimes"}, "autoreset_mode"),
                     ({"obs_mode": "pixels"}, "obs_mode"), ({"reward": "shaped"}, "reward"),
                     ({"action_mode": "torque"}, "action_mode"),
                     ({"render_mode": "human"}, "render_mode")):
        with pytest.raises(ConfigError, match=what) as exc:
            OceanVectorEnv("G2G", 1, coast, num_envs=1, **kw)
        assert "\n" not in str(exc.value)


# ------------------------------------------------------------ ecosystem checkers, every task
ALL_TASKS = ("G2G", "SK", "RF", "DPT", "AS", "PI", "FT", "SPC", "UPL", "FH")


@pytest.fixture(scope="module")
def default_grid():
    """The default region's grid (what an env without a grid uses)."""
    from oneocean.product.defaults import resolve_grid

    return resolve_grid(None)


@pytest.mark.parametrize("task", ALL_TASKS)
def test_every_task_passes_gymnasium_check_env(task, default_grid):
    from gymnasium.utils.env_checker import check_env

    from oneocean.envs import OceanEnv

    env = OceanEnv(task, 1, default_grid, obs_mode="normalized", action_mode="normalized",
                   render_mode="rgb_array")
    check_env(env)
    obs, _ = env.reset(seed=7)
    assert env.observation_space.contains(obs)


@pytest.mark.parametrize("task", ALL_TASKS)
def test_every_task_passes_pettingzoo_api_and_seed_tests(task, default_grid):
    from pettingzoo.test import parallel_api_test, parallel_seed_test

    from oneocean.envs import parallel_env

    parallel_api_test(parallel_env(task, 1, default_grid), num_cycles=20)
    parallel_seed_test(lambda: parallel_env(task, 1, default_grid), num_cycles=20)


def test_gymnasium_ids_make_the_envs(default_grid):
    import gymnasium as gym

    import oneocean  # noqa: F401  (registers the ids)

    env = gym.make("OneOcean/SK-T2-v0", grid=default_grid)
    assert env.spec.id == "OneOcean/SK-T2-v0" and env.unwrapped.venv.tier == 2
    venv = gym.make_vec("OneOcean/G2G-T1-v0", num_envs=3, grid=default_grid,
                        vectorization_mode="vector_entry_point")
    obs, _ = venv.reset(seed=1)
    assert obs.shape[0] == 3 and venv.metadata["autoreset_mode"].name == "NEXT_STEP"


def test_gymnasium_vector_wrappers_accept_the_vector_env(default_grid):
    """Gymnasium's vector wrappers that need NEXT_STEP autoreset take the env as it is."""
    from gymnasium.wrappers.vector import NormalizeObservation, RecordEpisodeStatistics

    from oneocean.envs import OceanVectorEnv

    env = RecordEpisodeStatistics(NormalizeObservation(
        OceanVectorEnv("SK", 1, default_grid, num_envs=4, obs_mode="normalized")))
    obs, _ = env.reset(seed=0)
    for _ in range(5):
        obs, r, term, trunc, info = env.step(np.zeros(env.action_space.shape))
    assert np.isfinite(obs).all() and obs.shape == (4, 1, 20)      # SK: no fields of its own


def test_a_seed_the_cell_cannot_host_moves_on_to_the_next_pool_seed(default_grid):
    """UPL tier 1 finds no episode in its current regime among seed 14's candidates on the
    default region: an env moves on to the next pool seed; evaluation (strict) says so."""
    from oneocean.envs import OceanVectorEnv, pool_seed
    from oneocean.errors import NotApplicable

    strict = OceanVectorEnv("UPL", 1, default_grid, num_envs=1, autoreset_mode="disabled",
                            strict_seed=True)
    with pytest.raises(NotApplicable, match="current regime"):
        strict.reset(seed=14)
    env = OceanVectorEnv("UPL", 1, default_grid, num_envs=1, autoreset_mode="disabled")
    obs, _ = env.reset(seed=14)
    served = next(i for i in range(1, 16)
                  if _hosts(env.cell, pool_seed(14, i)))
    init = env.cell.reset(1, pool_seed(14, served))
    np.testing.assert_array_equal(env.batch.state[0, :, :3], init["pos0"][0])
    assert np.isfinite(obs).all()


def _hosts(cell, seed) -> bool:
    from oneocean.errors import NotApplicable

    try:
        cell.reset(1, seed)
        return True
    except NotApplicable:
        return False


# ------------------------------------------------------------ the fused step, the run's forcing
def _trace(env, steps, seed, rng_seed=0):
    """Every output of a reset and ``steps`` steps (sub-env 0 heads for its goal cue and ends
    early, the others act at random), for equality checks."""
    rng = np.random.default_rng(rng_seed)
    obs = env.reset(seed=seed)[0]
    out = [obs]
    ends = 0
    for _ in range(steps):
        a = rng.uniform(-1.0, 1.0, env.action_space.shape) * env.action_space.high
        a[0] = env.v_max * obs[0, :, 0:3] / np.maximum(
            np.linalg.norm(obs[0, :, 0:3], axis=-1, keepdims=True), 1e-9)
        obs, r, term, trunc, info = env.step(a)
        out += [obs, r, term, trunc]
        out += [np.asarray(info[k]) for k in sorted(info)
                if not isinstance(info[k], (dict, tuple))]
        for b in info.get("briefing", ()):     # the new episodes' briefings, field by field
            if b is not None:
                out += [np.asarray(v) for v in b if isinstance(v, (np.ndarray, float, int))]
        ends += int((term | trunc).sum())
    return out, ends


@pytest.mark.parametrize("view", [("raw", "velocity", "sparse"),
                                  ("normalized", "normalized", "dense")])
@pytest.mark.parametrize("mode", ["next_step", "same_step", "disabled"])
def test_fused_step_equals_run_then_observe(coast, monkeypatch, mode, view):
    """``step`` advances and observes in one compiled call (the actions written, the raw
    view's undefined values zeroed and the end flags read in the kernel too:
    ``Episodes.env_step``); it gives exactly what the Python path with the two calls it
    replaces gives (``run(-1)``, then ``observe``), over autoresets across several pools,
    with sub-envs on different episodes, in both views and with both rewards."""
    from oneocean import envs

    obs_mode, action_mode, reward = view

    def make(n):
        return envs.OceanVectorEnv("G2G", 1, coast, num_envs=n, autoreset_mode=mode, pool=1,
                                   obs_mode=obs_mode, action_mode=action_mode, reward=reward)

    env = make(3)
    env.reset(seed=5)
    steps = env.cell_steps + (5 if mode == "disabled" else env.cell_steps // 2)
    fused = [_trace(make(n), steps, 5) for n in (3, 1)]

    def two_calls(batch, lo, hi):
        batch.run(-1)
        return batch.observe()

    monkeypatch.setattr(envs, "_step_observe", two_calls)
    monkeypatch.setattr(envs.OceanVectorEnv, "_fused_env_step", lambda *a: None)
    plain = [_trace(make(n), steps, 5) for n in (3, 1)]
    for (f, ends), (p, _) in zip(fused, plain):
        assert len(f) == len(p)
        for x, y in zip(f, p):
            np.testing.assert_array_equal(x, y)
    assert fused[0][1] >= 3


def test_the_step_moves_each_agent_in_the_current_its_observation_sampled(coast):
    """The true current each agent's move meets is the one sampled when its observation was
    taken (the step's start: ``LS.cw``), so an observation and its step agree; a different
    current there moves the agents differently."""
    from oneocean.envs import OceanVectorEnv

    def trace(poison):
        env = OceanVectorEnv("G2G", 1, coast, num_envs=2, autoreset_mode="disabled")
        out = [env.reset(seed=3)[0]]
        for _ in range(6):
            if poison:
                env.batch.LS.cw[...] = 5.0
            out.append(env.step(np.full(env.action_space.shape, 0.4))[0])
        return np.array(out)

    clean = trace(False)
    np.testing.assert_array_equal(trace(False), clean)
    assert not np.array_equal(trace(True), clean)


def test_evaluate_runs_the_forcing_it_is_given(coast):
    """``current_gain`` and ``tide`` reach the rollout: replaying the heuristic's actions of
    a forced cell through ``evaluate`` with the same forcing gives that cell's metrics (and
    differs from the unforced cell)."""
    tide = {"amplitude_ms": 0.2, "period_s": 44712.0}
    forced, _, act = run_cell(coast, "G2G", 1, "heuristic", episodes=3, seed=2,
                              dynamics="6dof", observations=True, current_gain=1.5, tide=tide)
    df = evaluate(Replay(act), "G2G", 1, coast, episodes=3, seed=2, current_gain=1.5,
                  tide=tide)
    pd.testing.assert_frame_equal(df[METRIC_COLS], forced[METRIC_COLS])
    plain = evaluate(Replay(act), "G2G", 1, coast, episodes=3, seed=2)
    # the same actions in other water: the currents the vehicle met differ
    assert (forced["current_speed_ms"] != plain["current_speed_ms"]).all()


def test_evaluate_gives_a_normalized_policy_the_envs_view(coast):
    """A policy that declares ``obs_mode``/``action_mode = "normalized"`` gets the env's
    normalised observations (what it trained on) and its actions are read in units of
    ``v_max``: full speed east normalised equals v_max east in m/s, episode by episode."""
    from oneocean.envs import NORM_DIM, OceanVectorEnv

    class East:
        obs_mode = action_mode = "normalized"

        def __init__(self):
            self.seen = []

        def __call__(self, obs):
            self.seen.append(obs.copy())
            a = np.zeros(obs.shape[:2] + (3,))
            a[..., 0] = 1.0
            return a

    pol = East()
    norm = evaluate(pol, "G2G", 1, coast, episodes=3, seed=1)
    v_max = OceanVectorEnv("G2G", 1, coast, num_envs=1).v_max
    vel = evaluate(lambda o: np.broadcast_to([v_max, 0.0, 0.0], o.shape[:2] + (3,)),
                   "G2G", 1, coast, episodes=3, seed=1)
    pd.testing.assert_frame_equal(norm[METRIC_COLS], vel[METRIC_COLS])
    env = OceanVectorEnv("G2G", 1, coast, num_envs=3, autoreset_mode="disabled",
                         obs_mode="normalized")
    np.testing.assert_array_equal(pol.seen[0], env.reset(seed=1)[0])
    assert pol.seen[0].shape == (3, 1, NORM_DIM + 2)          # G2G's own two fields


def _pool_env(task, grid, whole, **kw):
    """A Tier-1 vector env of ``task`` that builds its pools in parts, or with ``whole`` each
    pool seed's episodes at once (the baseline of the equality checks)."""
    from oneocean.envs import OceanVectorEnv

    env = OceanVectorEnv(task, 1, grid, **kw)
    if whole:
        env._part = env.pool_size
    return env


@pytest.mark.parametrize("mode", ["next_step", "same_step"])
def test_pools_built_in_parts_give_the_same_episodes(coast, mode):
    """A reset builds only the episodes the sub-envs start on; the rest of the pool seed's
    episodes are built, ``num_envs`` at a time, when the sub-envs reach them. Every output
    over autoresets through several parts and pool seeds equals that of the same env building
    each pool seed's episodes at once, and the parts are the cell's episodes."""
    def make(whole):
        return _pool_env("G2G", coast, whole, num_envs=2, autoreset_mode=mode, pool=3)

    env = make(False)
    assert env.cell.chunked
    env.reset(seed=5)
    assert [p.rows for p in env._pools] == [(0, 2)]           # not the pool's 6 episodes
    init = env.cell.reset(6, 5)
    np.testing.assert_array_equal(env._pools[0].batch.t0, init["t0"][:2])
    steps = env.cell_steps // 2
    parts, whole = _trace(make(False), steps, 5), _trace(make(True), steps, 5)
    assert parts[1] == whole[1] >= 5                   # episodes ended: into the 2nd pool seed
    assert len(parts[0]) == len(whole[0])
    for x, y in zip(parts[0], whole[0]):
        np.testing.assert_array_equal(x, y)
    env = make(False)
    _trace(env, steps, 5)
    assert env._n_pools == 2 and env._tail.rows == (0, 2)


def test_a_task_with_cell_wide_values_builds_its_pools_in_parts(default_grid):
    """PI's episodes share values computed on the whole pool (``cell_constants``: the plume
    field's shape). Its pools are built a part at a time too, from the whole pool's reset
    dict (drawn once per seed): every part equals those rows of the whole pool, bit for bit,
    and building a part again (a second reset on the same seed) gives the same episodes."""
    from oneocean.envs import _Cell

    assert _Cell("PI", 1, default_grid).chunked
    env = _pool_env("PI", default_grid, False, num_envs=3, pool=2)
    env.reset(seed=4)
    assert [p.rows for p in env._pools] == [(0, 3)]
    init = env.cell.reset(6, 4)
    later = env._next_pool()                         # the seed's episodes 3 .. 5
    assert later.rows == (3, 6)
    for pool, rows in ((env._pools[0], slice(0, 3)), (later, slice(3, 6))):
        np.testing.assert_array_equal(pool.batch.t0, init["t0"][rows])
        np.testing.assert_array_equal(pool.batch.W.leaks, init["leaks"][rows])
        np.testing.assert_array_equal(pool.batch.W.rate, init["leak_rate"][rows])
        assert pool.batch.W.C.shape[2:] == tuple(init["field_shape"][::-1])
    at_once = _pool_env("PI", default_grid, True, num_envs=3, pool=2)
    first = env.reset(seed=4)[0]
    np.testing.assert_array_equal(first, at_once.reset(seed=4)[0])
    for name in ("C", "frame", "leak_loc", "land", "uf", "vf"):
        np.testing.assert_array_equal(getattr(env._pools[0].batch.W, name),
                                      getattr(at_once._pools[0].batch.W, name)[:3])
    # over autoresets through the parts of two pool seeds: every output is the same
    steps = 3 * env.cell_steps
    parts, whole = (_trace(_pool_env("PI", default_grid, w, num_envs=2, pool=2), steps, 3)
                    for w in (False, True))
    assert parts[1] == whole[1] >= 4                   # into the second pool seed
    for x, y in zip(parts[0], whole[0]):
        np.testing.assert_array_equal(x, y)
