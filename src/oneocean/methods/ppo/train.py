"""Train the PPO baseline of one task: SB3 defaults, a fixed budget, training seeds only.

Environment: the task's :class:`~oneocean.envs.OceanVectorEnv` at each training tier
(``n_envs`` sub-envs per tier, ``autoreset_mode="same_step"``, ``obs_mode="normalized"``,
``action_mode="normalized"``, ``reward="dense"``), all tiers' sub-envs in one
:class:`~oneocean.sb3.SB3VecEnv`; the episodes are the env's pools of the training seed
(:func:`oneocean.envs.pool_seed`, :func:`oneocean.sb3.block_seed` per tier), never the
evaluation seed's.

Algorithm: ``PPO("MlpPolicy", env, seed=seed, device="cpu")`` with Stable-Baselines3's
default hyperparameters (:data:`PPO_CHANGES` lists what differs from them: nothing), for
``budget_steps`` SB3 timesteps (one per agent per control step: environment steps for a
single-vehicle task), in whole rollouts of ``n_steps x n_envs x tiers``.

Determinism: the same seed, budget and settings give the same weights (and so the same
``policy.zip`` bytes) in any process and on any x86-64 CPU: ``set_random_seed(seed)``, one
torch thread (also after the env's numba kernels have started their threads), the CPU,
torch's machine-independent kernels (:func:`pin_torch_cpu`, set before torch is imported) and
a byte-stable zip (:func:`save_stable`). The training report holds no wall time, so it is
byte-identical too (the workflow's ``benchmark:`` file times a training).

Several training seeds (``seeds``) train one run each with the same budget; the run kept for
evaluation is the one with the highest final success rate on its *training* episodes (the
first on a tie); every run's learning curve is in the report.
"""

from __future__ import annotations

import json
import math
import os
import re
import sys
import time
import zipfile
from pathlib import Path

import numpy as np

from ...errors import ConfigError
from ...vocab import EVALUATION_SEED

#: The documented range of PPO training seeds: every seed below the evaluation seed (the
#: workflow's replicate seeds lie above it). A training seed outside it is refused.
TRAINING_SEEDS = range(0, EVALUATION_SEED)
#: Changes to Stable-Baselines3's default PPO hyperparameters (none: the defaults).
PPO_CHANGES: dict = {}
#: The training env's modes (the policy maps raw observations and m s-1 actions through them).
ENV_MODES = {"obs_mode": "normalized", "action_mode": "normalized", "reward": "dense",
             "autoreset_mode": "same_step"}
#: Share of the rollouts (the last ones) whose finished episodes give the final success rate.
FINAL_SHARE = 0.1
#: A memory address at the end of a ``repr`` (``<function f at 0x7f...>``).
_ADDRESS = re.compile(r" at 0x[0-9a-fA-F]+>")
#: Entries of the SB3 ``data`` record that depend on the wall clock (not saved).
_VOLATILE = ["start_time", "ep_info_buffer", "ep_success_buffer"]


def check_training_seeds(seeds, evaluation_seeds=(EVALUATION_SEED,)) -> list[int]:
    """The training seeds, checked: in :data:`TRAINING_SEEDS`, distinct, no evaluation seed.

    Parameters
    ----------
    seeds : iterable of int
        Training seeds (``rl.seeds``).
    evaluation_seeds : iterable of int, optional
        Seeds a training seed must not be (default: :data:`oneocean.vocab.EVALUATION_SEED`).

    Returns
    -------
    list of int
        ``seeds`` as ints.

    Raises
    ------
    ConfigError
        No seed, a seed that is an evaluation seed or outside :data:`TRAINING_SEEDS`, or a
        repeated seed.
    """
    out = [int(s) for s in seeds]
    if not out:
        raise ConfigError("rl.seeds: at least one training seed is needed")
    held = {int(s) for s in evaluation_seeds}
    for s in out:
        if s in held:
            raise ConfigError(f"rl.seeds: {s} is an evaluation seed ({sorted(held)}); "
                              "training seeds must be disjoint from it")
        if s not in TRAINING_SEEDS:
            raise ConfigError(f"rl.seeds: {s} is outside the training seed range "
                              f"{TRAINING_SEEDS.start}-{TRAINING_SEEDS.stop - 1}")
    if len(set(out)) != len(out):
        raise ConfigError(f"rl.seeds: duplicate seed in {out}")
    return out


