"""Gymnasium ids for every built-in task and tier, and PettingZoo-side ids for the team tasks.

``import oneocean`` calls :func:`register_envs` (when Gymnasium is installed), so::

    import gymnasium as gym
    import oneocean

    env = gym.make("OneOcean/G2G-T2-v0")                            # OceanEnv("G2G", 2)
    envs = gym.make_vec("OneOcean/FT-T1-v0", num_envs=16,
                        vectorization_mode="vector_entry_point")  # OceanVectorEnv("FT", 1)
    par = oneocean.registration.make_parallel("OneOcean/FT-T2-parallel-v0")

Each id's kwargs are ``{"task": ..., "tier": ...}``; everything else (``grid``, ``obs_mode``,
...) is a keyword of :func:`gymnasium.make`. ``grid`` defaults to the default region's grid
(:func:`oneocean.product.defaults.resolve_grid`). No ``TimeLimit`` wrapper: an episode ends by the
task's own time limit (``truncated``).

Registering is cheap: the entry points are strings, so neither the env module nor numba nor
any task module is imported until an env is made, and the task ids come from the packaged
tier tables' file names (:func:`oneocean.registry.packaged_task_ids`).
"""

from __future__ import annotations

__all__ = ["register_envs", "env_id", "env_ids", "make_parallel", "parallel_ids", "PARALLEL_IDS",
           "NAMESPACE", "TIERS"]

#: The Gymnasium namespace of every id.
NAMESPACE = "OneOcean"
#: The tiers registered per task.
TIERS = (1, 2, 3)
VERSION = 0


def _ids() -> tuple[str, ...]:
    from .registry import packaged_task_ids

    return packaged_task_ids()


def env_id(task: str, tier: int) -> str:
    """The Gymnasium id of a (task, tier): ``OneOcean/<TASK>-T<tier>-v0``.

    Parameters
    ----------
    task : str
        A task id, e.g. ``"G2G"``.
    tier : int
        1, 2 or 3.

    Returns
    -------
    str
        The id.
    """
    return f"{NAMESPACE}/{task}-T{int(tier)}-v{VERSION}"


def env_ids() -> tuple[str, ...]:
    """Every Gymnasium id :func:`register_envs` registers, task by task.

    Returns
    -------
    tuple of str
        The ids, tiers 1-3 of each built-in task in turn.
    """
    return tuple(env_id(t, k) for t in _ids() for k in TIERS)


def register_envs() -> tuple[str, ...]:
    """Register ``OneOcean/<TASK>-T<tier>-v0`` with Gymnasium for every built-in task and tier.

    ``entry_point`` :class:`oneocean.envs.OceanEnv`, ``vector_entry_point``
    :class:`oneocean.envs.OceanVectorEnv`, kwargs ``{"task", "tier"}``, no step limit.
    Idempotent: ids already registered are left as they are.

    Returns
    -------
    tuple of str
        Every id (:func:`env_ids`), whether newly registered or not.
    """
    from gymnasium.envs.registration import register, registry

    ids = []
    for task in _ids():
        for tier in TIERS:
            eid = env_id(task, tier)
            ids.append(eid)
            if eid in registry:
                continue
            register(id=eid, entry_point="oneocean.envs:OceanEnv",
                     vector_entry_point="oneocean.envs:OceanVectorEnv",
                     kwargs={"task": task, "tier": tier}, max_episode_steps=None)
    return tuple(ids)


_parallel: dict = {}


def parallel_ids():
    """The PettingZoo-side ids of the built-in team tasks.

    A team task has a default team size > 1 (its tier table's ``agents.default``). Computed
    on first use and cached.

    Returns
    -------
    mappingproxy
        Read-only ``{"OneOcean/<TASK>-T<tier>-parallel-v0": (task, tier)}`` for every team
        task and tier 1-3.
    """
    if not _parallel:
        from types import MappingProxyType

        from .registry import builtin_task_ids, task_spec

        _parallel["ids"] = MappingProxyType({
            f"{NAMESPACE}/{t}-T{k}-parallel-v{VERSION}": (t, k)
            for t in builtin_task_ids() if task_spec(t).agents_default > 1 for k in TIERS})
    return _parallel["ids"]


def make_parallel(env_id: str, grid=None, **kw):
    """The PettingZoo ``ParallelEnv`` of a parallel id (:data:`PARALLEL_IDS`).

    Parameters
    ----------
    env_id : str
        ``OneOcean/<TASK>-T<tier>-parallel-v0`` (:func:`parallel_ids`).
    grid : Grid, path-like or mapping, optional
        As :func:`oneocean.product.defaults.resolve_grid`; None is the default region's grid.
    **kw
        Keywords of :class:`oneocean.envs.OceanVectorEnv` (modes, backend, ...).

    Returns
    -------
    pettingzoo.ParallelEnv
        :func:`oneocean.envs.parallel_env` ``(task, tier, grid, **kw)``.

    Raises
    ------
    ConfigError
        One line listing valid ids, if ``env_id`` is not registered.
    """
    ids = parallel_ids()
    if env_id not in ids:
        from .errors import ConfigError

        valid = sorted(ids)
        raise ConfigError(f"parallel env id {env_id!r} is not registered; valid ids are e.g. "
                          f"{', '.join(valid[:4])} ({len(valid)} in all: "
                          "oneocean.registration.PARALLEL_IDS)")
    from .envs import parallel_env

    task, tier = ids[env_id]
    return parallel_env(task, tier, grid, **kw)


def __getattr__(name: str):
    # PARALLEL_IDS reads the tier tables (team sizes): computed on first use, not at import
    if name == "PARALLEL_IDS":
        return parallel_ids()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
