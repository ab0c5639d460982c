"""Reinforcement learning through the step API: the Stable-Baselines3 adapter, the PPO
baseline (train -> save -> load -> evaluate -> cell file -> Table V), its training seeds,
the SuperSuit example and the workflow's rl stage."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

pytest.importorskip("torch")
pytest.importorskip("stable_baselines3")

from oneocean.envs import NORM_DIM, NORM_FIELDS, OceanEnv, OceanVectorEnv  # noqa: E402
from oneocean.errors import ConfigError  # noqa: E402
from oneocean.registry import builtin_task_ids  # noqa: E402
from oneocean.vocab import EVALUATION_SEED  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
MODES = {"obs_mode": "normalized", "action_mode": "normalized", "reward": "dense"}
#: SB3's advisories about OceanEnv's (N, D) observation and float64 action spaces (the
#: adapter gives SB3 one agent's 1-D Box): not failures.
ADVISORIES = ("unconventional shape", "action space has dtype float64")


@pytest.fixture(scope="module")
def grid():
    from oneocean.product.defaults import resolve_grid

    return resolve_grid(None)


@pytest.fixture(scope="module")
def grid_path():
    from oneocean.product.defaults import default_grid_path

    return default_grid_path()


@pytest.fixture(autouse=True)
def _sb3_logs_in_tmp(tmp_path, monkeypatch):
    """SB3's default logger makes a ``<tempdir>/SB3-<date>`` folder per ``learn``: the tests
    that train through SB3 directly keep it in their own temporary folder."""
    monkeypatch.setenv("SB3_LOGDIR", str(tmp_path / "sb3_logs"))


def _torch_one_thread():
    import torch

    torch.set_num_threads(1)


# ------------------------------------------------------------------ SB3's own checker

@pytest.mark.parametrize("task", builtin_task_ids())
def test_sb3_check_env_on_every_task(task, grid):
    from stable_baselines3.common.env_checker import check_env

    env = OceanEnv(task, 1, grid, obs_mode="normalized", action_mode="normalized")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env)
    other = [str(w.message) for w in caught
             if not any(a in str(w.message) for a in ADVISORIES)]
    assert not other, other


# ------------------------------------------------------------------ the adapter

def test_ppo_runs_on_the_adapter_without_other_wrappers(grid):
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecEnv

    from oneocean.sb3 import SB3VecEnv

    venv = OceanVectorEnv("G2G", 1, grid, num_envs=8, autoreset_mode="same_step", **MODES)
    env = SB3VecEnv(venv)
    assert isinstance(env, VecEnv) and env.num_envs == 8
    assert env.observation_space.shape == (venv.single_observation_space.shape[-1],)
    assert env.action_space.shape == (3,)
    _torch_one_thread()
    model = PPO("MlpPolicy", env, n_steps=32, batch_size=64, n_epochs=2, seed=1, device="cpu")
    model.learn(256)
    assert model.num_timesteps == 256
    # a team task: one row per vehicle, one shared policy, every agent the team's reward
    ft = OceanVectorEnv("FT", 1, grid, num_envs=2, autoreset_mode="same_step", **MODES)
    team = SB3VecEnv(ft)
    assert team.num_envs == 2 * ft.n_agents
    team.seed(3)
    obs = team.reset()
    assert obs.shape == (team.num_envs, team.observation_space.shape[0])
    _, r, d, _ = team.step(np.zeros((team.num_envs, 3)))
    assert np.all(r.reshape(2, ft.n_agents) == r.reshape(2, ft.n_agents)[:, :1])
    PPO("MlpPolicy", team, n_steps=16, batch_size=40, n_epochs=1, seed=1,
        device="cpu").learn(320)


def test_adapter_attributes_seed_render_and_wrong_mode(grid):
    from oneocean.sb3 import SB3VecEnv

    venv = OceanVectorEnv("SK", 1, grid, num_envs=3, autoreset_mode="same_step",
                          render_mode="rgb_array", **MODES)
    env = SB3VecEnv(venv)
    assert env.get_attr("task") == ["SK"] * 3 and env.get_attr("tier", [1]) == [1]
    assert env.env_is_wrapped(object) == [False] * 3
    env.set_attr("note", "x")
    assert venv.note == "x"
    imgs = env.env_method("render", indices=[0, 2])     # one call per vector env
    assert len(imgs) == 2 and imgs[0] is imgs[1]
    env.seed(11)
    a = env.reset()
    env.seed(11)
    b = env.reset()
    c = env.reset()                         # unseeded: the env's own generator
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    img = env.render()
    assert img.ndim == 3 and img.dtype == np.uint8
    env.close()
    with pytest.raises(ValueError, match="same_step"):
        SB3VecEnv(OceanVectorEnv("SK", 1, grid, num_envs=2, **MODES))


def test_forced_timeout_gives_sb3_terminal_values(grid):
    """Zero actions until the time limit: SB3's done, terminal_observation (the env's
    final_obs), TimeLimit.truncated, is_success and the metric columns."""
    from oneocean.sb3 import SB3VecEnv

    kw = dict(num_envs=2, autoreset_mode="same_step", **MODES)
    env = SB3VecEnv(OceanVectorEnv("SK", 3, grid, **kw))
    twin = OceanVectorEnv("SK", 3, grid, **kw)       # the same episodes, seen directly
    env.seed(5)
    obs = env.reset()
    tobs, _ = twin.reset(seed=5)
    np.testing.assert_array_equal(obs, tobs.reshape(2, -1))
    zero = np.zeros((2, 3))
    ret = np.zeros(2)
    for k in range(1, 100_000):
        obs, rew, done, infos = env.step(zero)
        tobs, trew, tterm, ttrunc, tinfo = twin.step(zero.reshape(2, 1, 3))
        np.testing.assert_array_equal(rew, trew.astype(np.float32))
        ret += trew
        if done.any():
            break
    steps = twin.cell_steps
    assert k == steps and done.all()                 # the time limit, not the task, ended it
    assert ttrunc.all() and not tterm.any()
    final = tinfo["final_obs"]
    for j, info in enumerate(infos):
        assert info["TimeLimit.truncated"] is True and info["is_success"] is False
        np.testing.assert_array_equal(info["terminal_observation"], final[j, 0])
        left = NORM_FIELDS.index("time_left")
        assert info["terminal_observation"][left] == 0.0         # no time left
        assert obs[j][left] == 1.0                               # the next episode began
        for col in ("success", "T_s", "E", "coll_ratio", "violations", "rms_error_m"):
            assert info[col] == pytest.approx(float(tinfo[col][j]))
        assert info["episode"]["l"] == steps
        assert info["episode"]["r"] == pytest.approx(ret[j])


# ------------------------------------------------------------------ the PPO baseline

def test_training_seeds_exclude_the_evaluation_seed():
    from oneocean.config import load_config
    from oneocean.methods.ppo.train import (TRAINING_SEEDS, check_training_seeds,
                                            episode_seeds)

    assert EVALUATION_SEED not in TRAINING_SEEDS
    assert check_training_seeds([0, 7]) == [0, 7]
    for bad, what in ((EVALUATION_SEED, "evaluation seed"), (1500, "outside"),
                      (-1, "outside")):
        with pytest.raises(ConfigError, match=what):
            check_training_seeds([bad])
    with pytest.raises(ConfigError, match="evaluation seed"):
        check_training_seeds([3], evaluation_seeds=(1000, 3))
    # every episode seed a run draws (per tier block, per pool) is a training seed's own
    used = episode_seeds(0, 3, 200)
    assert used[0] == 0 and EVALUATION_SEED not in used and len(set(used)) == len(used)
    with pytest.raises(ConfigError, match="rl.seeds"):
        load_config(REPO / "config" / "config.yaml", overrides={"rl": {"seeds": [1000]}})
    assert load_config(REPO / "config" / "config.yaml")["rl"]["seeds"] == [0]


def test_policy_constants_match_the_env(grid):
    from oneocean.methods.ppo.policy import episode_constants

    for task, tier in (("G2G", 1), ("SK", 3), ("DPT", 2)):
        env = OceanVectorEnv(task, tier, grid, num_envs=1, **MODES)
        env.reset(seed=0)
        c = episode_constants(task, tier)
        assert (c["v_max"], c["reach"], c["n_steps"]) == (env.v_max, env.reach,
                                                          env.cell_steps)


def test_train_save_load_evaluate_round_trip(grid_path, tmp_path, monkeypatch):
    from oneocean.reporting.cells import read_cell
    from oneocean.methods.ppo.policy import METHOD, evaluate_to_file, load
    from oneocean.methods.ppo.train import read_report, train_to_files
    from oneocean.registry import METHOD_KINDS, method_spec
    from oneocean.reporting.tables import task_success_ci_frame, task_success_table
    from oneocean.tasks import rollout_to_file

    assert method_spec("ppo") is METHOD and METHOD.kind == "callable" in METHOD_KINDS
    small = {"n_steps": 32, "batch_size": 32, "n_epochs": 1}
    # training leaves no empty SB3-<date> folder in the temporary directory
    import tempfile

    monkeypatch.delenv("SB3_LOGDIR")
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    paths = []
    for run in ("a", "b"):
        d = tmp_path / run
        rep = train_to_files(grid_path, d / "policy.zip", d / "report.json", "SK",
                             tiers=[3], budget_steps=64, n_envs=2, seeds=[0],
                             ppo_kwargs=small)
        evaluate_to_file(d / "policy.zip", grid_path, d / "ppo.parquet", "SK", 3, episodes=3)
        paths.append(d)
    a, b = paths
    assert not list((tmp_path / "tmp").glob("SB3-*"))
    # nothing in the zip that differs between processes or machines: SB3's class
    # descriptions without memory addresses, its system info without the OS line
    with zipfile.ZipFile(a / "policy.zip") as z:
        assert b"ActorCriticPolicy" in z.read("data") and b" at 0x" not in z.read("data")
        info = z.read("system_info.txt").decode()
        assert "Stable-Baselines3:" in info and "- OS:" not in info
    assert (a / "policy.zip").read_bytes() == (b / "policy.zip").read_bytes()
    assert (a / "ppo.parquet").read_bytes() == (b / "ppo.parquet").read_bytes()
    # the report is hash-tracked: no wall time, the same bytes
    assert (a / "report.json").read_bytes() == (b / "report.json").read_bytes()
    rep = read_report(a / "report.json")
    assert rep["budget_steps"] == 64 and rep["seeds"] == [0] and rep["selected_seed"] == 0
    assert EVALUATION_SEED in rep["evaluation_seeds_excluded"]
    assert rep["env"]["obs_mode"] == "normalized" and rep["env"]["reward"] == "dense"
    curve = rep["runs"][0]["curve"]
    assert len(curve) == 1 and curve[0]["timesteps"] == 64
    assert {"success_rate", "mean_reward", "mean_episode_return"} <= set(curve[0])
    assert "final_success" in rep and "wall_time_s" not in rep
    # the cell: the standard columns of a rollout cell, the policy's own actions
    heur = tmp_path / "heuristic.parquet"
    rollout_to_file(grid_path, heur, "SK", 3, "heuristic", 3, EVALUATION_SEED, "6dof")
    df, cell = read_cell(a / "ppo.parquet")
    ref = pd.read_parquet(heur)
    assert list(df.columns) == list(ref.columns) and list(df.dtypes) == list(ref.dtypes)
    assert len(df) == 3 and (df["method"] == "ppo").all() and (df["seed"] == 1000).all()
    assert cell["method"] == "ppo" and cell["forcing"] == "data" and cell["applicable"]
    assert list(df["candidate"]) == list(ref["candidate"])          # the same episodes
    pol = load(a / "policy.zip", "SK", 3)
    pol.reset(None)
    # it declares the views it trained on: the env's normalised observation in, the action
    # in units of v_max out (inside the Box; the env clips its norm to 1)
    assert pol.obs_mode == "normalized" and pol.action_mode == "normalized"
    act = pol(np.zeros((2, 1, NORM_DIM)))                        # SK: no fields of its own
    assert act.shape == (2, 1, 3) and np.all(np.abs(act) <= 1.0)
    # Table V: a PPO row (SR, Wilson interval) only when its cells exist
    long = task_success_table([heur, a / "ppo.parquet"], tmp_path / "t5.tex")
    row = long[(long["task"] == "SK") & (long["method"] == "ppo")].iloc[0]
    assert row["label"] == "PPO" and row["n"] == 3
    assert row["lo"] - 1e-9 <= row["sr"] <= row["hi"] + 1e-9 and row["hi"] > 0
    assert "PPO T3" in (tmp_path / "t5.tex").read_text()
    without = task_success_ci_frame([heur])
    assert "ppo" not in set(without["method"])


_TRAIN_IN_A_PROCESS = """
import sys
from oneocean.methods.ppo.train import train_to_files
train_to_files(sys.argv[1], sys.argv[2], sys.argv[3], "SK", tiers=[1], budget_steps=128,
               n_envs=2, seeds=[0], ppo_kwargs={"n_steps": 32, "batch_size": 32, "n_epochs": 2})