def episode_seeds(seed: int, blocks: int, pools: int) -> list[int]:
    """Every seed whose episodes a training run used.

    Parameters
    ----------
    seed : int
        The run's training seed.
    blocks : int
        Vector envs of the run (one per tier; :func:`oneocean.sb3.block_seed`).
    pools : int
        Episode pools each drew (:func:`oneocean.envs.pool_seed`).

    Returns
    -------
    list of int
        The pools' seeds, block by block.
    """
    from ...envs import pool_seed
    from ...sb3 import block_seed

    return [pool_seed(block_seed(seed, b), i) for b in range(blocks) for i in range(pools)]


#: torch's CPU settings under which training and inference give the same bits on any
#: x86-64 CPU: ATen's generic kernels instead of the ones chosen for the CPU's SIMD width
#: (AVX2, AVX-512: their vectorised loops and transcendental functions round differently)
#: and MKL's conditional numerical reproducibility (its matrix products otherwise pick
#: per-CPU code paths whose sums differ in the last bits). No training time difference
#: measured (8,192 G2G steps: 5.8-7.4 s pinned, 5.3-6.7 s native, alternating runs).
TORCH_CPU_ENV = {"ATEN_CPU_CAPABILITY": "default", "MKL_CBWR": "COMPATIBLE"}


def pin_torch_cpu() -> dict:
    """Set :data:`TORCH_CPU_ENV` in the process environment, where torch reads it.

    torch reads these variables once, when it first needs them; call this before torch is
    imported (:func:`train` and :func:`oneocean.methods.ppo.policy.load` do, before importing
    Stable-Baselines3). In a process that already used torch with other settings they may
    not take effect: the returned record says what is in force.

    Returns
    -------
    dict
        ``cpu_capability`` (torch's, ``DEFAULT`` when pinned) and ``mkl_cbwr`` (the
        environment's value).
    """
    os.environ.update(TORCH_CPU_ENV)
    import torch

    return {"cpu_capability": str(torch.backends.cpu.get_cpu_capability()),
            "mkl_cbwr": os.environ.get("MKL_CBWR")}


def _threads_one() -> None:
    """One torch thread and one numba thread (the env's numba threads and torch's share an
    OpenMP runtime: more threads than cores makes every small torch op wait)."""
    import numba
    import torch

    numba.set_num_threads(1)
    torch.set_num_threads(1)


def quiet_logger(model) -> None:
    """Give ``model`` the logger Stable-Baselines3 would configure, without its folder.

    Without a ``tensorboard_log``, SB3's ``learn`` configures a logger that writes nothing
    to disk (or only to stdout with ``verbose >= 1``) yet creates an empty
    ``<tempdir>/SB3-<date>`` folder on every call. This logger records the same values and
    prints the same lines, and leaves nothing behind. A model with a ``tensorboard_log``
    keeps SB3's own logger (its folder is where the user asked for it).

    Parameters
    ----------
    model : stable_baselines3.common.base_class.BaseAlgorithm
        The model, before ``learn``.
    """
    from stable_baselines3.common.logger import HumanOutputFormat, Logger

    if model.tensorboard_log is not None:
        return
    out = [HumanOutputFormat(sys.stdout)] if model.verbose >= 1 else []
    model.set_logger(Logger(folder=None, output_formats=out))


def make_env(task: str, tiers, grid, n_envs: int, *, dynamics: str = "6dof"):
    """The training env: one :class:`~oneocean.envs.OceanVectorEnv` per tier in one SB3 env.

    Each tier's env has ``n_envs`` sub-envs in the modes of :data:`ENV_MODES`; together they
    form one :class:`~oneocean.sb3.SB3VecEnv`.

    Parameters
    ----------
    task : str
        Task id.
    tiers : iterable of int
        Training tiers.
    grid : Grid, path or None
        The grid export (:class:`oneocean.engine.grid.Grid`) or its file; None: the default
        region's grid (:class:`~oneocean.envs.OceanVectorEnv`).
    n_envs : int
        Sub-envs per tier.
    dynamics : str, optional
        Dynamics model (:data:`oneocean.vocab.DYNAMICS`; default ``"6dof"``).

    Returns
    -------
    SB3VecEnv
        The training env.
    """
    from ...engine import load_grid
    from ...engine.grid import Grid
    from ...envs import OceanVectorEnv
    from ...sb3 import SB3VecEnv

    if grid is not None and not isinstance(grid, Grid):
        grid = load_grid(grid)
    return SB3VecEnv([OceanVectorEnv(task, int(k), grid, num_envs=int(n_envs),
                                     dynamics=dynamics, **ENV_MODES) for k in tiers])


