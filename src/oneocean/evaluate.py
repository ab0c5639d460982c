"""Score your own policy on the benchmark: the same episodes, loop and metrics as the paper's
methods, and the same Parquet table as the workflow's rollout cells.

A policy sees exactly what the built-in methods see (docs/policy.md): the task's briefing at
the start and every agent's observation at every step. Two forms:

* an object with ``reset(briefing)`` and ``act(observation)``: ``briefing`` is the task's
  briefing of every episode (its ``<ID>Briefing``: the forecast field, the goal / route /
  region / chart / slots / zone / report, the vehicle's limits and power model, the tier's
  time limit, tolerances and energy allocation); ``observation`` an :class:`Observation`
  (``agents`` (E, N, D): :data:`oneocean.tasks.common.OBS_FIELDS` then the task's own fields,
  NaN where undefined; the task's team observation ``team``; the ``report`` buffer a task that
  judges a report reads, e.g. PI's leak claims, written in place). The built-in heuristic
  itself runs this way (:class:`oneocean.methods.heuristic.FusedPolicy`) and gives the same
  episodes as its fused cell.
* a plain callable ``policy(obs)``: ``obs`` is the agents' array (E, N, D) with undefined
  values as 0 (the step API's raw view; the first 14 columns are the original observation).

Either returns the actions (E, N, 3): the desired velocity relative to the water, world frame
(x east, y down, z north), m s-1, clipped to the vehicle's ``v_max``; or (E, N, 4) with the
commanded heading (rad from north, NaN: free). Rows of finished episodes are ignored. A
policy trained on the step API's normalised views says so with ``obs_mode = "normalized"``
and/or ``action_mode = "normalized"`` attributes (or :func:`evaluate`'s arguments): it then
gets the env's normalised observations and returns actions in units of ``v_max``, exactly as
in training.

The grid is anything :func:`oneocean.product.defaults.resolve_grid` takes; None (the default) is the
default region's grid, built into the cache on first use.

Python::

    from oneocean.evaluate import evaluate
    df = evaluate(my_policy, "G2G", 2)                  # the default region's grid
    df = evaluate(my_policy, "G2G", 2, "results/exports/synthetic_coast/scene/grid.npz")

Command line::

    oneocean evaluate --task G2G --tier 2 --policy mypkg.mod:act --out mine.parquet
    oneocean evaluate --task G2G --tier 2 --policy mypkg.mod:act \\
        --grid results/exports/<region>/scene/grid.npz --out mine.parquet
"""

from __future__ import annotations

import importlib
from typing import NamedTuple

import numpy as np
import pandas as pd

from .errors import ConfigError
from .vocab import EVALUATION_SEED


def load_policy(spec: str):
    """Import a policy from its ``"package.module:attr"`` spec.

    Parameters
    ----------
    spec : str
        ``module:attr``; ``attr`` may be dotted (``mod:Class.method``).

    Returns
    -------
    object
        The object named by ``spec``; a class is instantiated without arguments (a policy
        with ``reset`` and ``act``).

    Raises
    ------
    ConfigError
        One line, if ``spec`` has no ``:``, the module does not import, the attribute is
        missing or the object is not callable.
    """
    if ":" not in spec:
        raise ConfigError(f"policy {spec!r}: expected 'module:callable', e.g. mypkg.mod:act")
    mod_name, attr = spec.split(":", 1)
    try:
        mod = importlib.import_module(mod_name)
    except ImportError as exc:
        raise ConfigError(f"policy {spec!r}: cannot import module {mod_name!r} ({exc})") from None
    except SyntaxError as exc:
        raise ConfigError(f"policy {spec!r}: cannot import module {mod_name!r} (SyntaxError: "
                          f"{exc.msg}, {exc.filename} line {exc.lineno})") from None
    obj = mod
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise ConfigError(f"policy {spec!r}: module {mod_name!r} has no attribute {attr!r}")
        obj = getattr(obj, part)
    if not callable(obj):
        raise ConfigError(f"policy {spec!r}: {attr!r} is not callable")
    if isinstance(obj, type):
        try:
            obj = obj()
        except TypeError as exc:
            raise ConfigError(f"policy {spec!r}: the class {attr!r} cannot be made without "
                              f"arguments ({exc})") from None
    return obj


