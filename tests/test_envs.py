"""The step API (Gymnasium vector env, single-env view, PettingZoo parallel env) and
``evaluate``: same episodes, loop and metrics as the fused rollouts."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from oneocean import engine as E
from oneocean.errors import ConfigError
from oneocean.evaluate import evaluate, load_policy
from oneocean.tasks import run_cell
from oneocean.tasks.common import OBS_DIM, OBS_FIELDS
from oneocean.testing import make_test_grid

METRIC_COLS = ["success", "T_s", "E", "coll_ratio", "violations", "current_speed_ms", "primary"]


@pytest.fixture(scope="module")
def coast():
    return E.load_grid(make_test_grid(nt=5, nz=3, ny=30, nx=40, dt_s=3600.0))


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

    env = OceanVectorEnv("G2G", 1, coast, num_envs=3)
    assert env.metadata["autoreset_mode"] == AutoresetMode.DISABLED
    obs, info = env.reset(seed=5)
    assert obs.shape == (3, 1, OBS_DIM) == env.observation_space.shape
    obs2, _ = env.reset(seed=5)
    np.testing.assert_array_equal(obs, obs2)            # same seed, same episodes
    # the goal cue is the goal relative to where the vehicle thinks it is: the true offset
    # up to its start fix (0.5 m per horizontal axis, truncated at 3 sigma; depth is measured)
    init = env.cell.reset(3, 5)
    err = obs[:, 0, :3] - (init["goal"] - init["pos0"][:, 0])
    assert np.all(np.abs(err[:, [0, 2]]) <= 1.5) and np.any(np.abs(err[:, [0, 2]]) > 1e-3)
    np.testing.assert_allclose(err[:, 1], 0.0, atol=1e-9)
    a = np.zeros(env.action_space.shape)
    obs, r, term, trunc, info = env.step(a)
    assert r.shape == term.shape == trunc.shape == (3,)
    assert not term.any() and not trunc.any() and info == {}
    assert OBS_FIELDS[0] == "goal_dx_m" and env.obs_fields == OBS_FIELDS


def test_episode_end_reports_metrics_in_info(coast):
    from oneocean.envs import OceanVectorEnv

    env = OceanVectorEnv("G2G", 1, coast, num_envs=2)
    env.reset(seed=0)
    n = env.batch.n_steps
    for k in range(n):
        _, r, term, trunc, info = env.step(np.zeros(env.action_space.shape))
    assert trunc.all() and not term.any() and (r == 0).all()
    assert info["_success"].all() and (info["T_s"] == n * env.batch.dt).all()


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
    assert list(obs) == ["vehicle_0"] and obs["vehicle_0"].shape == (OBS_DIM,)


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
