"""The trained PPO network as a method of kind ``callable``, and its cell files.

:func:`load` turns a ``policy.zip`` (:mod:`oneocean.methods.ppo.train`) into the callable
:func:`oneocean.evaluate.evaluate` scores: it declares the normalised views it was trained
on, so the evaluation gives it the env's normalised observations
(:func:`oneocean.envs.normalize` of the public observation: the vehicle's ``v_max``, the
task's reach ``v_max x time limit``, the fraction of the time limit left, the task's own
fields) and reads its deterministic action in units of ``v_max`` (norm clipped to 1: the
env's ``action_mode="normalized"``), exactly as the training env did.

:func:`evaluate_to_file` scores it on exactly a workflow cell's episodes (the evaluation
seed, ``rollouts.episodes``; :func:`oneocean.evaluate.evaluate`) and writes the cell file in
the rollout cells' layout and record (:func:`oneocean.tasks.rollout_to_file`), so the tables
read it like any other method's.

Importing this module registers the method ``ppo`` (kind ``callable``: Python ``obs ->
action`` through the step API, not a network inside the compiled loop) and imports neither
torch nor Stable-Baselines3.
"""

from __future__ import annotations

import numpy as np

from ...registry import MethodSpec, register_method
from ...vocab import EVALUATION_SEED

#: The method ``ppo`` (registered at import).
METHOD = register_method(MethodSpec(
    "ppo", "PPO", "callable", "shared sensor models",
    "Proximal policy optimisation (Stable-Baselines3 defaults, MlpPolicy), one policy per "
    "single-vehicle task trained on the step API's normalised observations and actions with "
    "the dense reward, on training seeds disjoint from the evaluation seed, for a fixed "
    "budget of environment steps; evaluated with deterministic actions.", short="PPO"))


def episode_constants(task: str, tier: int) -> dict:
    """What the normalised view needs for a (task, tier), as the env computes it.

    Parameters
    ----------
    task : str
        Task id.
    tier : int
        Tier.

    Returns
    -------
    dict
        ``v_max`` (m s-1, the task's vehicle), ``reach`` (m, ``v_max x time_limit_s``),
        ``t_lim`` (s) and ``n_steps`` (the episode length, steps).
    """
    from ...engine import load_vehicle
    from ...tasks.tiers import episode_steps, load_task_table, tier_params

    table = load_task_table(task)
    params = tier_params(task, int(tier))
    v_max = float(load_vehicle(table.get("vehicle")).v_max)
    return {"v_max": v_max, "reach": v_max * float(params["time_limit_s"]),
            "t_lim": float(params["time_limit_s"]),
            "n_steps": episode_steps({**params, "dt_s": float(table["dt_s"])})}


class PPOPolicy:
    """A trained PPO network as a policy (``reset(briefing)``, ``act(observation)``) for one
    (task, tier).

    It declares the views it was trained on (``obs_mode = action_mode = "normalized"``), so
    :func:`oneocean.evaluate.evaluate` gives it the env's normalised observations (E, N,
    NORM_DIM + the task's fields), computed exactly as in training, and reads its actions in
    units of ``v_max`` (norm clipped to 1); it returns the network's deterministic action
    (E, N, 3). :meth:`normalized` maps raw observations to that view for use outside the env.

    Parameters
    ----------
    model : stable_baselines3.PPO
        The trained model.
    task : str
        Task id.
    tier : int
        Tier (:func:`episode_constants`: ``v_max``, ``reach``, ``t_lim``).
    """

    obs_mode = "normalized"
    action_mode = "normalized"

    def __init__(self, model, task: str, tier: int):
        c = episode_constants(task, tier)
        self.model = model
        self.task, self.tier = task, int(tier)
        self.v_max, self.reach, self.t_lim = c["v_max"], c["reach"], c["t_lim"]

    def reset(self, briefing=None) -> None:
        """Start a batch of episodes: one torch thread (after the env's numba threads
        started).

        Parameters
        ----------
        briefing : NamedTuple, optional
            The task's briefing (not used: the network acts on the observation alone).
        """
        import torch

        torch.set_num_threads(1)       # after the env's numba threads started (train.py)

    def normalized(self, obs) -> np.ndarray:
        """The training env's view of raw observations.

        Parameters
        ----------
        obs : (E, N, D) array_like
            Raw observations (NaN where undefined).

        Returns
        -------
        (E, N, NORM_DIM + D - OBS_DIM) float64
            The normalised view (:func:`oneocean.envs.normalize`).
        """
        from ...envs import normalize

        return normalize(np.asarray(obs, dtype=np.float64), self.v_max, self.reach, self.t_lim)

    def act(self, observation) -> np.ndarray:
        """The actions of a step: :meth:`__call__` on the observation's agents' array.

        Parameters
        ----------
        observation : Observation
            The step's observation (:class:`oneocean.evaluate.Observation`; its ``agents``
            in the env's normalised view).

        Returns
        -------
        (E, N, 3) float64
            Actions in units of ``v_max``.
        """
        return self(observation.agents)

    def __call__(self, obs) -> np.ndarray:
        """The network's deterministic actions for a batch of normalised observations.

        Parameters
        ----------
        obs : (E, N, NORM_DIM + the task's fields) array_like
            The env's normalised observations.

        Returns
        -------
        (E, N, 3) float64
            Actions in units of ``v_max`` (the evaluation clips their norm to 1).
        """
        x = np.asarray(obs, dtype=np.float64)
        e, n, d = x.shape
        a, _ = self.model.predict(x.reshape(e * n, d), deterministic=True)
        return np.asarray(a, dtype=np.float64).reshape(e, n, -1)