class Observation(NamedTuple):
    """What a policy with ``reset``/``act`` receives every step (docs/policy.md)."""
    agents: np.ndarray  # (E, N, D) float64: OBS_FIELDS then the task's OBS_EXTRA; NaN: undefined
    team: tuple         # the task's team observation (its TEAM_OBS NamedTuple; () without one)
    report: np.ndarray  # the report the task judges (its REPORT; an empty array without one),
                        # written by the policy in place


def evaluate(policy, task: str, tier: int, grid=None, *, episodes: int = 50,
             seed: int = EVALUATION_SEED,
             dynamics: str = "6dof", n_agents: int | None = None, currents: bool = True,
             vehicle=None, name: str = "user", backend: str = "core",
             scene=None, current_gain: float = 1.0, tide=None, obs_mode: str | None = None,
             action_mode: str | None = None, info: str | None = None) -> pd.DataFrame:
    """Run ``policy`` on ``episodes`` episodes of a (task, tier) cell through the step API's loop.

    The same episodes, judge and metrics as the workflow's rollout cells, on either backend.

    Parameters
    ----------
    policy : object or callable
        ``reset(briefing)`` and ``act(observation) -> actions``, or ``policy(obs) ->
        actions``: see the module docstring. Non-finite velocities are replaced by 0.
    task : str
        A registered task id, e.g. ``"G2G"``.
    tier : int
        1, 2 or 3.
    grid : Grid, path-like or mapping, optional
        What :func:`oneocean.product.defaults.resolve_grid` takes (None: the default region's grid;
        ignored with ``scene``).
    episodes : int, default 50
        Number of episodes E, all run at once.
    seed : int, default ``EVALUATION_SEED``
        Evaluation seed (:data:`oneocean.vocab.EVALUATION_SEED`, held out from calibration);
        a seed whose episodes the cell cannot host raises ``NotApplicable``.
    dynamics : str, default "6dof"
        Vehicle model: ``kinematic``, ``3dof``, ``4dof`` or ``6dof``.
    n_agents : int, optional
        Team size N (default: the task's own).
    currents : bool, default True
        False: the currents-off ablation (the same episodes).
    vehicle : Vehicle, optional
        The vehicle (:func:`oneocean.engine.load_vehicle`; default: the task table's).
    name : str, default "user"
        The ``method`` column of the table.
    backend : str, default "core"
        The execution backend (:class:`oneocean.tasks.Cell`): ``core`` or ``mujoco`` (which
        needs ``scene``).
    scene : Scene, optional
        A :class:`oneocean.backends.mujoco.scenes.Scene` to run in.
    current_gain : float, default 1.0
        Gain on the data currents u, v (1: the data as they are); the episodes stay the same.
    tide : dict, optional
        A synthetic tide term, e.g. ``{"amplitude_ms": 0.3, "period_s": 44712}`` (m s-1, s);
        the episodes stay the same.
    obs_mode : str, optional
        The observation view the policy was built for (:class:`oneocean.envs.OceanVectorEnv`):
        ``raw`` or ``normalized``; None takes the policy's ``obs_mode`` attribute, else ``raw``.
    action_mode : str, optional
        ``velocity`` (m s-1) or ``normalized`` (units of ``v_max``); None takes the policy's
        ``action_mode`` attribute, else ``velocity``.
    info : str, optional
        What the policy is given instead of the sensor models
        (:data:`oneocean.sensing.INFO_LEVELS`): None, the sensor models, as every method;
        ``truth`` is what the oracle is given; the others are the information ablations.

    Returns
    -------
    pandas.DataFrame
        The cell table (:func:`oneocean.tasks.cell_frame`), one row per episode, with
        ``method = name`` and a ``candidate`` column after ``seed``.

    Raises
    ------
    ConfigError
        If the policy returns actions of the wrong shape (or on a bad argument).
    NotApplicable
        If the region cannot host the cell's episodes for ``seed``.
    """
    from .envs import OceanVectorEnv
    from .tasks import cell_frame

    if scene is None:
        from .product.defaults import resolve_grid

        grid = resolve_grid(grid)
    obs_mode = obs_mode or getattr(policy, "obs_mode", "raw")
    action_mode = action_mode or getattr(policy, "action_mode", "velocity")
    env = OceanVectorEnv(task, tier, grid, num_envs=int(episodes), dynamics=dynamics,
                         n_agents=n_agents, currents=currents, vehicle=vehicle,
                         current_gain=current_gain, tide=tide, backend=backend, scene=scene,
                         autoreset_mode="disabled", strict_seed=True, obs_mode=obs_mode,
                         action_mode=action_mode, info=info)
    obs, _ = env.reset(seed=int(seed))
    b = env.batch
    protocol = callable(getattr(policy, "act", None)) and callable(getattr(policy, "reset", None))
    if protocol:
        policy.reset(b.B)
    while not b.done.all():
        if protocol:
            raw = b.C.O if obs_mode == "raw" else obs
            act = policy.act(Observation(raw.copy(), b.C.T, b.C.R))
        else:
            act = policy(obs)
        act = np.array(act, dtype=np.float64)
        if (act.ndim != 3 or act.shape[:2] != env.action_space.shape[:2]
                or act.shape[2] not in (3, 4)):
            raise ConfigError(f"policy {name!r}: returned actions of shape {act.shape}, "
                              f"expected {env.action_space.shape} (episodes, agents, 3), or "
                              "a fourth column, the heading")
        act[..., :3] = np.where(np.isfinite(act[..., :3]), act[..., :3], 0.0)
        obs, *_ = env.step(act)
    res = b.results()
    df = cell_frame(b.mod, res, tier, name, b.n_agents, dynamics, currents, int(episodes),
                    int(seed))
    df.insert(df.columns.get_loc("seed") + 1, "candidate", b.candidate)
    return df


