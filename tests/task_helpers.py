"""Assertions and drivers shared by the tests: tier tables, thread counts, and external-action
episodes of the one loop (tests/test_task_*.py, tests/test_engine_*.py)."""

from __future__ import annotations

import numba
import numpy as np

from oneocean.engine import load_vehicle, sample_current
from oneocean.tasks import ft, g2g
from oneocean.tasks.tiers import tier_params
from oneocean.tasks.episodes import Episodes


def assert_tier_table_monotone(table: dict) -> None:
    """Tiers 1, 2, 3; every parameter declared in ``harder`` (``up`` or ``down``) and
    monotone T1 -> T2 -> T3 in its declared direction; every tier sets exactly those."""
    tiers = table["tiers"]
    assert sorted(tiers) == [1, 2, 3]
    for key, way in table["harder"].items():
        assert way in ("up", "down")
        sign = 1.0 if way == "up" else -1.0
        # a list-valued parameter (e.g. current_band [q_lo, q_hi]) is monotone elementwise
        vals = [np.atleast_1d(np.asarray(tiers[t][key], dtype=float)) for t in (1, 2, 3)]
        assert all(np.all(sign * (b - a) >= 0) for a, b in zip(vals, vals[1:])), (key, vals)
    for t in (1, 2, 3):
        assert set(tiers[t]) == set(table["harder"]), t


def on_one_thread(fn, *args, **kwargs):
    """``fn(*args, **kwargs)`` with numba limited to one thread (restored afterwards)."""
    prev = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        return fn(*args, **kwargs)
    finally:
        numba.set_num_threads(prev)


def external_episodes(grid, pos0, steps: int, *, dyn: str = "kinematic", vehicle=None,
                      dt: float = 1.0, t0: float = 0.0, psi0: float = 0.0, seed: int = 0,
                      record: bool = False):
    """Episodes of the one loop (:class:`oneocean.tasks.episodes.Episodes`) with N agents at
    ``pos0`` (E, N, 3) m, driven by external actions (``set_actions``): G2G for one agent,
    FT for more, with the tasks' own ends switched off (goal out of reach, no formation-error
    bound), so every episode runs ``steps`` steps of ``dt`` s from time ``t0``."""
    pos0 = np.array(pos0, dtype=np.float64)
    n_ep, n_ag = pos0.shape[:2]
    far = np.array([1e7, 0.0, 1e7])
    init = {"pos0": pos0, "psi0": np.full((n_ep, n_ag), float(psi0)),
            "t0": np.full(n_ep, float(t0))}
    run = {"dt_s": float(dt), "time_limit_s": steps * float(dt), "goal_radius_m": -1.0}
    if n_ag == 1:
        mod, tier = g2g, {**tier_params("G2G", 1), **run}
        init["goal"] = pos0[:, 0] + far
    else:
        mod, tier = ft, {**tier_params("FT", 1), **run, "max_error_m": 1e12}
        start = pos0.mean(axis=1)
        init.update(offsets=pos0 - start[:, None], start=start, goal=start + far)
    veh = vehicle if vehicle is not None else load_vehicle()
    return Episodes(mod, grid, tier, init, None, dyn, veh, seed, record=record)


def drive(ep, actions):
    """Advance ``ep`` (:func:`external_episodes`) step by step with ``actions``: an array
    (steps, E, N, 3) or a callable ``actions(ep, k) -> (E, N, 3)`` (closed loop; ``ep.state``
    holds the state before step ``k``). Returns the positions (steps + 1, E, N, 3) m, index
    0 = start."""
    traj = [ep.state[..., :3].copy()]
    for k in range(ep.n_steps):
        ep.set_actions(actions(ep, k) if callable(actions) else actions[k])
        ep.run(k + 1)
        traj.append(ep.state[..., :3].copy())
    return np.array(traj)


def goal_control(goals, kp: float):
    """The closed-loop P controller toward ``goals`` (E, N, 3) with current feed-forward,
    ``a = kp (goal - p) - c(p, t)``, as an ``actions`` callable for :func:`drive`."""
    goals = np.asarray(goals, dtype=np.float64)

    def act(ep, k):
        p = ep.state[..., :3]
        a = kp * (goals - p)
        for e in range(p.shape[0]):
            t = ep.t0[e] + k * ep.dt
            for i in range(p.shape[1]):
                ce, cn = sample_current(ep.grid, p[e, i, 0], p[e, i, 1], p[e, i, 2], t)
                a[e, i, 0] -= ce
                a[e, i, 2] -= cn
        return a

    return act