def load(path, task: str, tier: int) -> PPOPolicy:
    """The ``policy.zip`` at ``path`` as a :class:`PPOPolicy` for ``task`` at ``tier``.

    Parameters
    ----------
    path : path
        The SB3 model file (:func:`oneocean.methods.ppo.train.train_to_files`).
    task : str
        Task id.
    tier : int
        Tier.

    Returns
    -------
    PPOPolicy
        The policy, its model loaded on the CPU.
    """
    from .train import pin_torch_cpu

    pin_torch_cpu()                  # the same bits on any CPU (before torch is imported)
    from stable_baselines3 import PPO

    return PPOPolicy(PPO.load(str(path), device="cpu"), task, tier)


def evaluate_to_file(policy_path, grid_path, out_path, task: str, tier: int, *,
                     episodes: int = 50, seed: int = EVALUATION_SEED, dynamics: str = "6dof",
                     current_gain: float = 1.0, tide=None, backend: str = "core",
                     threads: int = 1) -> dict:
    """Score the policy on the cell's episodes and write its Parquet file atomically.

    :func:`oneocean.evaluate.evaluate` (method ``ppo``); the file carries the rollout cells'
    record (task, tier, method, dynamics, vehicle, seed, forcing, tier parameters,
    ``applicable``) plus the policy's sha256. A cell the region cannot host is written as not
    applicable.

    Parameters
    ----------
    policy_path : path
        The ``policy.zip`` (:func:`load`).
    grid_path : path
        The grid export file.
    out_path : path
        The Parquet file to write.
    task : str
        Task id.
    tier : int
        Tier.
    episodes : int, optional
        Episodes (default 50).
    seed : int, optional
        Episode seed (default :data:`oneocean.vocab.EVALUATION_SEED`).
    dynamics : str, optional
        Dynamics model (:data:`oneocean.vocab.DYNAMICS`; default ``"6dof"``).
    current_gain : float, optional
        The run's current gain g (default 1; the same episodes under any forcing,
        :class:`oneocean.tasks.Cell`).
    tide : optional
        The run's synthetic tide term (as :class:`oneocean.tasks.Cell`; default None).
    backend : str, optional
        Must be ``"core"`` (the default): the policy is scored on the core backend.
    threads : int, optional
        Numba threads (default 1).

    Returns
    -------
    dict
        The manifest entry (:func:`oneocean.engine.write_metrics`).

    Raises
    ------
    ConfigError
        A ``backend`` other than ``"core"`` (never a cell under another backend than its record
        says).
    """
    import numba

    from ...engine import load_grid, load_vehicle, write_metrics
    from ...errors import ConfigError, NotApplicable
    from ...evaluate import evaluate
    from ...io import sha256_file
    from ...tasks import n_agents_for, na_frame, task_module
    from ...tasks.tiers import load_task_table, tier_params

    if backend != "core":
        raise ConfigError(f"ppo cell {task} tier {tier}: the policy is scored on the core "
                          f"backend; got backend={backend!r}")
    numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))
    params = tier_params(task, int(tier))
    vehicle = load_vehicle(load_task_table(task).get("vehicle"))
    n = n_agents_for(task, None)
    meta = {"task": task, "tier": int(tier), "method": METHOD.name, "dynamics": dynamics,
            "vehicle": vehicle.name, "v_max_ms": vehicle.v_max, "n_agents": n,
            "episodes": int(episodes), "seed": int(seed),
            "current_gain": float(current_gain) * float(params.get("current_gain", 1.0)),
            "tide": tide,
            "currents": True, "tier_params": params, "applicable": True, "reason": "",
            "backend": "core", "policy": "oneocean.methods.ppo.policy:load",
            "policy_sha256": sha256_file(policy_path)}
    grid = load_grid(grid_path)
    try:
        df = evaluate(load(policy_path, task, tier), task, tier, grid, episodes=int(episodes),
                      seed=int(seed), dynamics=dynamics, name=METHOD.name,
                      current_gain=float(current_gain), tide=tide)
    except NotApplicable as exc:
        df = na_frame(task_module(task), int(tier), METHOD.name, n, dynamics, True, int(seed))
        meta.update(applicable=False, reason=str(exc))
    return write_metrics(df, out_path, meta=meta)
