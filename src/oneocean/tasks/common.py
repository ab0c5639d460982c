"""Pieces every task shares: probes, seeds, start times, steering helpers, observation
recording, tier tables and result columns.

The per-agent step (:func:`oneocean.engine.step.advance_agent`: clip, energy, dynamics,
feasibility) and everything else every episode shares is in the one episode loop
(:mod:`oneocean.tasks.loop`); task modules hold only their own world.
"""

from __future__ import annotations

import copy
import functools
import math
import os
from importlib import resources
from pathlib import Path
from typing import NamedTuple

import numpy as np
import yaml

from ..engine import status as st
from ..engine import streams
from ..engine.constraints import check_move
from ..engine._jit import hot_kernel
from ..engine.grid import Grid, sample_current_data, sample_elevation, synthetic_tide
from ..engine.rng import PURPOSE_TASK
from ..errors import ConfigError, NotApplicable

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
#: Transit arrival radius of the lawnmower followers (:func:`waypoint_carrot`), m: wider than
#: the REMUS 100's 10 m turning diameter, so a torpedo never orbits its first waypoint.
ARRIVE_M = 12.0
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


@hot_kernel(inline="always")
def seek(px, py, pz, gx, gy, gz, speed, kp, ce, cn):
    """Velocity request (relative to water) toward a goal, with current feed-forward.

    P-control of the ground velocity, ``min(kp d, speed)`` along the goal direction (``d`` the
    distance to the goal), plus feed-forward cancelling the (probed) current ``(ce, 0, cn)``.

    Parameters
    ----------
    px, py, pz : float
        Vehicle position, world m.
    gx, gy, gz : float
        Goal position, world m.
    speed : float
        Cap of the ground speed toward the goal, m s-1.
    kp : float
        Proportional gain, s-1.
    ce, cn : float
        Current (east, north) to cancel, m s-1.

    Returns
    -------
    ax, ay, az : float
        Velocity request relative to the water, world frame, m s-1 (not clipped; the engine
        clips it to ``v_max``).
    """
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
    """The tier table of one task.

    Parsed once per file version; every call returns a fresh copy (callers may change it).

    Parameters
    ----------
    task_id : str
        Registered task id.
    path : str or Path, optional
        The table file; default the registry spec's ``table_path`` (for the built-ins
        ``data/tasks/<ID>.yaml``).

    Returns
    -------
    dict
        ``agents``, ``dt_s``, ``harder``, ``tiers`` (int keys) and the table's other blocks
        (``spec``, ``scene_tiers``, ``vehicle``, ``calibration``, ...).

    Raises
    ------
    ConfigError
        If the file cannot be read or is malformed (missing key, undeclared tier parameter, bad
        ``vehicle`` or ``calibration.seeds``).
    """
    return copy.deepcopy(shared_task_table(task_id, path))


def shared_task_table(task_id: str, path: str | Path | None = None) -> dict:
    """:func:`load_task_table`'s table itself, not a copy: for readers on a hot path (an
    episode batch's set-up reads a key or two), which must not change it.

    Parameters
    ----------
    task_id : str
        Registered task id.
    path : str or Path, optional
        The table file (as :func:`load_task_table`).

    Returns
    -------
    dict
        The parsed table, shared by every caller until the file changes.

    Raises
    ------
    ConfigError
        As :func:`load_task_table`.
    """
    if path is None:
        from ..registry import task_spec

        path = task_spec(task_id).table_path
    f = Path(path)
    try:
        stamp = f.stat()
    except OSError as exc:
        raise ConfigError(f"{f}: cannot read tier table ({exc.strerror})") from None
    return _task_table(os.path.abspath(f), stamp.st_mtime_ns, stamp.st_size)


@functools.lru_cache(maxsize=64)
def _task_table(path: str, mtime_ns: int, size: int) -> dict:
    f = Path(path)
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
    if "vehicle" in doc and not isinstance(doc["vehicle"], str):
        raise ConfigError(f"{f}: 'vehicle' must be a vehicle name (data/vehicles.yaml), got "
                          f"{doc['vehicle']!r}")
    for tier, params in (doc.get("scene_tiers") or {}).items():
        bad = sorted(set(params) - set(doc["harder"]) - {"current_gain"})
        if bad:
            raise ConfigError(f"{f}: scene_tiers {tier} parameter '{bad[0]}' is not a tier "
                              f"parameter (declared in 'harder') nor current_gain")
    cal = doc.get("calibration")
    if cal is not None:
        seeds = cal.get("seeds") if isinstance(cal, dict) else None
        if not (isinstance(seeds, list) and seeds
                and all(isinstance(x, int) and not isinstance(x, bool) for x in seeds)):
            raise ConfigError(f"{f}: 'calibration.seeds' must be a non-empty list of integer "
                              f"seeds, got {seeds!r}")
    return doc


def tier_params(task_id: str, tier: int, scene: bool = False) -> dict:
    """The parameters of one tier of a task.

    Parameters
    ----------
    task_id : str
        Registered task id.
    tier : int
        Tier number.
    scene : bool
        True for a scene (either backend on a scene's local grid): the table's ``scene_tiers``
        row goes on top (the mission at scene scale and the tier's current multiplier
        ``current_gain``).

    Returns
    -------
    dict
        The tier's row of the tier table (a copy).

    Raises
    ------
    ConfigError
        Unknown tier, or a scene tier missing from ``scene_tiers``.
    NotApplicable
        ``scene=True`` for a task without ``scene_tiers`` (the message names the tasks that
        have one).
    """
    table = load_task_table(task_id)
    if tier not in table["tiers"]:
        raise ConfigError(f"task {task_id}: unknown tier {tier!r}; valid tiers are "
                          f"{sorted(table['tiers'])}")
    out = dict(table["tiers"][tier])
    if scene:
        rows = table.get("scene_tiers")
        if not rows:
            raise NotApplicable(f"task {task_id} has no scene_tiers in its tier table, so it "
                                f"does not run in a scene; tasks with scene tiers: "
                                f"{', '.join(scene_tasks())}")
        if tier not in rows:
            raise ConfigError(f"task {task_id}: scene_tiers has no tier {tier}")
        out.update(rows[tier])
    return out


def scene_tasks() -> tuple[str, ...]:
    """The tasks whose tier table has ``scene_tiers``.

    Returns
    -------
    tuple of str
        Task ids (:func:`oneocean.registry.scene_tasks`).
    """
    from ..registry import scene_tasks as _scene_tasks

    return _scene_tasks()


# ------------------------------------------------------------------------------ resets

def episode_rows(init: dict, index, n_all: int) -> dict:
    """A reset dict's episodes ``index``: every array whose leading axis has the ``n_all``
    episodes is indexed along it; other entries (scalars, shared arrays) are kept as they are.

    Parameters
    ----------
    init : dict
        A reset dict (the tasks' ``reset``, :meth:`oneocean.tasks.Cell.reset`).
    index : slice or numpy.ndarray
        Which episodes (a slice, or integer indices).
    n_all : int
        The number of episodes ``init`` holds.

    Returns
    -------
    dict
        The same keys; a slice gives views, integer indices copies.
    """
    return {k: (v[index] if isinstance(v, np.ndarray) and v.ndim and v.shape[0] == n_all
                else v) for k, v in init.items()}