def _curve_callback(n_agents: int):
    from stable_baselines3.common.callbacks import BaseCallback

    class Curve(BaseCallback):
        """Per rollout: finished episodes, their success rate and mean return, and the mean
        reward per step (one row per sub-env episode: a team's agents count once)."""

        def __init__(self):
            super().__init__()
            self.rows: list[dict] = []
            self.episodes: list[tuple[int, bool, float]] = []   # (rollout, success, return)

        def _on_rollout_start(self) -> None:
            self._r_sum, self._r_n = 0.0, 0
            self._succ, self._ret = [], []

        def _on_step(self) -> bool:
            r = np.asarray(self.locals["rewards"], dtype=np.float64)
            self._r_sum += float(r.sum())
            self._r_n += r.size
            for row, (info, done) in enumerate(zip(self.locals["infos"],
                                                   self.locals["dones"])):
                if done and row % n_agents == 0 and "episode" in info:
                    self._succ.append(bool(info["is_success"]))
                    self._ret.append(float(info["episode"]["r"]))
            return True

        def _on_rollout_end(self) -> None:
            k = len(self.rows)
            n = len(self._succ)
            self.rows.append({
                "rollout": k, "timesteps": int(self.num_timesteps), "episodes": n,
                "success_rate": (float(np.mean(self._succ)) if n else None),
                "mean_episode_return": (float(np.mean(self._ret)) if n else None),
                "mean_reward": self._r_sum / max(self._r_n, 1)})
            self.episodes += [(k, s, r) for s, r in zip(self._succ, self._ret)]

    return Curve()


def train(task: str, grid, *, tiers=(1, 2, 3), budget_steps: int = 1_000_000,
          n_envs: int = 8, seed: int = 0, dynamics: str = "6dof",
          evaluation_seeds=(EVALUATION_SEED,), ppo_kwargs=None, log=None):
    """Train PPO on ``task`` for ``budget_steps`` timesteps with one training ``seed``.

    Parameters
    ----------
    task : str
        Task id (a single-vehicle task).
    grid : Grid, path or None
        The grid export or its file (:func:`make_env`).
    tiers : iterable of int, optional
        Training tiers (default 1, 2, 3).
    budget_steps : int, optional
        SB3 timesteps (default 1 000 000; one per agent per control step), run in whole
        rollouts.
    n_envs : int, optional
        Sub-envs per tier (default 8).
    seed : int, optional
        Training seed (default 0; :func:`check_training_seeds`).
    dynamics : str, optional
        Dynamics model (default ``"6dof"``).
    evaluation_seeds : iterable of int, optional
        Seeds the training episodes must never reach (default the evaluation seed).
    ppo_kwargs : dict, optional
        Hyperparameters other than :data:`PPO_CHANGES`, e.g. a small ``n_steps`` for a smoke
        test (recorded in the report).
    log : logging.Logger, optional
        Logs a line when the run ends.

    Returns
    -------
    model : stable_baselines3.PPO
        The trained model.
    run : dict
        The run's record: seed, timesteps, rollouts, torch's CPU settings in force
        (``torch_cpu``: :func:`pin_torch_cpu`), episodes,
        ``final_success`` and ``final_episodes`` (the success rate over the episodes that
        ended in the last :data:`FINAL_SHARE` of the rollouts; None without any), episode
        pools, and ``curve``: one row per rollout with ``timesteps, episodes, success_rate,
        mean_episode_return, mean_reward``.

    Raises
    ------
    ConfigError
        A seed that :func:`check_training_seeds` refuses.
    """
    torch_cpu = pin_torch_cpu()
    from stable_baselines3 import PPO
    from stable_baselines3.common.utils import set_random_seed

    seed = check_training_seeds([seed], evaluation_seeds)[0]
    tiers = [int(k) for k in tiers]
    env = make_env(task, tiers, grid, n_envs, dynamics=dynamics)
    env.seed(seed)
    env.reset()                      # starts the env's numba threads before torch's are set
    _threads_one()
    set_random_seed(seed)
    model = PPO("MlpPolicy", env, seed=seed, device="cpu", verbose=0,
                **{**PPO_CHANGES, **(ppo_kwargs or {})})
    quiet_logger(model)
    curve = _curve_callback(env.venvs[0].n_agents)
    t0 = time.perf_counter()
    model.learn(total_timesteps=int(budget_steps), callback=curve)
    wall = time.perf_counter() - t0
    pools = max(v._n_pools for v in env.venvs)
    used = episode_seeds(seed, len(env.venvs), pools)
    held = {int(s) for s in evaluation_seeds}
    assert not held & set(used), f"training episodes of seed {seed} reach an evaluation seed"
    n_roll = len(curve.rows)
    last = max(1, int(math.ceil(FINAL_SHARE * n_roll)))
    fin = [s for k, s, _ in curve.episodes if k >= n_roll - last]
    run = {"seed": seed, "timesteps": int(model.num_timesteps), "rollouts": n_roll,
           "torch_cpu": torch_cpu, "episodes": len(curve.episodes),
           "final_success": float(np.mean(fin)) if fin else None,
           "final_episodes": len(fin), "final_rollouts": last,
           "episode_pools": int(pools), "curve": curve.rows}
    env.close()
    if log is not None:
        log.info("PPO %s seed %d: %d steps in %.0f s, final training success %s over %d "
                 "episodes", task, seed, run["timesteps"], wall, run["final_success"],
                 len(fin))
    return model, run