"""


def test_training_gives_the_same_bytes_on_another_cpu(grid_path, tmp_path):
    """Training in a fresh process gives the same policy.zip bytes with MKL restricted to
    SSE4.2 (a CPU without AVX, as another machine would run it) as with its own choice
    for this CPU: torch's machine-independent settings are in force (``pin_torch_cpu``),
    and the zip holds no memory address. Fails without the pin (MKL's products differ)."""
    import json
    import os

    out = []
    for name, extra in (("native", {}), ("sse42", {"MKL_ENABLE_INSTRUCTIONS": "SSE4_2"})):
        d = tmp_path / name
        env = {k: v for k, v in os.environ.items() if k not in ("ATEN_CPU_CAPABILITY",
                                                                 "MKL_CBWR")}
        run = subprocess.run([sys.executable, "-c", _TRAIN_IN_A_PROCESS, str(grid_path),
                              str(d / "policy.zip"), str(d / "report.json")],
                             env={**env, **extra}, capture_output=True, text=True, timeout=900)
        assert run.returncode == 0, run.stderr[-2000:]
        out.append(d)
    a, b = out
    assert (a / "policy.zip").read_bytes() == (b / "policy.zip").read_bytes()
    assert (a / "report.json").read_bytes() == (b / "report.json").read_bytes()
    cpu = json.loads((a / "report.json").read_text())["runs"][0]["torch_cpu"]
    assert cpu == {"cpu_capability": "DEFAULT", "mkl_cbwr": "COMPATIBLE"}


def test_no_macro_for_a_method_run_on_some_tasks(grid_path, tmp_path):
    """A PPO cell of one task beside the heuristic's of two: PPO has its per-task row and no
    macro (never a mean over other tasks than the rest of the row's)."""
    from oneocean.reporting.tables import task_success_frame, task_success_table
    from oneocean.tasks import rollout_to_file

    files = []
    for task in ("SK", "DPT"):
        f = tmp_path / f"{task}_h.parquet"
        rollout_to_file(grid_path, f, task, 3, "heuristic", 2, EVALUATION_SEED, "6dof")
        files.append(f)
    ppo = tmp_path / "SK_ppo.parquet"
    df = pd.read_parquet(files[0])
    df["method"] = "ppo"
    from oneocean.engine import read_metrics_meta, write_metrics

    write_metrics(df, ppo, meta={**read_metrics_meta(files[0]), "method": "ppo"})
    long = task_success_table(files + [ppo], tmp_path / "t.tex")
    mac = long[long["task"] == "Macro"]
    assert set(mac["method"]) == {"heuristic"}
    assert "No macro for a method run on only some of the tasks (PPO T3: 1 of the 2 tasks)" \
        in (tmp_path / "t.tex").read_text()
    wide = task_success_frame(files + [ppo]).set_index("Task")
    assert np.isnan(wide.loc["Macro", "PPO T3"]) and not np.isnan(wide.loc["SK", "PPO T3"])


# ------------------------------------------------------------------ the SuperSuit example

def test_supersuit_example_runs():
    pytest.importorskip("supersuit")
    spec = importlib.util.spec_from_file_location("supersuit_ft",
                                                  REPO / "examples" / "supersuit_ft.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    out = mod.main(["--steps", "64", "--n-steps", "4", "--copies", "1", "--evaluate", "1"])
    assert out["timesteps"] >= 64 and out["rows"] >= 2 and 0.0 <= out["success_rate"] <= 1.0


# ------------------------------------------------------------------ the workflow's rl stage

def _dry_run(tmp_path, target, config):
    import yaml

    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(yaml.safe_dump(config))
    out = subprocess.run([sys.executable, "-m", "snakemake", "-n", "--snakefile",
                          str(REPO / "Snakefile"), "--directory", str(tmp_path),
                          "--configfile", str(REPO / "config" / "config.yaml"), str(cfg),
                          "--", target], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-2000:]
    stats = out.stdout.split("Job stats:")[-1]
    return {ln.split()[0]: int(ln.split()[1]) for ln in stats.splitlines()
            if len(ln.split()) == 2 and ln.split()[1].isdigit()}


def test_rl_baselines_is_its_own_target(tmp_path):
    sys.path.insert(0, str(REPO / "tests"))
    from workflow_helpers import SMALL_CONFIG

    cfg = {**SMALL_CONFIG, "rl": {"tasks": ["G2G", "SK"], "tiers_train": [1],
                                  "tiers_eval": [1, 3], "budget_steps": 64, "n_envs": 1}}
    jobs = _dry_run(tmp_path, "rl_baselines", cfg)
    assert jobs["rl_train"] == 2 and jobs["rl_cell"] == 4
    assert jobs["table_task_success_rl"] == 1 and jobs["manifest_rl"] == 1
    assert jobs["figure_rl_curves"] == 1
    paper = _dry_run(tmp_path, "paper_tables", cfg)
    assert not {"rl_train", "rl_cell", "table_task_success_rl", "figure_rl_curves",
                "manifest_rl"} & set(paper)
    off = _dry_run(tmp_path, "rl_baselines", {**cfg, "rl": {"enabled": False}})
    assert "rl_train" not in off
    bad = {**cfg, "rl": {**cfg["rl"], "seeds": [5]},
           "rollouts": {**cfg["rollouts"], "replicate": {"seeds": [5]}}}
    import yaml

    (tmp_path / "bad.yaml").write_text(yaml.safe_dump(bad))
    out = subprocess.run([sys.executable, "-m", "snakemake", "-n", "--snakefile",
                          str(REPO / "Snakefile"), "--directory", str(tmp_path),
                          "--configfile", str(REPO / "config" / "config.yaml"),
                          str(tmp_path / "bad.yaml"), "--", "rl_baselines"],
                         capture_output=True, text=True)
    assert out.returncode != 0 and "evaluation seed" in out.stdout + out.stderr


# ------------------------------------------------------------------ the docs' example

def test_readme_train_and_score_example_runs():
    """The train-and-score block of docs/rl.md (the README shows it too) runs as written (with
    a smaller training and evaluation budget) and prints a success rate in [0, 1] over the
    evaluation seed's episodes."""
    import re

    text = (REPO / "docs" / "rl.md").read_text()
    head = text.index("## Train and score")
    block = re.search(r"```python\n(.*?)```", text[head:], re.S).group(1)
    readme = (REPO / "README.md").read_text()
    shown = re.search(r"```python\n(.*?)```",
                      readme[readme.index("## Train and score an RL policy"):], re.S).group(1)
    assert shown == block                # the README shows the same example
    assert "learn(300_000)" in block and "evaluate(PPOPolicy(" in block
    assert "episodes=50" in block and block.rstrip().splitlines()[-1].startswith("print(")
    code = block.replace("learn(300_000)", "learn(512)").replace("episodes=50", "episodes=4")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=REPO, timeout=900)
    assert out.returncode == 0, out.stderr[-2000:]
    sr = float(out.stdout.strip().splitlines()[-1])
    assert 0.0 <= sr <= 1.0 and sr * 4 == round(sr * 4)