def episode_seed_sequence(seed: int, episode: int, purpose: int) -> np.random.SeedSequence:
    """The ``SeedSequence`` of one episode's random stream.

    Parameters
    ----------
    seed : int
        Run seed.
    episode : int
        Episode index.
    purpose : int
        Stream purpose (``PURPOSE_*``).

    Returns
    -------
    numpy.random.SeedSequence
        ``SeedSequence([seed, episode, purpose])``.
    """
    return np.random.SeedSequence([int(seed), int(episode), int(purpose)])


def episode_generators(seed: int, n_episodes: int, purpose: int = PURPOSE_RESET):
    """One independent random generator per episode.

    Parameters
    ----------
    seed : int
        Run seed.
    n_episodes : int
        Number of episodes.
    purpose : int
        Stream purpose, default ``PURPOSE_RESET``.

    Returns
    -------
    list of numpy.random.Generator
        Generator ``e`` seeded with :func:`episode_seed_sequence` ``(seed, e, purpose)``.
    """
    return [np.random.default_rng(episode_seed_sequence(seed, e, purpose))
            for e in range(n_episodes)]


def start_times(grid: Grid, rngs, duration_s: float) -> np.ndarray:
    """Episode start times, uniform over the part of the grid's time span that leaves
    ``duration_s`` of data.

    Parameters
    ----------
    grid : Grid
        The grid export.
    rngs : sequence of numpy.random.Generator, or (n, 4) uint64
        One generator per episode, or one stream per episode
        (:func:`oneocean.engine.streams.episode_states`, advanced in place); each gives one
        uniform draw.
    duration_s : float
        Episode duration, s.

    Returns
    -------
    (len(rngs),) float64
        Start times, s since the grid's ``time0``; all the grid's first time (no draw) where
        the span is shorter than ``duration_s`` (e.g. a single-time grid).
    """
    t_lo = float(grid.time_s[0])
    t_hi = float(grid.time_s[-1]) - float(duration_s)
    if t_hi <= t_lo:
        return np.full(len(rngs), t_lo)
    if isinstance(rngs, np.ndarray):
        return streams.uniform_rows(rngs, t_lo, t_hi)[:, 0]
    return np.array([r.uniform(t_lo, t_hi) for r in rngs])


# ------------------------------------------------------------------------------ current regime

class Regime(NamedTuple):
    """A tier's current regime on one region: episodes are accepted where the mean current
    speed over the episode lies in ``[lo, hi]`` m s-1, the region's own speed quantiles
    ``band = (q_lo, q_hi)`` (tier key ``current_band``) at the reference depth ``depth_m``.

    The quantiles are taken over every water node of the grid level nearest ``depth_m`` and
    every time of the grid (the data current with its tide layers, as ``Cell.grid_reset``
    holds it: no run forcing, so forcing ablations replay the same episodes), so "Tier 3 = the
    fastest third of this region's water" means the same in a calm region and in a tidal one.
    """

    band: tuple
    lo: float
    hi: float
    depth_m: float


#: Most bytes of one grid level's currents at its nodes a :class:`RegimeSampler` keeps
#: (``REGIME_LEVELS_KEPT`` of them at most); beyond it the speeds are sampled from the grid
#: at each depth (the same numbers, slower).
REGIME_LEVEL_BYTES = 64 * 2 ** 20
REGIME_LEVELS_KEPT = 4