def hyperparameters(model) -> dict:
    """The PPO hyperparameters a model trained with (SB3's defaults plus :data:`PPO_CHANGES`).

    Parameters
    ----------
    model : stable_baselines3.PPO
        The trained model.

    Returns
    -------
    dict
        Rollout, optimisation and network settings (``n_steps``, ``batch_size``, ``gamma``,
        ``learning_rate``, ``clip_range``, ``net_arch``, ``n_envs``, ...), JSON-able.
    """
    out = {k: getattr(model, k) for k in ("n_steps", "batch_size", "n_epochs", "gamma",
                                            "gae_lambda", "ent_coef", "vf_coef",
                                            "max_grad_norm", "normalize_advantage", "target_kl")}
    out["learning_rate"] = model.learning_rate if not callable(model.learning_rate) else "schedule"
    out["clip_range"] = model.clip_range(1.0) if callable(model.clip_range) else model.clip_range
    out["net_arch"] = str(model.policy.net_arch)
    out["activation_fn"] = model.policy.activation_fn.__name__
    out["n_envs"] = int(model.n_envs)
    return out


def _stable_member(name: str, raw: bytes) -> bytes:
    """A member of SB3's ``.zip`` without what differs between processes and machines.

    ``data``: SB3 describes each class it stores (the policy's, the rollout buffer's) by the
    ``repr`` of its attributes beside the pickled class it loads, and a function's or
    object's ``repr`` holds its memory address (``<function f at 0x7f...>``), which changes
    from one process to the next; the addresses are dropped (``<function f>``; SB3 loads
    only the pickle). ``system_info.txt``: the ``- OS:`` line (the kernel build of the
    machine that trained) is dropped; the package versions stay. Other members unchanged.
    """
    if name == "data":
        return _ADDRESS.sub(">", raw.decode()).encode()
    if name == "system_info.txt":
        return "".join(ln for ln in raw.decode().splitlines(keepends=True)
                       if not ln.startswith("- OS:")).encode()
    return raw


def save_stable(model, path) -> None:
    """Save the SB3 ``.zip`` atomically and byte-stably.

    Without the wall-clock entries (``_VOLATILE``), the memory addresses in SB3's
    description of the classes it stores and the training machine's OS line
    (:func:`_stable_member`), and with every member's time stamp at 1980-01-01 (members in
    SB3's order, deflated): the same weights give the same bytes in any process.

    Parameters
    ----------
    model : stable_baselines3.PPO
        The model.
    path : path
        The ``.zip`` to write.
    """
    import io

    from ...io import atomic_path

    buf = io.BytesIO()
    model.save(buf, exclude=list(_VOLATILE))
    buf.seek(0)
    with atomic_path(path, suffix=".zip") as tmp, zipfile.ZipFile(buf) as src, \
            zipfile.ZipFile(tmp, "w") as dst:
        for info in src.infolist():
            out = zipfile.ZipInfo(info.filename, date_time=(1980, 1, 1, 0, 0, 0))
            out.compress_type = zipfile.ZIP_DEFLATED
            out.external_attr = 0o644 << 16
            dst.writestr(out, _stable_member(info.filename, src.read(info)))