def evaluate_to_file(policy_spec: str, out_path, task: str, tier: int, grid_path=None, *,
                     name: str | None = None, **kw) -> dict:
    """:func:`evaluate` a ``module:callable`` policy and write the cell's Parquet table.

    Written atomically, with the run's configuration in the file's metadata, like the
    workflow's rollout cells.

    Parameters
    ----------
    policy_spec : str
        ``module:callable`` (:func:`load_policy`).
    out_path : path-like
        The output ``.parquet`` file.
    task : str
        A registered task id.
    tier : int
        1, 2 or 3.
    grid_path : path-like, optional
        As :func:`evaluate`'s ``grid``.
    name : str, optional
        The ``method`` column (default: the callable's name in ``policy_spec``).
    **kw
        Further keyword arguments of :func:`evaluate`.

    Returns
    -------
    dict
        The manifest entry (:func:`oneocean.engine.write_metrics`).
    """
    from .engine import write_metrics
    from .tasks.tiers import tier_params

    policy = load_policy(policy_spec)
    name = name or policy_spec.split(":", 1)[1]
    df = evaluate(policy, task, tier, grid_path, name=name, **kw)
    scene = kw.get("scene")
    params = tier_params(task, int(tier), scene is not None)
    # the forcing the rollout ran (as the workflow's cells record it: the run's gain times
    # the tier's own current_gain)
    meta = {"dynamics": kw.get("dynamics", "6dof"), "policy": policy_spec,
            "tier_params": params, "backend": kw.get("backend", "core"),
            "current_gain": float(kw.get("current_gain", 1.0))
            * float(params.get("current_gain", 1.0)), "tide": kw.get("tide")}
    if scene is not None:
        from .tasks import scene_record

        meta.update(scene=scene.name, scene_meta=scene_record(scene))
    return write_metrics(df, out_path, meta=meta)
