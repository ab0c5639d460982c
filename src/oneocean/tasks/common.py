"""What every task's episode loop shares: the task layer's random-stream purposes, the
standard result columns (:data:`STANDARD`) and :func:`rollout_results`, the common head of
every agent's observation (:data:`OBS_FIELDS`, :func:`observe_common`, :func:`record_step`)
and the recorded action (:data:`ACT_FIELDS`), the status ``OK``, the depth, altitude and
clearance constants, the true current at a point (:func:`current_at`) and the numba cache
hygiene of the task kernels (:func:`fresh_cache`).

The rest of the task layer's shared pieces have their own modules: tier tables
(:mod:`oneocean.tasks.tiers`), the current regime (:mod:`oneocean.tasks.regime`), what a
reset draws (:mod:`oneocean.tasks.spawn`) and the mission computer's waypoint geometry
(:mod:`oneocean.tasks.waypoints`); the methods' steering laws are
:mod:`oneocean.methods.steering`. The per-agent step
(:func:`oneocean.engine.step.advance_agent`: clip, energy, dynamics, feasibility) and
everything else every episode shares is in the one episode loop (:mod:`oneocean.tasks.loop`);
task modules hold only their own world.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..engine import status as st
from ..engine._jit import hot_kernel
from ..engine.grid import sample_current_data, sample_elevation, synthetic_tide
from ..engine.rng import PURPOSE_TASK

#: Random-stream purposes of the task layer (counter-based: ``normal(seed, ep, purpose, k)``;
#: ``PURPOSE_TASK + 1`` and ``+ 4 .. + 6`` are the sensor models': :mod:`oneocean.sensing`).
PURPOSE_PROBE = PURPOSE_TASK + 1
PURPOSE_RESET = PURPOSE_TASK + 2
PURPOSE_TASK_NOISE = PURPOSE_TASK + 3

#: Columns every task returns for every episode (then its own METRICS).
STANDARD = ("success", "T_s", "E", "coll_ratio", "violations", "current_speed_ms")

#: The common head of every agent's observation, one row per (episode, step, agent)
#: (:func:`observe_common`; a task appends its own fields, its ``OBS_EXTRA``): the task's cue
#: relative to the agent's navigation estimate (the point the task's mission computer gives:
#: goal, station, route carrot, slot, ...; NaN where the task gives none), the current the
#: agent knows there (its estimate: :mod:`oneocean.sensing`), depth (pressure) and altitude
#: above the seafloor (DVL), the task's probe (SPC: surface concentration kg m-2; PI: the
#: sensor reading; NaN where the task has none), the N_MATES nearest teammates' horizontal
#: offsets (NaN when there are fewer teammates), the agent's navigation estimate (x east,
#: z north), heading (rad from north, clockwise) and velocity over ground (DVL, world x, y,
#: z), the time since the episode started, the energy proxy it has used (sum of
#: ``|a|^2 dt``, m2 s-1) and whether an absolute position fix (GNSS at the surface, the
#: support vessel's USBL) came at the last step (1) or not (0). World frame, metres, m s-1.
N_MATES = 3
OBS_FIELDS = (("goal_dx_m", "goal_dy_m", "goal_dz_m", "current_e_ms", "current_n_ms",
               "depth_m", "altitude_m", "pollution")
              + tuple(f"mate{m + 1}_{c}_m" for m in range(N_MATES) for c in ("dx", "dz"))
              + ("x_m", "z_m", "heading_rad", "vx_ms", "vy_ms", "vz_ms", "t_s", "energy_m2s",
                 "fix"))
OBS_DIM = len(OBS_FIELDS)
#: The common head's fields: name -> (unit, meaning).
OBS_DOCS = {
    "goal_dx_m": ("m", "the task's cue minus the agent's navigation estimate, east"),
    "goal_dy_m": ("m", "the same, down (depth)"),
    "goal_dz_m": ("m", "the same, north"),
    "current_e_ms": ("m s-1", "the current the agent knows at its position, east: the "
                     "briefing's forecast corrected by a Kalman filter on in-situ samples "
                     "(ADCP/DVL class); the truth for the oracle"),
    "current_n_ms": ("m s-1", "the same, north"),
    "depth_m": ("m", "depth (pressure sensor)"),
    "altitude_m": ("m", "height above the seafloor (DVL beams)"),
    "pollution": ("task's", "the task's probe (SPC: surface concentration, kg m-2; PI: the "
                  "plume sensor's reading); NaN where the task has none"),
    **{f"mate{m + 1}_{c}_m": ("m", f"the {m + 1}{('st', 'nd', 'rd')[m]} nearest teammate's "
                              f"offset from the agent, {'east' if c == 'dx' else 'north'} "
                              "(navigation estimates; NaN: no such teammate)")
       for m in range(N_MATES) for c in ("dx", "dz")},
    "x_m": ("m", "the agent's navigation estimate, east (DVL dead reckoning with the task's "
            "position fixes; the truth for the oracle)"),
    "z_m": ("m", "the same, north"),
    "heading_rad": ("rad", "heading, clockwise from north (compass)"),
    "vx_ms": ("m s-1", "velocity over ground, east (DVL)"),
    "vy_ms": ("m s-1", "the same, down"),
    "vz_ms": ("m s-1", "the same, north"),
    "t_s": ("s", "time since the episode started (the step times dt)"),
    "energy_m2s": ("m2 s-1", "the energy proxy the agent used so far, sum of |a|^2 dt"),
    "fix": ("", "1 if an absolute position fix (GNSS at the surface, the support vessel's "
            "USBL) came at the last step, else 0"),
}
assert tuple(OBS_DOCS) == OBS_FIELDS
#: Column of each common field in an observation row, by name and as constants (jit code).
OBS = {name: j for j, name in enumerate(OBS_FIELDS)}
(O_GX, O_GY, O_GZ, O_CE, O_CN, O_DEPTH, O_ALT, O_PROBE, O_MATES, O_X, O_Z, O_PSI, O_VX, O_VY,
 O_VZ, O_T, O_ENERGY, O_FIX) = (0, 1, 2, 3, 4, 5, 6, 7, 8, 14, 15, 16, 17, 18, 19, 20, 21, 22)
#: The recorded action: the method's through-water velocity request (world m s-1), before
#: the engine clips it to v_max.
ACT_FIELDS = ("ax_ms", "ay_ms", "az_ms")

#: Status code of :func:`advance_agent` (re-exported for kernels).
OK = st.OK

# shared by the single-vehicle navigation tasks (G2G, SK, RF, DPT) and FT
#: Depth range of starts, goals and routes, m (positive down).
DEPTH_RANGE_M = (2.0, 10.0)
#: Minimum altitude above the seafloor of starts, goals and the segments between them, m.
MIN_ALTITUDE_M = 5.0
#: Seafloor clearance of the feasibility check during the rollout, m (engine default).
CLEARANCE_M = 1.0


@hot_kernel(inline="always")
def current_at(grid, x, y, z, t):
    """True current at a world point and time, gain and tides included.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    x, y, z : float
        World position (x east, y depth positive down, z north), m.
    t : float
        Time, s since the grid's ``time0``.

    Returns
    -------
    ce, cn : float
        Eastward and northward current, m s-1.
    """
    ce, cn = sample_current_data(grid, x, y, z, t)
    te, tn = synthetic_tide(grid, t)
    return ce + te, cn + tn


def fresh_cache(kernel, module_file: str, *deps) -> bool:
    """Drop ``kernel``'s stale numba cache entries at import (:func:`ensure_fresh_cache`).

    numba keys a cache entry on the kernel's own file only; a task kernel also inlines (or
    links) the engine, this module, the episode loop (``loop.py``), the sensor models
    (``sensing/kernels.py``), the learned controller it calls (``learned.py``), the resets'
    samplers (``spawn.py``), the waypoint geometry (``waypoints.py``), the methods' steering
    laws (``methods/steering.py``) and ``deps``, so the fingerprint covers exactly those:
    editing one task recompiles that task alone.

    Parameters
    ----------
    kernel : numba dispatcher
        The kernel module's cached kernel.
    module_file : str
        The kernel module's ``__file__``.
    *deps : path-like
        Further files it depends on (its task module, its policy module, a model file).

    Returns
    -------
    bool
        True if cache files were removed.
    """
    from ..engine._jit import ensure_fresh_cache

    here = Path(module_file).resolve()
    mine = Path(__file__).resolve()
    learned = mine.with_name("learned.py")
    sensing = mine.parents[1] / "sensing" / "kernels.py"
    steering = mine.parents[1] / "methods" / "steering.py"
    return ensure_fresh_cache(kernel, (here.stem + ".",), here, mine,
                              mine.with_name("loop.py"), learned, sensing,
                              mine.with_name("spawn.py"), mine.with_name("waypoints.py"),
                              steering, *(Path(d).resolve() for d in deps))


def rollout_results(res: np.ndarray, columns, obs, act, record: bool) -> dict:
    """A task kernel's result matrix as the ``rollout`` dict.

    Parameters
    ----------
    res : (E, C) float64
        Result rows, one column per name of ``columns``.
    columns : sequence of str
        Column names (the task's ``COLUMNS``).
    obs : (E, n_steps, N, OBS_DIM) float64
        Recorded observations (:meth:`oneocean.tasks.episodes.Episodes` ``record``).
    act : (E, n_steps, N, 3) float64
        Recorded actions.
    record : bool
        Include ``obs`` and ``act``.

    Returns
    -------
    dict
        One (E,) array per column (``success`` bool, ``violations`` int64, the rest float64),
        plus ``obs`` / ``act`` when ``record``.
    """
    out = {k: res[:, i].copy() for i, k in enumerate(columns)}
    out["success"] = out["success"] > 0.5
    out["violations"] = out["violations"].astype(np.int64)
    if record:
        out["obs"], out["act"] = obs, act
    return out


@hot_kernel(inline="always")
def observe_common(o, grid, X, state, e, i, gx, gy, gz, pe, pn, probe, t_s, energy, fix):
    """Write the common head (:data:`OBS_FIELDS`) of agent ``i``'s observation row ``o``.

    The cue, the teammates' offsets, the position and the velocity are the states the method
    knows (``X``: its navigation estimate, the truth for the oracle); depth (pressure sensor)
    and altitude (the DVL's beams) are measured, so they come from the true ``state``.

    Parameters
    ----------
    o : (D,) float64
        The observation row, its first :data:`OBS_DIM` values written.
    grid : Grid
        The grid export (the true seafloor under the agent).
    X, state : (E, N, STATE_DIM) float64
        The states the method knows and the true states.
    e, i : int
        Episode and agent.
    gx, gy, gz : float
        The task's cue, world m.
    pe, pn : float
        The current estimate, east and north, m s-1.
    probe : float
        The task's probe (NaN: none).
    t_s : float
        Time since the episode started, s.
    energy : float
        The agent's energy proxy so far, m2 s-1.
    fix : int
        1 if an absolute position fix came at the last step.
    """
    px = X[e, i, 0]
    py = X[e, i, 1]
    pz = X[e, i, 2]
    o[0] = gx - px
    o[1] = gy - py
    o[2] = gz - pz
    o[3] = pe
    o[4] = pn
    o[5] = state[e, i, 1]
    o[6] = -sample_elevation(grid, state[e, i, 0], state[e, i, 2]) - state[e, i, 1]
    o[7] = probe
    n_ag = X.shape[1]
    d_prev = -1.0
    j_prev = -1
    for m in range(N_MATES):
        best = -1
        d_best = math.inf
        for j in range(n_ag):
            if j == i:
                continue
            d = (X[e, j, 0] - px) ** 2 + (X[e, j, 2] - pz) ** 2
            # strictly after the previous pick in (distance, index) order
            if (d > d_prev or (d == d_prev and j > j_prev)) and d < d_best:
                best = j
                d_best = d
        if best < 0:
            o[8 + 2 * m] = math.nan
            o[9 + 2 * m] = math.nan
        else:
            o[8 + 2 * m] = X[e, best, 0] - px
            o[9 + 2 * m] = X[e, best, 2] - pz
            d_prev = d_best
            j_prev = best
    o[14] = px
    o[15] = pz
    o[16] = X[e, i, 5]
    o[17] = X[e, i, 12]
    o[18] = X[e, i, 13]
    o[19] = X[e, i, 14]
    o[20] = t_s
    o[21] = energy
    o[22] = fix


@hot_kernel
def record_step(rec_o, rec_a, O, e, k, i, ax, ay, az):
    """Record agent ``i``'s observation and its requested action at step ``k``.

    Not inlined: it runs only while recording, and one compiled copy shared by every task
    kernel keeps their compile times down.

    Parameters
    ----------
    rec_o, rec_a : (E, S, N, D) and (E, S, N, 3) float64
        The observation and action records, ``[e, k, i]`` written.
    O : (E, N, D) float64
        This step's observations.
    e, k, i : int
        Episode, step and agent.
    ax, ay, az : float
        The requested action, world m s-1.
    """
    r = rec_o[e, k, i]
    o = O[e, i]
    for d in range(o.shape[0]):
        r[d] = o[d]
    a = rec_a[e, k, i]
    a[0] = ax
    a[1] = ay
    a[2] = az


# this module's cache entries (record_step; current_at and observe_common when called from
# Python, which inline the engine's current and seafloor): drop them when the engine or this
# file changes
def _fresh_own_cache() -> None:
    from ..engine._jit import ensure_fresh_cache

    ensure_fresh_cache(record_step, ("common.",), Path(__file__).resolve())


_fresh_own_cache()