def train_to_files(grid_path, policy_path, report_path, task: str, *, tiers=(1, 2, 3),
                   budget_steps: int = 1_000_000, n_envs: int = 8, seeds=(0,),
                   dynamics: str = "6dof", evaluation_seeds=(EVALUATION_SEED,),
                   ppo_kwargs=None, log=None) -> dict:
    """Train one run per seed, keep the best, write its ``policy.zip`` and the training report.

    The kept run is the one with the best final training success (the first on a tie;
    :func:`train`); the model (:func:`save_stable`) and the report (JSON) are written
    atomically.

    Parameters
    ----------
    grid_path : path
        The grid export file.
    policy_path : path
        The ``policy.zip`` to write.
    report_path : path
        The JSON report to write.
    task : str
        Task id (a single-vehicle task).
    tiers, budget_steps, n_envs, dynamics, evaluation_seeds, ppo_kwargs, log
        As :func:`train`.
    seeds : iterable of int, optional
        Training seeds, one run each (default ``(0,)``).

    Returns
    -------
    dict
        The training report: settings, the selected seed, hyperparameters, final success,
        the policy's sha256, package versions and every run's record. No wall time (the
        report is hash-tracked and byte-identical for the same settings; the workflow's
        ``benchmark:`` file and the log line of :func:`train` time the training).

    Raises
    ------
    ConfigError
        Bad seeds, or a team task (PPO trains single-vehicle tasks).
    """
    from importlib.metadata import version

    from ...io import sha256_file, write_json_atomic
    from ...registry import task_spec

    seeds = check_training_seeds(seeds, evaluation_seeds)
    spec = task_spec(task)
    if spec.agents_default != 1:
        raise ConfigError(f"rl.tasks: {task} is a team task ({spec.agents_default} agents); "
                          "the PPO baseline trains single-vehicle tasks")
    runs, best, best_model = [], None, None
    for s in seeds:
        model, run = train(task, grid_path, tiers=tiers, budget_steps=budget_steps,
                           n_envs=n_envs, seed=s, dynamics=dynamics,
                           evaluation_seeds=evaluation_seeds, ppo_kwargs=ppo_kwargs,
                           log=log)
        runs.append(run)
        score = -1.0 if run["final_success"] is None else run["final_success"]
        if best is None or score > best[0]:
            best, best_model = (score, run), model
    save_stable(best_model, policy_path)
    sel = best[1]
    report = {
        "method": "ppo", "task": task, "tiers": [int(k) for k in tiers],
        "budget_steps": int(budget_steps), "n_envs_per_tier": int(n_envs),
        "dynamics": dynamics, "env": dict(ENV_MODES),
        "seeds": seeds, "selected_seed": sel["seed"],
        "selection": "highest final success on the training episodes (first on a tie)",
        "training_seed_range": [TRAINING_SEEDS.start, TRAINING_SEEDS.stop - 1],
        "evaluation_seeds_excluded": sorted(int(s) for s in evaluation_seeds),
        "algorithm": "stable_baselines3.PPO MlpPolicy",
        "ppo_changes": {**PPO_CHANGES, **(ppo_kwargs or {})},
        "hyperparameters": hyperparameters(best_model),
        "final_success": sel["final_success"], "final_episodes": sel["final_episodes"],
        "final_share": FINAL_SHARE,
        "policy_sha256": sha256_file(policy_path),
        "versions": {p: version(p) for p in ("stable_baselines3", "torch", "gymnasium")},
        "runs": runs,
    }
    write_json_atomic(report_path, report)
    return report


def read_report(path) -> dict:
    """A training report (:func:`train_to_files`).

    Parameters
    ----------
    path : path
        The JSON report.

    Returns
    -------
    dict
        The report.
    """
    return json.loads(Path(path).read_text())