class RegimeSampler:
    """The speeds a grid's current regime takes its quantiles of, at any reference depth.

    The samples are every water node of the grid level nearest the depth (every
    ``jj.size // 20000``-th, at most about 40,000) at every time of the grid: the
    :func:`~oneocean.engine.grid.sample_speeds_times` of those points at that depth, the
    same bits. The nodes and each level's data current at them are kept
    (:func:`~oneocean.engine.grid.level_currents`), so the next depth between the same two
    levels costs only the blend and the ``hypot`` (a reset's candidates are drawn at their
    own median depth, a different one for every seed).

    Parameters
    ----------
    grid : Grid
        The grid export (``Cell.grid_reset``: the data current, the tier's gain).
    """

    def __init__(self, grid: Grid):
        self.grid = grid
        self._nodes = {}      # nearest level -> (x, z, cells, weights)
        self._levels = {}     # (nearest level, level) -> (T, P, 2) currents, or None

    def nodes(self, depth_m: float) -> tuple:
        """The sampled water nodes for a depth.

        Parameters
        ----------
        depth_m : float
            Reference depth, m.

        Returns
        -------
        tuple
            ``(k, x, z)``: the grid level nearest ``depth_m`` (int) and the nodes' positions
            east and north, (P,) float64 each, m.

        Raises
        ------
        NotApplicable
            No water with currents on that level.
        """
        grid = self.grid
        k = int(np.argmin(np.abs(np.asarray(grid.depth) - float(depth_m))))
        hit = self._nodes.get(k)
        if hit is None:
            water = (np.asarray(grid.valid[k]) == 1) & (np.asarray(grid.land) < 0.5)
            jj, ii = np.nonzero(water)
            if jj.size == 0:
                raise NotApplicable(f"no water with currents at {depth_m:g} m")
            stride = max(1, jj.size // 20000)
            jj, ii = jj[::stride], ii[::stride]
            x = grid.x0 + ii * grid.dx
            z = grid.z0 + jj * grid.dz
            hit = self._nodes[k] = (x, z, None, None)
        return (k,) + hit[:2]

    def _parts(self, depth_m: float):
        """The nodes at ``depth_m`` (P, 3), the kept currents of the depth's two levels and of
        the tide layers and the weight of the deeper level; the levels None when they are not
        kept (too large, or times the kept levels cannot stand for)."""
        from ..engine.grid import _point_weights, level_currents, tide_layer_currents

        grid = self.grid
        k, x, z = self.nodes(depth_m)
        xyz = np.column_stack([x, np.full(x.size, float(depth_m)), z])
        n_t, n_p = len(grid.time_s), x.size
        if n_t * n_p * 16 > REGIME_LEVEL_BYTES:
            return xyz, None, None, None, 0.0
        _, _, cells, weights = self._nodes[k]
        if cells is None:
            cells = np.empty((n_p, 4), dtype=np.int64)
            weights = np.empty((n_p, 5))
            _point_weights(grid, xyz, cells, weights)
            self._nodes[k] = (x, z, cells, weights)
        # the depth's levels and weight (the horizontal place does not depend on it)
        c1 = np.empty((1, 4), dtype=np.int64)
        w1 = np.empty((1, 5))
        _point_weights(grid, xyz[:1], c1, w1)
        parts = []
        for level in (int(c1[0, 2]), int(c1[0, 3]), -1):
            key = (k, level)
            if key in self._levels:
                self._levels[key] = self._levels.pop(key)      # most recently used last
            else:
                while len(self._levels) >= REGIME_LEVELS_KEPT:
                    self._levels.pop(next(iter(self._levels)))
                if level < 0 and grid.tide_layers != 1:
                    self._levels[key] = np.zeros((1, 1, 2))
                elif level < 0:
                    out = np.empty((n_t, n_p, 2))
                    tide_layer_currents(grid, cells, weights, out)
                    self._levels[key] = out
                else:
                    out = np.empty((n_t, n_p, 2))
                    self._levels[key] = out if level_currents(grid, cells, weights, level,
                                                              out) else None
            parts.append(self._levels[key])
        if parts[0] is None or parts[1] is None:
            return xyz, None, None, None, 0.0
        return xyz, parts[0], parts[1], parts[2], float(w1[0, 4])

    def speeds(self, depth_m: float) -> np.ndarray:
        """Current speed at the nodes at every time of the grid.

        Parameters
        ----------
        depth_m : float
            Reference depth, m.

        Returns
        -------
        (T * P,) float64
            Speeds, m s-1, time-major: ``sample_speeds_times(grid, nodes at depth_m,
            grid.time_s)``, the same bits.
        """
        from ..engine.grid import sample_speeds_times, speeds_from_levels

        xyz, c0, c1, ct, wk = self._parts(depth_m)
        if c0 is None:
            return sample_speeds_times(self.grid, xyz, np.asarray(self.grid.time_s,
                                                                  dtype=np.float64))
        return speeds_from_levels(self.grid, c0, c1, ct, wk,
                                  np.empty(c0.shape[0] * c0.shape[1]))

    def quantiles(self, depth_m: float, qs) -> tuple:
        """Quantiles of :meth:`speeds`.

        From the speeds' order statistics
        (:func:`~oneocean.engine.grid.order_stats_from_levels`) when they can be certified,
        else from the speeds themselves.

        Parameters
        ----------
        depth_m : float
            Reference depth, m.
        qs : sequence of float
            Quantiles in ``[0, 1]``.

        Returns
        -------
        tuple of float
            ``np.quantile(self.speeds(depth_m), qs)`` (linear method), the same values,
            m s-1.
        """
        from ..engine.grid import order_stats_from_levels

        qs = [float(q) for q in qs]
        xyz, c0, c1, ct, wk = self._parts(depth_m)
        if c0 is not None and _linear_quantile_matches_numpy():
            size = c0.shape[0] * c0.shape[1]
            where = [_linear_quantile_ranks(size, q) for q in qs]
            ranks = np.array(sorted({r for w in where for r in w[:2]}), dtype=np.int64)
            vals = np.empty(ranks.size)
            if order_stats_from_levels(self.grid, c0, c1, ct, wk, ranks, np.empty(size),
                                       vals):
                at = dict(zip(ranks.tolist(), vals.tolist()))
                return tuple(_linear_quantile_lerp(at[i], at[j], gamma)
                             for i, j, gamma in where)
        return tuple(float(v) for v in np.quantile(self.speeds(depth_m), qs))


def _linear_quantile_ranks(n: int, q: float) -> tuple:
    """NumPy's linear-method quantile ``q`` of ``n`` sorted values: the ranks ``(i, j)`` it
    interpolates between and the weight ``gamma`` of ``j``."""
    v = float(n - 1) * q
    i = float(math.floor(v))
    j = i + 1.0
    if v >= n - 1:
        i = j = -1.0
    if v < 0:
        i = j = 0.0
    gamma = v - i
    return int(i) % n, int(j) % n, gamma


def _linear_quantile_lerp(a: float, b: float, gamma: float) -> float:
    """NumPy's interpolation between the two order statistics of a linear-method quantile."""
    d = b - a
    return b - d * (1.0 - gamma) if gamma >= 0.5 else a + d * gamma


@functools.lru_cache(maxsize=1)
def _linear_quantile_matches_numpy() -> bool:
    """Whether :func:`_linear_quantile_ranks` and :func:`_linear_quantile_lerp` give this
    NumPy's ``np.quantile`` to the bit (checked once per process on random samples; if not,
    the regime's quantiles are taken by ``np.quantile`` itself)."""
    rng = np.random.default_rng(12345)
    for n in (1, 2, 3, 7, 100, 1001):
        x = rng.gamma(2.0, 0.3, n)
        xs = np.sort(x)
        for q in (0.0, 1e-9, 0.15, 0.25, 1.0 / 3.0, 0.5, 0.55, 0.83, 0.999, 1.0):
            i, j, gamma = _linear_quantile_ranks(n, q)
            got = _linear_quantile_lerp(float(xs[i]), float(xs[j]), gamma)
            if got != float(np.quantile(x, q)):
                return False
    return True


def current_regime(grid: Grid, tier: dict, depth_m: float,
                   sampler: RegimeSampler | None = None) -> Regime | None:
    """The :class:`Regime` of a tier's ``current_band`` on ``grid``.

    Parameters
    ----------
    grid : Grid
        The grid export.
    tier : dict
        Tier parameters; ``current_band`` ``[q_lo, q_hi]``, speed quantiles with
        ``0 <= q_lo < q_hi <= 1``.
    depth_m : float
        Reference depth, m (the quantiles are taken on the grid level nearest it).
    sampler : RegimeSampler, optional
        A sampler of ``grid`` kept between calls (its levels are reused); a new one if None.

    Returns
    -------
    Regime or None
        The regime (``hi`` is inf when ``q_hi == 1``); None when the tier has no
        ``current_band``.

    Raises
    ------
    ConfigError
        A malformed ``current_band``.
    NotApplicable
        No water with currents at ``depth_m``.
    """
    band = tier.get("current_band")
    if band is None:
        return None
    try:
        q_lo, q_hi = (float(b) for b in band)
    except (TypeError, ValueError):
        raise ConfigError(f"current_band: expected [q_lo, q_hi], got {band!r}") from None
    if not 0.0 <= q_lo < q_hi <= 1.0:
        raise ConfigError(f"current_band: need 0 <= q_lo < q_hi <= 1, got {band!r}")
    if sampler is None or sampler.grid is not grid:
        sampler = RegimeSampler(grid)
    lo, hi = sampler.quantiles(depth_m, [q_lo, q_hi])
    return Regime((q_lo, q_hi), float(lo), float(hi) if q_hi < 1.0 else math.inf,
                  float(depth_m))


def site_speeds(grid: Grid, points, t0, duration_s: float, n_times: int = 5) -> np.ndarray:
    """Mean current speed of each candidate episode, in one vectorised sample.

    The mean over the candidate's points and ``n_times`` times evenly spread over
    ``[t0[c], t0[c] + duration_s]``: the current an episode there meets.

    Parameters
    ----------
    grid : Grid
        The grid export.
    points : (C, P, 3) array_like
        Points of each candidate, world m.
    t0 : (C,) array_like
        Start times, s since the grid's ``time0``.
    duration_s : float
        Episode duration, s.
    n_times : int
        Sample times per candidate.

    Returns
    -------
    (C,) float64
        Mean current speed, m s-1.
    """
    from ..engine.grid import sample_currents

    pts = np.asarray(points, dtype=np.float64)
    t0 = np.asarray(t0, dtype=np.float64)
    n_c, n_p = pts.shape[0], pts.shape[1]
    ts = np.linspace(t0, t0 + float(duration_s), int(n_times), axis=1)        # (C, T)
    xyz = np.broadcast_to(pts[:, None], (n_c, ts.shape[1], n_p, 3)).reshape(-1, 3)
    t = np.broadcast_to(ts[:, :, None], (n_c, ts.shape[1], n_p)).reshape(-1)
    c = sample_currents(grid, xyz, t)
    return np.hypot(c[:, 0], c[:, 1]).reshape(n_c, -1).mean(axis=1)


def site_speed(grid: Grid, points, t0: float, duration_s: float, n_times: int = 5) -> float:
    """:func:`site_speeds` of one episode.

    Parameters
    ----------
    grid : Grid
        The grid export.
    points : (P, 3) array_like
        The episode's points, world m.
    t0 : float
        Start time, s since the grid's ``time0``.
    duration_s : float
        Episode duration, s.
    n_times : int
        Sample times.

    Returns
    -------
    float
        Mean current speed, m s-1.
    """
    pts = np.atleast_2d(np.asarray(points, dtype=np.float64))
    return float(site_speeds(grid, pts[None], [float(t0)], duration_s, n_times)[0])


# ------------------------------------------------------------------------------ nav helpers
# (added for G2G/SK/RF/DPT/FT; generic: any task that steers to a point or samples a route)

@hot_kernel(inline="always")
def seek_max(px, py, pz, gx, gy, gz, v_max, kp, ce, cn):
    """Best-effort velocity request (relative to water, ``|a| <= v_max``) toward a goal.

    Cancels the cross-track part of the current ``(ce, 0, cn)`` first and spends the rest of
    the speed budget along the goal direction ("crabbing"), so the ground track points at the
    goal whenever ``|c_perp| < v_max``; the ground speed is ``min(kp * d, c_par +
    sqrt(v_max^2 - |c_perp|^2))``. At the goal it holds station (``-c``, clipped).
    The navigation tasks' steering: the oracle calls it with the exact current, the heuristic
    with its current estimate (both with the full ``v_max``).

    Parameters
    ----------
    px, py, pz : float
        Vehicle position, world m.
    gx, gy, gz : float
        Goal position, world m.
    v_max : float
        Speed budget through the water, m s-1 (<= 0: a zero request).
    kp : float
        Proportional gain on the distance ``d`` to the goal, s-1.
    ce, cn : float
        Current (east, north), m s-1.

    Returns
    -------
    ax, ay, az : float
        Velocity request relative to the water, world frame, m s-1.
    """
    if not v_max > 0.0:
        return 0.0, 0.0, 0.0
    dx = gx - px
    dy = gy - py
    dz = gz - pz
    d = math.sqrt(dx * dx + dy * dy + dz * dz)
    if d <= 1e-9:
        n = math.sqrt(ce * ce + cn * cn)
        if n > v_max:
            return -ce * v_max / n, 0.0, -cn * v_max / n
        return -ce, 0.0, -cn
    ux = dx / d
    uy = dy / d
    uz = dz / d
    c_par = ce * ux + cn * uz
    qx = ce - c_par * ux          # cross-track current (world)
    qy = -c_par * uy
    qz = cn - c_par * uz
    q2 = qx * qx + qy * qy + qz * qz
    if q2 >= v_max * v_max:
        f = v_max / math.sqrt(q2)
        return -qx * f, -qy * f, -qz * f
    v = c_par + math.sqrt(v_max * v_max - q2)   # fastest feasible ground speed along the goal
    if kp * d < v:
        v = kp * d
    return ux * v - ce, uy * v, uz * v - cn


def path_clear(grid: Grid, p0, p1, clearance: float, land_threshold: float = 0.5,
               spacing_m: float | None = None) -> bool:
    """Whether the straight segment ``p0 -> p1`` is feasible.

    Checked every ``spacing_m`` metres (:func:`oneocean.engine.constraints.feasibility`:
    land, grid extent and ``clearance`` above the seafloor).

    Parameters
    ----------
    grid : Grid
        The grid export.
    p0, p1 : (3,) array_like
        Segment ends, world m.
    clearance : float
        Seafloor clearance, m.
    land_threshold : float
        Land-mask threshold.
    spacing_m : float, optional
        Check spacing, m; default 20 m, or half the grid's node spacing where that is finer
        (a scene's local grid, whose thin structures a 20 m check would step over).

    Returns
    -------
    bool
        True if every check point is feasible.
    """
    from ..engine.constraints import feasibility

    if spacing_m is None:
        spacing_m = min(20.0, 0.5 * min(float(grid.dx), float(grid.dz)))
    p0 = np.asarray(p0, dtype=np.float64)
    p1 = np.asarray(p1, dtype=np.float64)
    d = p1 - p0                      # not np.linalg.norm: a 1-D norm is BLAS's dot, CPU-dependent
    n = max(2, int(math.ceil(math.sqrt(float(np.sum(d * d))) / spacing_m)) + 1)
    if p0.shape != (3,) or p1.shape != (3,):
        w = np.linspace(0.0, 1.0, n)[:, None]
        return bool(np.all(feasibility(grid, p0 + w * (p1 - p0), land_threshold, clearance)
                           == st.OK))
    return bool(_call(_segment_clear, grid, float(p0[0]), float(p0[1]), float(p0[2]),
                      float(p1[0]), float(p1[1]), float(p1[2]), int(n),
                      float(land_threshold), float(clearance)))


def paths_clear(grid: Grid, p0, p1, clearance: float, land_threshold: float = 0.5) -> np.ndarray:
    """:func:`path_clear` of many segments in one compiled call (the same checks, at its
    default spacing).

    Parameters
    ----------
    grid : Grid
        The grid export.
    p0, p1 : (m, 3) array_like
        Segment ends, world m.
    clearance : float
        Seafloor clearance, m.
    land_threshold : float
        Land-mask threshold.

    Returns
    -------
    (m,) bool
        Whether each segment is feasible.
    """
    p0 = np.ascontiguousarray(p0, dtype=np.float64).reshape(-1, 3)
    p1 = np.ascontiguousarray(p1, dtype=np.float64).reshape(-1, 3)
    spacing = min(20.0, 0.5 * min(float(grid.dx), float(grid.dz)))
    out = np.empty(p0.shape[0], dtype=np.bool_)
    return _call(_paths_kernel, grid, p0, p1, float(spacing), float(land_threshold),
                 float(clearance), out)


@hot_kernel
def _paths_kernel(grid, p0, p1, spacing, land_threshold, clearance, out):
    for j in range(p0.shape[0]):
        dx = p1[j, 0] - p0[j, 0]
        dy = p1[j, 1] - p0[j, 1]
        dz = p1[j, 2] - p0[j, 2]
        n = max(2, int(math.ceil(math.sqrt(dx * dx + dy * dy + dz * dz) / spacing)) + 1)
        out[j] = _segment_clear(grid, p0[j, 0], p0[j, 1], p0[j, 2], p1[j, 0], p1[j, 1],
                                p1[j, 2], n, land_threshold, clearance)
    return out


@hot_kernel
def _segment_clear(grid, ax, ay, az, bx, by, bz, n, land_threshold, clearance):
    """:func:`path_clear`'s test, compiled: the points ``p0 + w (p1 - p0)`` at ``w =
    np.linspace(0, 1, n)`` (the same values) all pass :func:`~oneocean.engine.constraints.
    check_move`; stops at the first that fails."""
    dx = bx - ax
    dy = by - ay
    dz = bz - az
    step = 1.0 / (n - 1)
    for i in range(n):
        w = 1.0 if i == n - 1 else i * step + 0.0
        if check_move(grid, ax + w * dx, ay + w * dy, az + w * dz, land_threshold,
                      clearance) != OK:
            return False
    return True


_ENTRIES: dict = {}
_MAX_ENTRIES = 16


def _call(kernel, grid, *args):
    """``kernel(grid, *args)`` through its compiled entry point for these argument types
    (:func:`oneocean.engine.dispatch.fast_entry`: no numba dispatch, which costs several us
    with the Grid's many arrays); the entry is kept per kernel and grid (the Grid itself
    is kept with it, so its id is not reused; at most ``_MAX_ENTRIES``, then the cache
    starts over, so few grids are held)."""
    key = (id(kernel), id(grid))
    hit = _ENTRIES.get(key)
    if hit is not None and hit[0] is grid:
        return hit[1](grid, *args)
    from ..engine.dispatch import fast_entry

    out = kernel(grid, *args)          # compiles (or loads) the version for these types
    if len(_ENTRIES) >= _MAX_ENTRIES:
        _ENTRIES.clear()
    _ENTRIES[key] = (grid, fast_entry(kernel, (grid,) + args))
    return out


def feasible_codes(grid: Grid, xyz, land_threshold: float, clearance: float) -> np.ndarray:
    """:func:`oneocean.engine.constraints.feasibility` through the compiled entry point.

    The same codes, without numba's dispatch: for the resets' many small checks.

    Parameters
    ----------
    grid : Grid
        The grid export.
    xyz : (n, 3) or (3,) array_like
        Points, world m.
    land_threshold : float
        Land-mask threshold.
    clearance : float
        Seafloor clearance, m.

    Returns
    -------
    (n,) int64
        Status of each point (:mod:`oneocean.engine.status`; ``OK`` = feasible).
    """
    from ..engine.constraints import check_points

    xyz = np.ascontiguousarray(np.atleast_2d(xyz), dtype=np.float64)
    return _call(check_points, grid, xyz, float(land_threshold), float(clearance),
                 np.empty(xyz.shape[0], dtype=np.int64))


#: Candidates of one start point (:func:`sample_route`), drawn ``_SPAWN_BATCH`` at a time.
_SPAWN_MAX = 4096
_SPAWN_BATCH = 64


def _spawn_one(grid: Grid, rng: np.random.Generator, y: float, land_threshold: float,
               clearance: float) -> np.ndarray:
    """``spawn_positions(grid, rng, 1, {"y": (y, y)}, land_threshold=..., clearance=...,
    max_candidates=4096)[0]`` (:func:`oneocean.engine.constraints.spawn_positions`): the same
    draws from ``rng`` and the same point, without its per-call overhead. Where no candidate
    is valid the generator is rewound and ``spawn_positions`` itself raises its ConfigError."""
    from ..engine.constraints import check_points, spawn_positions

    state = rng.bit_generator.state
    xl, xh = float(grid.x0), float(grid.x_max)
    zl, zh = float(grid.z0), float(grid.z_max)
    y = float(y)
    lt, cl = float(land_threshold), float(clearance)
    m = _SPAWN_BATCH
    codes = np.empty(m, dtype=np.int64)
    cand = np.empty((m, 3))
    for _ in range(_SPAWN_MAX // m):          # 4096 is a multiple of 64
        cand[:, 0] = rng.uniform(xl, xh, m)
        cand[:, 2] = rng.uniform(zl, zh, m)
        cand[:, 1] = rng.uniform(y, y, m)
        _call(check_points, grid, cand, lt, cl, codes)
        ok = np.flatnonzero(codes == st.OK)
        if ok.size:
            return cand[ok[0]].copy()
    rng.bit_generator.state = state
    return spawn_positions(grid, rng, 1, {"y": (y, y)}, land_threshold=land_threshold,
                           clearance=clearance, max_candidates=_SPAWN_MAX)[0]


def sample_route(grid: Grid, rng: np.random.Generator, n_legs: int, leg_m: float,
                 depth_m: tuple[float, float], clearance: float, *,
                 max_turn_rad: float = math.pi, land_threshold: float = 0.5,
                 vary_depth: bool = False, tries: int = 2000,
                 what: str = "route") -> np.ndarray:
    """A random polyline of ``n_legs`` straight legs, clear of land and the seafloor.

    Every leg is ``leg_m`` metres long at one depth (or between per-vertex depths with
    ``vary_depth``), clear of land and ``clearance`` m above the seafloor (:func:`path_clear`).
    ``n_legs = 0`` samples one valid point (a station).

    Parameters
    ----------
    grid : Grid
        The grid export.
    rng : numpy.random.Generator
        The episode's reset stream.
    n_legs : int
        Number of legs (0: one point).
    leg_m : float
        Leg length, m.
    depth_m : (lo, hi)
        Range of the (constant) route depth, m, positive down; drawn uniformly per try.
    clearance : float
        Seafloor clearance of the start point and of every leg, m.
    max_turn_rad : float
        Largest heading change between consecutive legs, rad (pi = any direction).
    land_threshold : float
        Land-mask threshold.
    vary_depth : bool
        Draw every vertex's depth independently in ``depth_m`` (a piecewise-linear depth
        profile whose straight 3-D legs all keep ``clearance``) instead of one depth.
    tries : int
        Attempts before giving up.
    what : str
        What is being drawn, for the error message.

    Returns
    -------
    (n_legs + 1, 3) float64
        Vertices (x, y, z) in world metres; vertex 0 is the start.

    Raises
    ------
    NotApplicable
        If no valid route was found in ``tries`` attempts, or no start point at the drawn
        depths five times (never a silent fallback): the region cannot host this cell.
    """
    n_legs = int(n_legs)
    lo, hi = float(depth_m[0]), float(depth_m[1])
    out = np.empty((n_legs + 1, 3))
    spawn_fails = 0
    for _ in range(int(tries)):
        y = rng.uniform(lo, hi)
        try:
            out[0] = _spawn_one(grid, rng, y, land_threshold, clearance)
        except ConfigError as exc:
            spawn_fails += 1
            if spawn_fails >= 5:   # no valid water at these depths: fail now, loudly
                raise NotApplicable(f"{what}: {exc}") from None
            continue
        heading = rng.uniform(-math.pi, math.pi)
        ok = True
        for leg in range(n_legs):
            if leg > 0:
                heading += rng.uniform(-max_turn_rad, max_turn_rad)
            p = out[leg] + leg_m * np.array([math.sin(heading), 0.0, math.cos(heading)])
            if vary_depth:
                p[1] = rng.uniform(lo, hi)
            if not path_clear(grid, out[leg], p, clearance, land_threshold):
                ok = False
                break
            out[leg + 1] = p
        if ok:
            return out
    raise _no_route(what, n_legs, leg_m, lo, hi, clearance, tries)


def _no_route(what, n_legs, leg_m, lo, hi, clearance, tries) -> NotApplicable:
    return NotApplicable(f"{what}: no {n_legs}-leg route of {leg_m:g} m legs at depths "
                         f"[{lo:g}, {hi:g}] m with {clearance:g} m clearance found in {tries} "
                         "tries; the region cannot host this tier")


@hot_kernel(inline="always")
def _spawn_one_c(grid, stv, r, cand, y, land_threshold, clearance):
    """:func:`_spawn_one` from stream ``r`` of ``stv``, compiled: batches of ``cand.shape[0]``
    x, then z, then y draws over the grid at depth ``y``, up to ``_SPAWN_MAX`` candidates.
    Returns the row of ``cand`` that holds the first valid point, or -1 (none: the draws of
    all ``_SPAWN_MAX`` spent, as ``spawn_positions`` spends them)."""
    xl, xh = grid.x0, grid.x_max
    zl, zh = grid.z0, grid.z_max
    m = cand.shape[0]
    for _b in range(_SPAWN_MAX // m):
        for c in range(m):
            cand[c, 0] = streams.uniform(stv, r, xl, xh)
        for c in range(m):
            cand[c, 2] = streams.uniform(stv, r, zl, zh)
        for c in range(m):
            cand[c, 1] = streams.uniform(stv, r, y, y)
        for c in range(m):
            if check_move(grid, cand[c, 0], cand[c, 1], cand[c, 2], land_threshold,
                          clearance) == OK:
                return c
    return -1


@hot_kernel(inline="always")
def _route_row(grid, stv, r, n_legs, leg_m, lo, hi, clearance, max_turn, land_threshold,
               vary_depth, tries, spacing, cand, out, j):
    """:func:`sample_route` from stream ``r`` of ``stv``, compiled: the same draws in the
    same order (``_spawn_one``'s batches of ``_SPAWN_BATCH`` x, then z, then y; a failed
    start point spends its ``_SPAWN_MAX`` candidates, as ``spawn_positions`` does) and the
    same checks; the vertices in ``out[j]``. Returns 0 (a route), 1 (five failed start
    points) or 2 (none in ``tries``)."""
    spawn_fails = 0
    for _ in range(tries):
        y = streams.uniform(stv, r, lo, hi)
        q = _spawn_one_c(grid, stv, r, cand, y, land_threshold, clearance)
        if q < 0:
            spawn_fails += 1
            if spawn_fails >= 5:
                return 1
            continue
        out[j, 0, 0] = cand[q, 0]
        out[j, 0, 1] = cand[q, 1]
        out[j, 0, 2] = cand[q, 2]
        heading = streams.uniform(stv, r, -math.pi, math.pi)
        ok = True
        for leg in range(n_legs):
            if leg > 0:
                heading += streams.uniform(stv, r, -max_turn, max_turn)
            ax, ay, az = out[j, leg, 0], out[j, leg, 1], out[j, leg, 2]
            px = ax + leg_m * math.sin(heading)
            py = ay + leg_m * 0.0
            pz = az + leg_m * math.cos(heading)
            if vary_depth:
                py = streams.uniform(stv, r, lo, hi)
            dx, dy, dz = px - ax, py - ay, pz - az
            n = max(2, int(math.ceil(math.sqrt(dx * dx + dy * dy + dz * dz) / spacing)) + 1)
            if not _segment_clear(grid, ax, ay, az, px, py, pz, n, land_threshold,
                                  clearance):
                ok = False
                break
            out[j, leg + 1, 0] = px
            out[j, leg + 1, 1] = py
            out[j, leg + 1, 2] = pz
        if ok:
            return 0
    return 2


@hot_kernel(inline="always")
def _spawn_altitude(grid, stv, r, cand, n, xl, xh, zl, zh, alt_lo, alt_hi, land_threshold,
                    clearance, sep2, max_candidates, out):
    """:func:`~oneocean.engine.constraints.spawn_positions` of ``n`` points with an
    ``altitude`` range from stream ``r`` of ``stv``, compiled: batches of ``cand.shape[0]``
    (``max(64, 4 (n - got))`` for ``n <= 16``) x, then z, then altitudes in NumPy's order,
    the candidates accepted greedily at squared separation ``sep2`` into ``out[:n]``.
    Returns how many were found (``n`` unless ``max_candidates`` ran out)."""
    m = cand.shape[0]
    got = 0
    tried = 0
    while got < n and tried < max_candidates:
        mb = min(m, max_candidates - tried)
        for c in range(mb):
            cand[c, 0] = streams.uniform(stv, r, xl, xh)
        for c in range(mb):
            cand[c, 2] = streams.uniform(stv, r, zl, zh)
        for c in range(mb):
            floor = -sample_elevation(grid, cand[c, 0], cand[c, 2])
            cand[c, 1] = floor - streams.uniform(stv, r, alt_lo, alt_hi)
        tried += mb
        for c in range(mb):
            if check_move(grid, cand[c, 0], cand[c, 1], cand[c, 2], land_threshold,
                          clearance) != OK:
                continue
            near = False
            for q in range(got):
                d0 = out[q, 0] - cand[c, 0]
                d1 = out[q, 1] - cand[c, 1]
                d2 = out[q, 2] - cand[c, 2]
                if d0 * d0 + d1 * d1 + d2 * d2 < sep2:
                    near = True
                    break
            if near:
                continue
            out[got, 0] = cand[c, 0]
            out[got, 1] = cand[c, 1]
            out[got, 2] = cand[c, 2]
            got += 1
            if got == n:
                break
    return got


@hot_kernel
def _routes_kernel(grid, stv, rows, n_legs, leg_m, lo, hi, clearance, max_turn, land_threshold,
                   vary_depth, tries, spacing, cand, out, status):
    """:func:`_route_row` of every stream ``rows[j]`` of ``stv`` into ``out[j]``;
    ``status[j]`` its result."""
    for j in range(rows.shape[0]):
        status[j] = _route_row(grid, stv, rows[j], n_legs, leg_m, lo, hi, clearance,
                               max_turn, land_threshold, vary_depth, tries, spacing, cand,
                               out, j)
    return status


def sample_routes(grid: Grid, stv: np.ndarray, n_legs: int, leg_m: float,
                  depth_m: tuple[float, float], clearance: float, *, rows=None,
                  max_turn_rad: float = math.pi, land_threshold: float = 0.5,
                  vary_depth: bool = False, tries: int = 2000, what=None):
    """:func:`sample_route` from each of several streams (:mod:`oneocean.engine.streams`) in
    one compiled call: the routes ``sample_route`` draws from the same streams' generators,
    bit for bit, and the streams advanced as far.

    Parameters
    ----------
    grid : Grid
        The grid export.
    stv : (n, 4) uint64
        Stream states (:func:`oneocean.engine.streams.episode_states`), advanced in place.
    n_legs, leg_m, depth_m, clearance, max_turn_rad, land_threshold, vary_depth, tries
        As :func:`sample_route`.
    rows : array_like of int, optional
        Which streams (default all).
    what : callable, optional
        ``what(j)``: what row ``j`` draws, for its error message (default ``"route"``).

    Returns
    -------
    routes : (len(rows), n_legs + 1, 3) float64
        Vertices, world m (undefined in a failed row).
    failed : dict
        ``{j: NotApplicable}`` for every row with no route: the error ``sample_route``
        raises there.
    """
    rows = (np.arange(stv.shape[0]) if rows is None
            else np.asarray(rows, dtype=np.int64).reshape(-1))
    n_legs = int(n_legs)
    lo, hi = float(depth_m[0]), float(depth_m[1])
    spacing = min(20.0, 0.5 * min(float(grid.dx), float(grid.dz)))    # path_clear's
    start = stv[rows].copy()
    out = np.zeros((rows.size, n_legs + 1, 3))
    status = _call(_routes_kernel, grid, stv, rows.astype(np.int64), n_legs, float(leg_m), lo,
                   hi, float(clearance), float(max_turn_rad), float(land_threshold),
                   bool(vary_depth), int(tries), float(spacing),
                   np.empty((_SPAWN_BATCH, 3)), out, np.empty(rows.size, dtype=np.int64))
    failed = {}
    for j in np.flatnonzero(status):
        label = "route" if what is None else what(int(j))
        if status[j] == 2:
            failed[int(j)] = _no_route(label, n_legs, leg_m, lo, hi, clearance, int(tries))
            continue
        try:         # the generator's own path raises its error (a start point's reasons)
            sample_route(grid, streams.generator(start[j]), n_legs, leg_m, depth_m,
                         clearance, max_turn_rad=max_turn_rad, land_threshold=land_threshold,
                         vary_depth=vary_depth, tries=tries, what=label)
        except NotApplicable as exc:
            failed[int(j)] = exc
        else:       # pragma: no cover - the two paths are tested to agree
            raise AssertionError(f"{label}: the compiled route sampler found no route where "
                                 "sample_route finds one")
    return out, failed


@hot_kernel(inline="always")
def steer(vx, vy, vz, budget, ce, cn):
    """Velocity request (relative to water, ``|a| <= budget``) realising a desired ground velocity
    under the current.

    Returns ``v - c`` when it fits the budget; otherwise keeps the ground track along ``v``
    if possible (cancels the cross-track current first, then the along-track ground speed
    closest to ``|v|`` that the rest of the budget allows), else fights the cross current
    with the whole budget. Used for slot / line-of-sight tracking with feed-forward.

    Parameters
    ----------
    vx, vy, vz : float
        Desired ground velocity ``v``, world frame, m s-1.
    budget : float
        Speed budget through the water, m s-1 (<= 0: a zero request).
    ce, cn : float
        Current ``c = (ce, 0, cn)``, m s-1.

    Returns
    -------
    ax, ay, az : float
        Velocity request relative to the water, world frame, m s-1.
    """
    if not budget > 0.0:
        return 0.0, 0.0, 0.0
    ax = vx - ce
    ay = vy
    az = vz - cn
    b2 = budget * budget
    if ax * ax + ay * ay + az * az <= b2:
        return ax, ay, az
    s = math.sqrt(vx * vx + vy * vy + vz * vz)
    if s <= 1e-9:
        n = math.sqrt(ce * ce + cn * cn)
        return -ce * budget / n, 0.0, -cn * budget / n
    ux = vx / s
    uy = vy / s
    uz = vz / s
    c_par = ce * ux + cn * uz
    qx = ce - c_par * ux
    qy = -c_par * uy
    qz = cn - c_par * uz
    q2 = qx * qx + qy * qy + qz * qz
    if q2 >= b2:
        f = budget / math.sqrt(q2)
        return -qx * f, -qy * f, -qz * f
    r = math.sqrt(b2 - q2)
    w = c_par + r if s > c_par else c_par - r
    return ux * w - ce, uy * w, uz * w - cn


@hot_kernel(inline="always")
def profile_at(ax_, ay_, az_, bx, by, bz, px, pz):
    """Horizontal projection of a point on a leg of a depth profile.

    Parameters
    ----------
    ax_, ay_, az_ : float
        Leg start (x, target depth, z), m.
    bx, by, bz : float
        Leg end (x, target depth, z), m.
    px, pz : float
        The point's horizontal position (x, z), m.

    Returns
    -------
    s : float
        Along-track position of the projection from the leg start, m (not clamped).
    length : float
        Horizontal leg length, m.
    tx, tz : float
        Unit horizontal tangent of the leg.
    y : float
        Target depth at the projection clamped to the leg, m.
    slope : float
        Profile slope ``dy/ds``.
    xt : float
        Horizontal distance from the point to the leg (a segment), m.

    Notes
    -----
    A leg shorter than 1e-12 m gives ``s = length = tx = tz = slope = 0``, ``y = by`` and the
    distance to its end.
    """
    lx = bx - ax_
    lz = bz - az_
    ln = math.sqrt(lx * lx + lz * lz)
    if ln <= 1e-12:
        return 0.0, 0.0, 0.0, 0.0, by, 0.0, math.sqrt((px - bx) ** 2 + (pz - bz) ** 2)
    tx = lx / ln
    tz = lz / ln
    s = (px - ax_) * tx + (pz - az_) * tz
    f = min(max(s / ln, 0.0), 1.0)
    qx = ax_ + f * lx - px
    qz = az_ + f * lz - pz
    return s, ln, tx, tz, ay_ + f * (by - ay_), (by - ay_) / ln, math.sqrt(qx * qx + qz * qz)


@hot_kernel(inline="always")
def nav_waypoint(route, nwp, e, px, py, pz, radius, horizontal):
    """The route's active waypoint as the vehicle's mission computer knows it.

    ``nwp[e]`` (1..W; W + 1 once the route is done) advances by one when the position the
    vehicle knows is within ``radius`` m of it. The task's judge keeps its own pointer on the
    true position, so a waypoint the vehicle believes it reached may not count. At most one
    waypoint per call (the same position gives the same pointer however often it is asked).

    Parameters
    ----------
    route : (E, W + 1, 3) float64
        Route vertices, world m (vertex 0 the start).
    nwp : (E,) int64
        The mission computer's waypoint pointers, updated in place.
    e : int
        Episode index.
    px, py, pz : float
        The position the vehicle knows, world m.
    radius : float
        Waypoint radius, m.
    horizontal : int
        1: distance in x and z only; 0: 3-D distance.

    Returns
    -------
    int
        The (updated) pointer ``nwp[e]``.
    """
    w = nwp[e]
    if w <= route.shape[1] - 1:
        dx = px - route[e, w, 0]
        dz = pz - route[e, w, 2]
        d2 = dx * dx + dz * dz
        if horizontal == 0:
            dy = py - route[e, w, 1]
            d2 += dy * dy
        if d2 <= radius * radius:
            nwp[e] = w + 1
    return nwp[e]


@hot_kernel(inline="always")
def los_carrot(px, pz, ax_, az_, bx, bz, look):
    """Line-of-sight carrot on segment a -> b: the projection of p plus ``look`` m, clamped to the
    segment.

    Parameters
    ----------
    px, pz : float
        The point p (x, z), m.
    ax_, az_ : float
        Segment start (x, z), m.
    bx, bz : float
        Segment end (x, z), m.
    look : float
        Lookahead along the segment, m.

    Returns
    -------
    cx, cz : float
        The carrot (x, z), m (b for a segment shorter than 1e-9 m).
    along : float
        Along-track position of p's projection from a, m (not clamped).
    length : float
        Segment length, m.
    """
    dx = bx - ax_
    dz = bz - az_
    L = math.sqrt(dx * dx + dz * dz)
    if L < 1e-9:
        return bx, bz, 0.0, 0.0
    ux = dx / L
    uz = dz / L
    s = (px - ax_) * ux + (pz - az_) * uz
    c = s + look
    if c > L:
        c = L
    if c < 0.0:
        c = 0.0
    return ax_ + c * ux, az_ + c * uz, s, L


@hot_kernel(inline="always")
def waypoint_carrot(wps, widx, wcount, e, i, px, pz, look, tol, arrive=0.0):
    """Follow agent ``i``'s waypoint list (AS and PI lawnmowers), in the horizontal plane.

    ``wps[e, i, :wcount[e, i]]`` are (x, z) waypoints and ``widx[e, i]`` the current one:
    0 = transit to the first (reached within ``2 tol``), then each leg w-1 -> w is followed
    with a line-of-sight carrot ``look`` m ahead (:func:`los_carrot`), advancing when the
    along-track end is within ``tol``; past the last waypoint the agent holds there.

    Parameters
    ----------
    wps : (E, N, n_max, 2) float64
        Waypoints (x, z) of every agent, m.
    widx : (E, N) int64
        Current waypoint of every agent, updated in place.
    wcount : (E, N) int64
        Number of waypoints of every agent.
    e : int
        Episode index.
    i : int
        Agent index.
    px, pz : float
        The agent's position (x, z), m.
    look : float
        Carrot lookahead, m.
    tol : float
        Leg-end tolerance, m.
    arrive : float
        > 0: the transit ends as soon as the agent is within ``arrive`` m of the first
        waypoint, checked before the leg is followed (a vehicle that cannot close on a point
        inside its turning circle, e.g. a torpedo, would orbit a ``2 tol`` target:
        :data:`ARRIVE_M`); 0: off.

    Returns
    -------
    gx, gz : float
        The carrot, m.
    w : int
        The waypoint index this step used (before a ``2 tol`` transit arrival is counted).
    """
    w = widx[e, i]
    if (w == 0 and arrive > 0.0
            and (px - wps[e, i, 0, 0]) ** 2 + (pz - wps[e, i, 0, 1]) ** 2 <= arrive * arrive):
        w = 1
        widx[e, i] = 1
    nw = wcount[e, i]
    gx = 0.0
    gz = 0.0
    if w >= 1 and w < nw:
        gx, gz, along, L = los_carrot(px, pz, wps[e, i, w - 1, 0], wps[e, i, w - 1, 1],
                                      wps[e, i, w, 0], wps[e, i, w, 1], look)
        if along >= L - tol:
            w += 1
            widx[e, i] = w
            if w < nw:
                gx, gz, along, L = los_carrot(px, pz, wps[e, i, w - 1, 0], wps[e, i, w - 1, 1],
                                              wps[e, i, w, 0], wps[e, i, w, 1], look)
    if w >= nw:  # done: hold at the last waypoint
        gx = wps[e, i, nw - 1, 0]
        gz = wps[e, i, nw - 1, 1]
    elif w == 0:  # transit to the first leg's start
        gx = wps[e, i, 0, 0]
        gz = wps[e, i, 0, 1]
        if (px - gx) ** 2 + (pz - gz) ** 2 <= 4.0 * tol * tol:
            widx[e, i] = 1
    return gx, gz, w


def fresh_cache(kernel, module_file: str, *deps) -> bool:
    """Drop ``kernel``'s stale numba cache entries at import (:func:`ensure_fresh_cache`).

    numba keys a cache entry on the kernel's own file only; a task kernel also inlines (or
    links) the engine, this module, the episode loop (``loop.py``), the sensor models
    (``sensing/kernels.py``) and the learned controller it calls (``learned.py``), and
    ``deps``, so the fingerprint covers exactly those: editing one task recompiles that task
    alone.

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
    return ensure_fresh_cache(kernel, (here.stem + ".",), here, mine,
                              mine.with_name("loop.py"), learned, sensing,
                              *(Path(d).resolve() for d in deps))




def need_tier(task_id: str, tier: dict, *keys: str) -> None:
    """Check that a tier has the parameters a task needs.

    Parameters
    ----------
    task_id : str
        Task id, for the message.
    tier : dict
        Tier parameters.
    *keys : str
        Parameters the task needs.

    Raises
    ------
    ConfigError
        One line naming the parameters ``keys`` missing from ``tier``.
    """
    missing = [k for k in keys if k not in tier]
    if missing:
        raise ConfigError(f"task {task_id}: tier parameters missing: {', '.join(missing)}")


def episode_steps(tier: dict) -> int:
    """Steps of an episode: ``ceil(time_limit_s / dt_s)`` (round-off tolerant).

    Parameters
    ----------
    tier : dict
        Tier parameters with ``time_limit_s`` and ``dt_s``, s.

    Returns
    -------
    int
        Number of steps.
    """
    return int(math.ceil(float(tier["time_limit_s"]) / float(tier["dt_s"]) - 1e-9))


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


# this module's own kernels (the resets' samplers) inline the engine's (check_move, the
# streams): drop their cache entries when the engine or this file changes
def _fresh_own_cache() -> None:
    from ..engine._jit import ensure_fresh_cache

    ensure_fresh_cache(_routes_kernel, ("common.",), Path(__file__).resolve())


_fresh_own_cache()

