"""Pieces every task shares: the per-agent step, probes, seeds, start times and result columns.

Task kernels (one ``@njit(parallel=True, cache=True)`` rollout per task, ``prange`` over
episodes) call :func:`advance_agent` for every agent and step, so dynamics, feasibility
(eq. 3), the energy proxy (eq. 7) and violation counting are identical across tasks.
"""

from __future__ import annotations

import math
from importlib import resources
from pathlib import Path

import numpy as np
import yaml

from ..engine import dynamics as dyn
from ..engine import status as st
from ..engine._jit import hot_kernel
from ..engine.constraints import check_move, min_pairwise_distance
from ..engine.grid import Grid, sample_current_data, synthetic_tide
from ..engine.rng import PURPOSE_TASK, normal
from ..errors import ConfigError
from ..vocab import validate_choice

#: Methods a task kernel understands (``method`` int inside the kernels).
HEURISTIC, ORACLE = 0, 1
METHOD_IDS = {"heuristic": HEURISTIC, "oracle": ORACLE}

#: Random-stream purposes of the task layer (counter-based: ``normal(seed, ep, purpose, k)``).
PURPOSE_PROBE = PURPOSE_TASK + 1
PURPOSE_RESET = PURPOSE_TASK + 2
PURPOSE_TASK_NOISE = PURPOSE_TASK + 3

#: Columns every task returns for every episode (then its own METRICS).
STANDARD = ("success", "T_s", "E", "coll_ratio", "violations")

#: Status code of :func:`advance_agent` (re-exported for kernels).
OK = st.OK


def method_id(method: str) -> int:
    return METHOD_IDS[validate_choice(method, tuple(METHOD_IDS), "method")]


@hot_kernel(inline="always")
def current_at(grid, x, y, z, t):
    """True current (ce, cn) m s-1 at world (x, y, z) m, time t s (gain and tides included)."""
    ce, cn = sample_current_data(grid, x, y, z, t)
    te, tn = synthetic_tide(grid, t)
    return ce + te, cn + tn


@hot_kernel(inline="always")
def probe(ce, cn, noise_std, seed, episode, counter):
    """The heuristic's current probe: the true current plus Gaussian noise (std m s-1).

    ``counter`` must be unique per (step, agent) within an episode, e.g. ``2*(k*n_agents+i)``.
    """
    if noise_std <= 0.0:
        return ce, cn
    return (ce + noise_std * normal(seed, episode, PURPOSE_PROBE, counter),
            cn + noise_std * normal(seed, episode, PURPOSE_PROBE, counter + 1))


@hot_kernel(inline="always")
def advance_agent(grid, model, vp, s, cmd, ce, cn, v_max, dt, land_threshold, clearance):
    """Clip the command, advance one agent one step and enforce feasibility, in place.

    Parameters
    ----------
    s : (STATE_DIM,) float64
        Agent state (see :mod:`oneocean.engine.dynamics`), modified in place.
    cmd : (CMD_DIM,) float64
        ``[ax, ay, az, psi_cmd, thrust]``: desired velocity relative to the water (world m s-1);
        clipped here to ``v_max`` (the executed action a_t is written back into ``cmd``).
    ce, cn : float
        True current at the agent (m s-1), frozen over the step.

    Returns
    -------
    energy : float
        ``||a_t||^2 dt`` of the clipped action (m2 s-1), 0 when thrust is off.
    code : int
        Status of the move (``OK`` or the rejection reason); a rejected move keeps the
        position and zeroes the velocity.
    """
    ax, ay, az = dyn.clip_action(cmd[0], cmd[1], cmd[2], v_max)
    cmd[0] = ax
    cmd[1] = ay
    cmd[2] = az
    e = (ax * ax + ay * ay + az * az) * dt if cmd[4] != 0.0 else 0.0
    px = s[0]
    py = s[1]
    pz = s[2]
    dyn.step_agent(model, vp, s, cmd, ce, cn, dt)
    code = check_move(grid, s[0], s[1], s[2], land_threshold, clearance)
    if code != st.OK:
        s[0] = px
        s[1] = py
        s[2] = pz
        for c in range(dyn.U, dyn.W + 1):
            s[c] = 0.0
        for c in range(dyn.VX, dyn.VZ + 1):
            s[c] = 0.0
    return e, code


@hot_kernel(inline="always")
def set_velocity_cmd(cmd, ax, ay, az):
    """Fill a command row with a world-frame velocity request, heading free, thrust on."""
    cmd[0] = ax
    cmd[1] = ay
    cmd[2] = az
    cmd[3] = math.nan
    cmd[4] = 1.0


@hot_kernel(inline="always")
def seek(px, py, pz, gx, gy, gz, speed, kp, ce, cn):
    """Velocity request (relative to water) toward a goal: P-control capped at ``speed``
    (ground-relative), plus feed-forward cancelling the (probed) current ``(ce, 0, cn)``."""
    dx = gx - px
    dy = gy - py
    dz = gz - pz
    d = math.sqrt(dx * dx + dy * dy + dz * dz)
    v = kp * d
    if v > speed:
        v = speed
    if d > 1e-9:
        f = v / d
        return dx * f - ce, dy * f, dz * f - cn
    return -ce, 0.0, -cn


# ------------------------------------------------------------------------------ tier tables

def _tiers_dir() -> Path:
    return Path(str(resources.files("oneocean") / "data" / "tasks"))


def load_task_table(task_id: str, path: str | Path | None = None) -> dict:
    """The tier table of one task (``data/tasks/<ID>.yaml``): agents, dt, harder, tiers."""
    f = Path(path) if path else _tiers_dir() / f"{task_id}.yaml"
    try:
        doc = yaml.safe_load(f.read_text())
    except OSError as exc:
        raise ConfigError(f"{f}: cannot read tier table ({exc.strerror})") from None
    for key in ("agents", "dt_s", "harder", "tiers"):
        if key not in doc:
            raise ConfigError(f"{f}: missing key '{key}'")
    doc["tiers"] = {int(k): v for k, v in doc["tiers"].items()}
    for tier, params in doc["tiers"].items():
        undeclared = sorted(set(params) - set(doc["harder"]))
        if undeclared:
            raise ConfigError(f"{f}: tier {tier} parameter '{undeclared[0]}' has no 'harder' "
                              "direction")
    return doc


def tier_params(task_id: str, tier: int) -> dict:
    table = load_task_table(task_id)
    if tier not in table["tiers"]:
        raise ConfigError(f"task {task_id}: unknown tier {tier!r}; valid tiers are "
                          f"{sorted(table['tiers'])}")
    return dict(table["tiers"][tier])


# ------------------------------------------------------------------------------ resets

def episode_seed_sequence(seed: int, episode: int, purpose: int) -> np.random.SeedSequence:
    return np.random.SeedSequence([int(seed), int(episode), int(purpose)])


def episode_generators(seed: int, n_episodes: int, purpose: int = PURPOSE_RESET):
    """One independent ``numpy.random.Generator`` per episode (SeedSequence-derived)."""
    return [np.random.default_rng(episode_seed_sequence(seed, e, purpose))
            for e in range(n_episodes)]


def start_times(grid: Grid, rngs, duration_s: float) -> np.ndarray:
    """Episode start times (s since the grid's time0), uniform over the part of the grid's
    time span that leaves ``duration_s`` of data; 0 for single-time grids."""
    t_lo = float(grid.time_s[0])
    t_hi = float(grid.time_s[-1]) - float(duration_s)
    if t_hi <= t_lo:
        return np.full(len(rngs), t_lo)
    return np.array([r.uniform(t_lo, t_hi) for r in rngs])


def empty_result(n_episodes: int, metrics) -> dict:
    out = {k: np.zeros(n_episodes) for k in STANDARD + tuple(metrics)}
    out["success"] = np.zeros(n_episodes, dtype=np.bool_)
    out["violations"] = np.zeros(n_episodes, dtype=np.int64)
    return out
