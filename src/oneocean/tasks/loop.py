"""The one episode loop every task runs on, and the contract of a task's hooks.

A task (``oneocean.tasks.<id>``) says what the world does; a method (``oneocean.methods``)
says what the agents do. This loop owns everything they share, so no task re-implements it:
time, current sampling at every agent, the method's sensing and navigation (the sensor
models of :mod:`oneocean.sensing` for every non-oracle method, the truth for the oracle),
observation recording, the action (through :func:`advance_agent`:
clipping to ``v_max``, dynamics, feasibility), the energy proxy (eq. 7), rejected moves,
near-collisions (eq. 4, one ``r_coll``), termination, success and ``T``, and the metric
horizon (below) — in resumable segments of steps (``k_stop``), so a Python planner or a step
API can act between them.

Per step ``k`` of episode ``e`` (``t = t0[e] + k dt``)::

    env.pre_step                      task physics before the agents act (e.g. face velocities)
    X = the agents' state as the method knows it (navigation estimate; truth for the oracle)
    policy.plan(X)                    the method's team-level decision (assignment, map);
                                      skipped when a Python planner writes the plan tokens
    for every agent i:
        c   = true current at the agent (gain and tides included)
        c~  = the method's current estimate (forecast + filtered in-situ sample; or c)
        a   = policy.act(X, c~)       or the external action ext[e, i] (step API)
        record observation (env.cue on X) and action when asked
        advance_agent(a, c) on the true state; env.after_agent
    near-collision count (eq. 4) and the closest pair distance
    code = env.post_step              task physics after the moves, metrics, termination
    navigation errors propagate over the step (dead reckoning, GNSS at the surface)
    k += 1
    at the end: success = env.finish(...); T = k dt on success (k_succ dt after REACHED),
    else the time limit

Termination and the metric horizon. ``post_step`` returns a stop code: ``GO`` (0 / False:
continue), ``STOP`` (1 / True: the episode ends now: success or a terminal failure, as
``finish`` then says) or ``REACHED`` (2: the task's success was reached at this step, but the
episode runs on to its time limit, the task's fixed *metric horizon*, for metrics measured
over that horizon, e.g. SPC's cleanup rate). The loop latches the first ``REACHED`` step in
``LoopState.k_succ``; from then on the standard metrics are frozen: ``T`` is ``k_succ dt``
(time to success), and ``E``, ``violations``, the near-collision ratio (``coll / k_succ``)
and the closest pair distance ``LoopState.dmin`` cover the steps up to success, exactly what
a run that stopped there would report. Everything else (the world, the agents, the task's own
accumulators) runs to the horizon, and ``finish`` sees the final step.

Hooks are plain ``@hot_kernel`` functions of the task module (the env) and of its method
module (the policy); neither imports the other. The task's kernel module
(:mod:`oneocean.kernels`) passes them to :func:`run_episode` (``inline="always"``) from its
serial ``_episode`` (``hot_kernel``), which its kernel ``_kernel``
(``njit(cache=True, nogil=True)``) runs for a block of episodes ``[e_lo, e_hi)``, and
inlined in its step API's ``_step_kernel`` (one step per call);
:func:`oneocean.tasks.episodes.over_episodes` runs the blocks on numba's thread count (no
``prange``: the parfor pass more than doubles every task kernel's compile time). ``_observe``
/ ``_observe_kernel`` do the same for :func:`observe_next`. Two numba facts shape this
(numba 0.6x; ``tests/test_loop.py`` checks that the kernels cache and that the loop state is
written back):

* functions must reach the loop as module globals of the caller and the loop must be
  inlined there: a kernel that receives functions as run-time arguments embeds their
  addresses and cannot be cached ("uses dynamic globals"), so it recompiles in every process;
* code inlined directly into a ``prange`` body loses stores into arrays held by a
  heterogeneous NamedTuple (such as :class:`LoopState` or a task's work arrays): keep the
  serial ``_episode`` between any parallel loop and the inlined loop.

NamedTuple classes crossing into a kernel need package-unique names (numba's parfor lowering
resolves them by name: two classes both called ``Params`` collide), so they carry the task id.

Env hooks (``P``: the task's params NamedTuple, ``W``: its per-episode work arrays)::

    begin(grid, P, W, state, e) -> stop            before step 0 (state holds the start)
    pre_step(grid, P, W, state, e, k, t)
    cue(grid, P, W, state, e, k, i) -> (gx, gy, gz, probe)   observation's goal cue, probe
    after_agent(grid, P, W, state, e, k, i, code)  right after agent i moved
    post_step(grid, P, W, state, prev, e, k, t) -> GO | STOP | REACHED  (prev: positions
                                                   before the step; a bool is GO / STOP)
    finish(grid, P, W, state, e, k, row) -> success        writes the task's metric columns

Policy hooks (``M``: the method's params NamedTuple; ``state`` is the state the method knows,
``X`` above, and ``pe, pn`` its current estimate: a policy never sees the truth unless it is
the oracle's)::

    plan(grid, P, W, M, state, e, k, t)
    act(grid, P, W, M, state, e, k, i, t, pe, pn) -> (ax, ay, az, psi)
        desired velocity relative to the water (world m s-1) and heading (rad, NaN = free)
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, types
from numba.experimental import structref

from ..engine.constraints import min_pairwise_distance
from ..engine.dynamics import STATE_DIM, clip_action
from ..engine._jit import hot_kernel
from ..engine.step import advance_agent
from .learned import LearnedNet, learned_act
from ..sensing import SensingParams
from ..sensing.kernels import current_estimate, nav_fill, nav_update
from .common import OK, current_at, observe

#: Policy kinds inside the loop: the task's fused policy (heuristic, oracle, ...), an
#: external action per agent and step (``ext``; the step API and Python callables), or a
#: learned controller (a network, :mod:`oneocean.tasks.learned`, e.g. ``bc``: the fused
#: policy's mission layer -- its plan and target point -- with the action replaced by the
#: network's).
FUSED, EXTERNAL, LEARNED = 0, 1, 2

#: Columns every task writes first in its result row (then its metrics).
N_STANDARD = 6
C_SUCCESS, C_T, C_E, C_COLL, C_VIOL, C_CUR = range(N_STANDARD)


class LoopParams(NamedTuple):
    """Parameters of the loop (one rollout, all episodes)."""
    model: int          # dynamics model id (engine.dynamics.model_id)
    policy: int         # FUSED, EXTERNAL or LEARNED
    plan: int           # 1: call the fused policy's plan hook every step; 0: the plan tokens
                        # in W come from a Python planner between segments
    n_steps: int        # episode length, steps (the time limit)
    seed: int           # run seed (sensor-error streams)
    dt: float           # step, s
    v_max: float        # vehicle speed limit, m s-1
    sens: SensingParams  # what the method senses (oneocean.sensing; the truth for the oracle)
    land_thr: float     # land-mask threshold of the feasibility check
    clearance: float    # seafloor clearance of the feasibility check, m
    r_coll: float       # near-collision radius, m
    net: LearnedNet     # the learned controller (LEARNED; learned.no_net otherwise)
    phase: int = 0      # FULL (the core backend), DECIDE or JUDGE (another backend's physics)
    e0: int = 0         # the cell's episode of row 0: row e draws episode e0 + e's random
                        # streams (0 unless the cell runs in shards of episodes)


class LoopState(NamedTuple):
    """Per-episode state of the loop, kept between segments."""
    k: np.ndarray           # (E,) int64 steps taken
    status: np.ndarray      # (E,) int64 RUNNING / STOPPED / FINISHED
    energy: np.ndarray      # (E,) float64 team energy proxy, m2 s-1
    viol: np.ndarray        # (E,) int64 rejected moves (team)
    coll: np.ndarray        # (E,) int64 steps with a near-collision
    prev: np.ndarray        # (E, N, 3) positions before the current step, m
    k_succ: np.ndarray      # (E,) int64 steps to the REACHED success (-1: not reached)
    dmin: np.ndarray        # (E,) float64 smallest pair distance after a step, m (inf: N < 2)
    # what the method knows (oneocean.sensing.kernels): its navigation estimate of every
    # agent's state (the state the policy hooks see), position errors, dead-reckoning
    # constants, filtered forecast corrections and the episode's forecast error
    nav: np.ndarray         # (E, N, STATE_DIM) float64
    nerr: np.ndarray        # (E, N, 2) float64 horizontal position error (x, z), m
    navc: np.ndarray        # (E, N, 3) float64 1 + scale factor, cos / sin heading bias
    cb: np.ndarray          # (E, N, 2) float64 filtered forecast correction (east, north)
    fc: np.ndarray          # (E, 5) float64 forecast error (1 + gain, cos, sin, bias e, n)
    cur: np.ndarray         # (E,) float64 sum over agents and steps of the true current speed
    # the hand-over to a backend that moves the agents itself (phases DECIDE / JUDGE)
    en: np.ndarray          # (E, N) float64 energy proxy of each agent's executed action, m2 s-1
    cw: np.ndarray          # (E, N, 2) float64 true current at each agent (east, north), m s-1
    code: np.ndarray        # (E, N) int64 status of each agent's move (engine.status)
    # the step API's next observation sampled the true current at each agent for step k:
    # [x, y, z, k, east, north] (k = -1: none), which the step reuses at the same position
    ocur: np.ndarray        # (E, N, 6) float64


NEW, RUNNING, FINISHED = 0, 1, 2

#: What a call of the loop runs (``LoopParams.phase``): whole steps with the core's physics;
#: one step's decisions for a backend that moves the agents itself; that step's judging once
#: it has (:func:`run_episode`).
FULL, DECIDE, JUDGE = 0, 1, 2

#: Stop codes of the env's ``post_step`` (a bool return is GO / STOP): continue; end the
#: episode now; success reached at this step, run on to the metric horizon (the time limit).
GO, STOP, REACHED = 0, 1, 2


def new_loop_state(n_episodes: int, n_agents: int) -> LoopState:
    """A fresh :class:`LoopState`: every episode ``NEW`` at step 0, no success step
    (``k_succ = -1``), no pair distance yet (``dmin = inf``), everything else zero.

    Parameters
    ----------
    n_episodes : int
        Episodes E.
    n_agents : int
        Team size N.

    Returns
    -------
    LoopState
        Its arrays, shaped as the class documents.
    """
    E, N = n_episodes, n_agents
    return LoopState(np.zeros(E, np.int64), np.zeros(E, np.int64),
                     np.zeros(E), np.zeros(E, np.int64),
                     np.zeros(E, np.int64), np.zeros((E, N, 3)),
                     np.full(E, -1, np.int64), np.full(E, np.inf),
                     np.zeros((E, N, STATE_DIM)), np.zeros((E, N, 2)), np.zeros((E, N, 3)),
                     np.zeros((E, N, 2)), np.zeros((E, 5)), np.zeros(E),
                     np.zeros((E, N)), np.zeros((E, N, 2)), np.zeros((E, N), np.int64),
                     np.full((E, N, 6), -1.0))


#: ``flags`` bits of the step API's fused step (:func:`env_step_out`): the episode ended at
#: this step; it ended in success; it ended at the time limit without success.
ENV_ENDED, ENV_SUCCESS, ENV_TRUNCATED = 1, 2, 4


class EnvIO(NamedTuple):
    """The step API's side of a fused step (``_step_kernel`` of a kernel module) for ``n``
    sub-envs. No rows in ``a``/``out``: a plain step (``step_observe``)."""
    a: np.ndarray        # (n, N, 3) float64 actions (velocity m s-1, or units of v_max)
    out: np.ndarray      # (n, N, OBS_DIM) float64 the next observations (raw view)
    flags: np.ndarray    # (n,) int64 ENV_* bits
    rows: np.ndarray     # (E,) int64 the sub-env of each episode of the batch (-1: none)
    normalized: int      # 1: ``a`` in units of v_max, its norm clipped to 1
    clean: int           # 1: undefined (non-finite) observation values written as 0


def env_io(n: int, n_agents: int, obs_dim: int) -> EnvIO:
    """An :class:`EnvIO` with no rows (a plain fused step).

    Parameters
    ----------
    n : int
        Sub-envs (rows of ``a``, ``out`` and ``flags``).
    n_agents : int
        Team size N.
    obs_dim : int
        Observation width (``OBS_DIM``).

    Returns
    -------
    EnvIO
        Zero actions and observations, zero flags, an empty ``rows``, ``normalized`` and
        ``clean`` 0.
    """
    return EnvIO(np.zeros((n, n_agents, 3)), np.zeros((n, n_agents, obs_dim)),
                 np.zeros(n, np.int64), np.zeros(0, np.int64), 0, 0)


#: The fused step's arguments in :class:`StepArgs` (a kernel module's ``_step_kernel``
#: arguments before ``io``).
STEP_FIELDS = ("grid", "vp", "LP", "P", "W", "M", "LS", "t0", "state", "cmd", "ext", "obs",
               "act", "res", "nobs", "nact")


@structref.register
class StepArgsType(types.StructRef):
    """The numba type of :class:`StepArgs`."""

    def preprocess_fields(self, fields):
        """The struct's fields with literal types widened (one type per field whatever the
        values).

        Parameters
        ----------
        fields : sequence of (str, numba type)
            The fields' names and types.

        Returns
        -------
        tuple of (str, numba type)
            The same fields, each type ``types.unliteral``.
        """
        return tuple((name, types.unliteral(t)) for name, t in fields)


class StepArgs(structref.StructRefProxy):
    """A batch's fused-step arguments (:data:`STEP_FIELDS`: its own arrays, shared, not
    copied) in one numba struct: a compiled call unboxes one object instead of every array
    of the grid and the loop (about 6 us a call with them; the step API's step at one env
    is a few us of work). Built by :func:`step_args`; read by a kernel module's
    ``_step_boxed`` (:func:`step_fields`)."""


structref.define_proxy(StepArgs, StepArgsType, STEP_FIELDS)


@njit(cache=True)
def step_args(grid, vp, LP, P, W, M, LS, t0, state, cmd, ext, obs, act, res, nobs, nact):
    """The :class:`StepArgs` of these arrays (compiled per argument types, cached).

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    vp : (PARAM_DIM,) float64
        Vehicle parameters (:func:`oneocean.engine.dynamics.vehicle_params`).
    LP : LoopParams
        The loop's params.
    P, W
        The task's params and per-episode work arrays (its ``make``).
    M : NamedTuple
        The method's params (its policy module's ``params``).
    LS : LoopState
        The loop's per-episode state.
    t0 : (E,) float64
        Start time of each episode, s since the grid's ``time0``.
    state : (E, N, STATE_DIM) float64
        True vehicle states (layout: :mod:`oneocean.engine.dynamics`).
    cmd : (E, N, CMD_DIM) float64
        Command rows.
    ext : (E, N, 3) float64
        External actions, m s-1.
    obs : (E, n_steps, N, OBS_DIM) float64
        Observation record (zero-length step axis unless recording).
    act : (E, n_steps, N, 3) float64
        Action record.
    res : (E, C) float64
        Result rows.
    nobs : (E, 1, N, OBS_DIM) float64
        The next observation of every agent.
    nact : (E, 1, N, 3) float64
        Scratch of :func:`observe_next`.

    Returns
    -------
    StepArgs
        The arrays, shared (not copied).
    """
    return StepArgs(grid, vp, LP, P, W, M, LS, t0, state, cmd, ext, obs, act, res, nobs, nact)


# A StepArgs' fields, read the way numba reads a struct's field (``A.grid``) but without
# taking a reference to every array in it: a field read in jit code counts a reference to
# each array it holds (about 60 of them) and the end of the call gives them back, which
# cost about 0.9 us of a step() at one env (the step itself: 1-2 us for a single vehicle).
# The StepArgs keeps its arrays alive for the call (its Python owner holds it), so a kernel
# may borrow them. A kernel module's ``_step_boxed`` (compiled with reference counting:
# the struct it unboxes is given back at its end) calls its ``_step_fields``, compiled
# without (``step_kernel``), which reads the fields by :func:`step_fields`: nothing is
# counted there, so nothing is given back either. The payload is found the way numba's own
# ``NRT_MemInfo_data_fast`` finds it (its MemInfo layout, ``_meminfo_struct_type``);
# without that name (another numba) the fields are read by numba's own getattr instead.
try:
    from numba.core.runtime.nrtdynmod import _meminfo_struct_type as _MEMINFO
except ImportError:  # pragma: no cover - another numba's internals
    _MEMINFO = None

#: Whether :func:`step_fields` borrows (True) or reads the fields by numba's getattr.
BORROWED_FIELDS = _MEMINFO is not None

if BORROWED_FIELDS:
    from numba.core import cgutils as _cgutils
    from numba.core.extending import intrinsic as _intrinsic

    @_intrinsic
    def step_fields(typingctx, A):
        """The :data:`STEP_FIELDS` of the :class:`StepArgs` ``A``, in that order, borrowed
        (no reference counted): only in a kernel compiled without reference counting
        (:data:`step_kernel`) and called from jit code that holds ``A`` (a kernel taking a
        struct from Python without reference counting would keep it: never given back)."""
        tys = [A.field_dict[f] for f in STEP_FIELDS]
        tup = types.Tuple(tys)

        def codegen(context, builder, sig, args):
            ref = _cgutils.create_struct_proxy(sig.args[0])(context, builder, value=args[0])
            mi = builder.bitcast(ref.meminfo, _MEMINFO.as_pointer())
            data = builder.load(_cgutils.gep(builder, mi, 0, 3))
            payload = sig.args[0].get_data_type()
            ptype = context.data_model_manager[payload].get_value_type()
            fields = _cgutils.create_struct_proxy(payload)(
                context, builder, ref=builder.bitcast(data, ptype.as_pointer()))
            return context.make_tuple(builder, tup, [getattr(fields, f) for f in STEP_FIELDS])

        return tup(A), codegen

    #: The decorator of a kernel module's ``_step_fields`` (it calls :func:`step_fields`).
    step_kernel = hot_kernel(nogil=True)
else:  # pragma: no cover - another numba's internals
    @njit(cache=True)
    def step_fields(A):
        """The :data:`STEP_FIELDS` of the :class:`StepArgs` ``A``, in that order."""
        return (A.grid, A.vp, A.LP, A.P, A.W, A.M, A.LS, A.t0, A.state, A.cmd, A.ext, A.obs,
                A.act, A.res, A.nobs, A.nact)

    step_kernel = njit(cache=True, nogil=True)


@hot_kernel(inline="always")
def env_step_in(LP, LS, ext, io, e):
    """Before episode ``e``'s fused step: its sub-env's action (if it has one) into
    ``ext[e]``.

    With ``io.normalized`` the action is scaled as ``v_max * a / max(|a|, 1)`` (numpy's
    arithmetic; a non-finite norm propagates).

    Parameters
    ----------
    LP : LoopParams
        The loop's params (``v_max``, m s-1).
    LS : LoopState
        The loop's per-episode state.
    ext : (E, N, 3) float64
        External actions, m s-1; row ``e`` written.
    io : EnvIO
        The step API's side of the step (``io.rows[e]``: episode ``e``'s sub-env, -1: none).
    e : int
        Episode index.

    Returns
    -------
    bool
        Whether the episode had already ended before the step.
    """
    was = LS.status[e] == FINISHED
    if io.a.shape[0] > 0 and io.rows[e] >= 0:
        j = io.rows[e]
        for i in range(io.a.shape[1]):
            x = io.a[j, i, 0]
            y = io.a[j, i, 1]
            z = io.a[j, i, 2]
            if io.normalized != 0:
                m = math.sqrt(x * x + y * y + z * z)
                if not (m > 1.0 or m != m):
                    m = 1.0
                x = LP.v_max * x / m
                y = LP.v_max * y / m
                z = LP.v_max * z / m
            ext[e, i, 0] = x
            ext[e, i, 1] = y
            ext[e, i, 2] = z
    return was


@hot_kernel(inline="always")
def env_step_out(LP, LS, res, nobs, io, e, was):
    """After episode ``e``'s fused step and observation (``nobs[e, 0]``): its sub-env's
    observation into ``io.out`` and its :data:`ENV_ENDED` / ``ENV_SUCCESS`` /
    ``ENV_TRUNCATED`` bits into ``io.flags``.

    Nothing for an episode without a sub-env. The bits are set only at the step the episode
    ended; with ``io.clean`` non-finite observation values are written as 0.

    Parameters
    ----------
    LP : LoopParams
        The loop's params (``n_steps``).
    LS : LoopState
        The loop's per-episode state.
    res : (E, C) float64
        Result rows (``res[e, C_SUCCESS]``).
    nobs : (E, 1, N, OBS_DIM) float64
        The next observation of every agent (:func:`observe_next`).
    io : EnvIO
        The step API's side of the step, written.
    e : int
        Episode index.
    was : bool
        Whether the episode had ended before the step (:func:`env_step_in`).
    """
    if io.out.shape[0] == 0 or io.rows[e] < 0:
        return
    j = io.rows[e]
    o = nobs[e, 0]
    for i in range(o.shape[0]):
        for d in range(o.shape[1]):
            v = o[i, d]
            if io.clean != 0 and not math.isfinite(v):
                v = 0.0
            io.out[j, i, d] = v
    f = 0
    if LS.status[e] == FINISHED and not was:
        f = ENV_ENDED
        if res[e, C_SUCCESS] > 0.5:
            f |= ENV_SUCCESS
        elif LS.k[e] >= LP.n_steps:
            f |= ENV_TRUNCATED
    io.flags[j] = f


@hot_kernel(inline="always")
def known_state(LP, LS, state, e):
    """The agents' state as the method knows it: the truth for a method given the true
    position (the oracle), else the navigation estimate, refreshed for every agent.

    Parameters
    ----------
    LP : LoopParams
        The loop's params (``sens.true_position``).
    LS : LoopState
        The loop's per-episode state (``nerr``; ``nav`` is written).
    state : (E, N, STATE_DIM) float64
        True vehicle states (layout: :mod:`oneocean.engine.dynamics`).
    e : int
        Episode index (the only row refreshed).

    Returns
    -------
    (E, N, STATE_DIM) float64
        ``state`` itself, or ``LS.nav``.
    """
    if LP.sens.true_position != 0:
        return state
    for i in range(state.shape[1]):
        nav_fill(state, LS.nerr, LS.nav, e, i)
    return LS.nav


@hot_kernel(inline="always")
def observe_next(grid, cue, P, W, LP, LS, state, t0, e, nobs, nact):
    """The observation every agent gets before its episode's next step ``k`` (the step
    API's ``obs``), into ``nobs[e, 0]``: exactly what the loop's step ``k`` will sense (the
    filter update is computed, not stored).

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    cue : function
        The task's ``cue`` hook.
    P, W
        The task's params and per-episode work arrays (its ``make``).
    LP : LoopParams
        The loop's params.
    LS : LoopState
        The loop's per-episode state (``k[e]`` is the next step).
    state : (E, N, STATE_DIM) float64
        True vehicle states (layout: :mod:`oneocean.engine.dynamics`).
    t0 : (E,) float64
        Start time of each episode, s since the grid's ``time0``.
    e : int
        Episode index.
    nobs : (E, 1, N, OBS_DIM) float64
        The next observations, row ``e`` written.
    nact : (E, 1, N, 3) float64
        Scratch (the observation's action slot).
    """
    n_ag = state.shape[1]
    k = LS.k[e]
    t = t0[e] + k * LP.dt
    X = known_state(LP, LS, state, e)
    for i in range(n_ag):
        s = state[e, i]
        ce, cn = current_at(grid, s[0], s[1], s[2], t)
        q = LS.ocur[e, i]
        q[0] = s[0]
        q[1] = s[1]
        q[2] = s[2]
        q[3] = k
        q[4] = ce
        q[5] = cn
        pe, pn = current_estimate(LP.sens, LP.seed, LS.cb, LS.fc, e, k, i, n_ag, ce, cn, 0,
                                  LP.e0)
        gx, gy, gz, pr = cue(grid, P, W, X, e, k, i)
        observe(nobs, nact, e, 0, i, grid, X, state, gx, gy, gz, pe, pn, pr,
                math.nan, math.nan, math.nan)


@hot_kernel(inline="always")
def decide_agent(cue, act, grid, P, W, M, LP, LS, X, state, cmd, ext, obs, act_rec, e, k, i,
                 t, counting, cur):
    """The decision half of agent ``i``'s step ``k`` (every backend).

    Remember where the agent is (``LS.prev``), sample the true current at it (or take the
    step API's observation's sample of it, ``LS.ocur``, at the same step and position: the
    same value), give the method its current estimate, choose the action (the fused policy,
    the learned controller or the external action), record the observation and write the
    command row ``cmd[e, i]`` (unclipped, heading free unless the fused policy sets it,
    thrust on).

    Parameters
    ----------
    cue, act : function
        The task's ``cue`` hook and the policy's ``act`` hook.
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P, W
        The task's params and per-episode work arrays (its ``make``).
    M : NamedTuple
        The method's params.
    LP : LoopParams
        The loop's params.
    LS : LoopState
        The loop's per-episode state.
    X : (E, N, STATE_DIM) float64
        The states the method knows (:func:`known_state`).
    state : (E, N, STATE_DIM) float64
        True vehicle states (layout: :mod:`oneocean.engine.dynamics`).
    cmd : (E, N, CMD_DIM) float64
        Command rows; ``cmd[e, i]`` written.
    ext : (E, N, 3) float64
        External actions, m s-1 (``LP.policy == EXTERNAL``).
    obs : (E, n_steps, N, OBS_DIM) float64
        Observation record (zero-length step axis unless recording).
    act_rec : (E, n_steps, N, 3) float64
        Action record.
    e : int
        Episode index.
    k : int
        Step index.
    i : int
        Agent index.
    t : float
        Time, s since the grid's ``time0`` (``t0[e] + k dt``).
    counting : bool
        The standard metrics still accumulate (no ``REACHED`` yet).
    cur : float
        The episode's sum of true current speeds so far, m s-1.

    Returns
    -------
    cur : float
        The updated current-speed sum, m s-1.
    ce, cn : float
        The true current at the agent, east and north, m s-1.
    """
    s = state[e, i]
    px = s[0]
    py = s[1]
    pz = s[2]
    LS.prev[e, i, 0] = px
    LS.prev[e, i, 1] = py
    LS.prev[e, i, 2] = pz
    q = LS.ocur[e, i]
    if q[3] == k and q[0] == px and q[1] == py and q[2] == pz:
        # the step API's observation sampled it at this step and position
        ce = q[4]
        cn = q[5]
    else:
        ce, cn = current_at(grid, px, py, pz, t)
    if counting:
        cur += math.sqrt(ce * ce + cn * cn)
    pe, pn = current_estimate(LP.sens, LP.seed, LS.cb, LS.fc, e, k, i, state.shape[1], ce, cn,
                              1, LP.e0)
    if LP.policy != EXTERNAL:
        ax, ay, az, psi = act(grid, P, W, M, X, e, k, i, t, pe, pn)
        if LP.policy == LEARNED:
            # the fused policy ran for its mission layer (plan, target point, claims);
            # the network maps the observation to the action
            gx, gy, gz, pr = cue(grid, P, W, X, e, k, i)
            observe(LP.net.obs, LP.net.act, e, 0, i, grid, X, state, gx, gy, gz, pe,
                    pn, pr, math.nan, math.nan, math.nan)
            ax, ay, az = learned_act(LP.net, e, i, LP.v_max)
            psi = math.nan
    else:
        ax = ext[e, i, 0]
        ay = ext[e, i, 1]
        az = ext[e, i, 2]
        psi = math.nan
    if k < obs.shape[1]:
        gx, gy, gz, pr = cue(grid, P, W, X, e, k, i)
        observe(obs, act_rec, e, k, i, grid, X, state, gx, gy, gz, pe, pn, pr, ax, ay, az)
    c = cmd[e, i]
    c[0] = ax
    c[1] = ay
    c[2] = az
    c[3] = psi
    c[4] = 1.0
    return cur, ce, cn


@hot_kernel(inline="always")
def account_agent(after_agent, grid, P, W, LP, LS, state, e, k, i, en, code, counting, energy,
                  viol):
    """The accounting half of agent ``i``'s step after it moved (every backend).

    The energy proxy ``en`` of its executed action and the move's status ``code`` (a rejected
    move or a contact) counted up to success, the task's ``after_agent`` hook, and the
    navigation estimate teammates acting later see.

    Parameters
    ----------
    after_agent : function
        The task's ``after_agent`` hook.
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P, W
        The task's params and per-episode work arrays (its ``make``).
    LP : LoopParams
        The loop's params.
    LS : LoopState
        The loop's per-episode state.
    state : (E, N, STATE_DIM) float64
        True vehicle states (layout: :mod:`oneocean.engine.dynamics`).
    e : int
        Episode index.
    k : int
        Step index.
    i : int
        Agent index.
    en : float
        Energy proxy of the executed action, m2 s-1.
    code : int
        Status of the move (:mod:`oneocean.engine.status`; ``OK`` or a violation).
    counting : bool
        The standard metrics still accumulate (no ``REACHED`` yet).
    energy : float
        The team's energy proxy so far, m2 s-1.
    viol : int
        The team's rejected moves so far.

    Returns
    -------
    energy : float
        The updated energy proxy, m2 s-1.
    viol : int
        The updated violation count.
    """
    if counting:
        energy += en
        if code != OK:
            viol += 1
    after_agent(grid, P, W, state, e, k, i, code)
    if LP.sens.true_position == 0:   # teammates acting later see where i now thinks it is
        nav_fill(state, LS.nerr, LS.nav, e, i)
    return energy, viol


@hot_kernel(inline="always")
def end_step(post_step, grid, P, W, LP, LS, state, e, k, t, counting, coll, dmin):
    """The end of step ``k`` once every agent moved (every backend).

    Near-collisions (eq. 4) and the closest pair (while counting), the task's ``post_step``
    judge, dead reckoning over the step, the ``REACHED`` latch (``LS.k_succ[e]``).

    Parameters
    ----------
    post_step : function
        The task's ``post_step`` hook.
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P, W
        The task's params and per-episode work arrays (its ``make``).
    LP : LoopParams
        The loop's params.
    LS : LoopState
        The loop's per-episode state.
    state : (E, N, STATE_DIM) float64
        True vehicle states after the step (layout: :mod:`oneocean.engine.dynamics`).
    e : int
        Episode index.
    k : int
        Step index.
    t : float
        Time at the step's start, s since the grid's ``time0``.
    counting : bool
        The standard metrics still accumulate (no ``REACHED`` yet).
    coll : int
        Steps with a near-collision so far.
    dmin : float
        Smallest pair distance so far, m.

    Returns
    -------
    k : int
        ``k + 1``.
    stop : bool
        The judge ended the episode (``STOP``).
    counting : bool
        False from the ``REACHED`` step on.
    coll : int
        The updated near-collision count.
    dmin : float
        The updated smallest pair distance, m.
    """
    S = state[e]
    if S.shape[0] > 1 and counting:
        d = min_pairwise_distance(S)
        if d <= LP.r_coll:
            coll += 1
        if d < dmin:
            dmin = d
    rc = int(post_step(grid, P, W, state, LS.prev, e, k, t))
    for i in range(S.shape[0]):   # dead reckoning over the step's ground displacement
        nav_update(LP.sens, LP.seed, LS.navc, LS.nerr, state, LS.prev, e, k, i, S.shape[0],
                   LP.dt, LP.e0)
    k += 1
    stop = False
    if rc == REACHED:
        if counting:
            LS.k_succ[e] = k
            counting = False
    elif rc != GO:
        stop = True
    return k, stop, counting, coll, dmin


@hot_kernel(inline="always")
def finish_episode(finish, grid, P, W, LP, LS, state, res, e, k):
    """Close episode ``e`` after ``k`` steps (every backend): the task's ``finish`` judge
    writes its metrics, the loop the standard columns over the steps up to success.

    ``T`` is the steps to success times ``dt`` on success, else the time limit; the
    near-collision ratio and the mean current speed are per step (and agent) up to success.

    Parameters
    ----------
    finish : function
        The task's ``finish`` hook.
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    P, W
        The task's params and per-episode work arrays (its ``make``).
    LP : LoopParams
        The loop's params.
    LS : LoopState
        The loop's per-episode state (``status[e]`` set to ``FINISHED``).
    state : (E, N, STATE_DIM) float64
        True vehicle states (layout: :mod:`oneocean.engine.dynamics`).
    res : (E, C) float64
        Result rows; row ``e`` written (the ``C_*`` columns, then the task's).
    e : int
        Episode index.
    k : int
        Steps taken.
    """
    LS.status[e] = FINISHED
    row = res[e]
    success = finish(grid, P, W, state, e, k, row)
    k_end = LS.k_succ[e] if LS.k_succ[e] >= 0 else k   # the steps the metrics cover
    dt = LP.dt
    n_ag = state.shape[1]
    row[C_SUCCESS] = 1.0 if success else 0.0
    row[C_T] = k_end * dt if success else LP.n_steps * dt
    row[C_E] = LS.energy[e]
    row[C_COLL] = LS.coll[e] / k_end if k_end > 0 else 0.0
    row[C_VIOL] = LS.viol[e]
    row[C_CUR] = LS.cur[e] / (k_end * n_ag) if k_end > 0 else 0.0


@hot_kernel(inline="always")
def run_episode(begin, pre_step, cue, after_agent, post_step, finish, plan, act,
                grid, vp, LP, P, W, M, LS, t0, state, cmd, ext, obs, act_rec, res, e, k_stop):
    """Advance episode ``e`` up to step ``k_stop`` (or its end; a negative ``k_stop``
    advances it by ``-k_stop`` steps from where it is, so episodes at different steps move
    together); write ``res[e]`` when it ends. Serial; the per-task kernel runs it for every
    episode of its block.

    ``LP.phase`` says which part of a step this call runs: ``FULL`` (the core backend:
    whole steps, each agent deciding and moving in turn through :func:`advance_agent`),
    ``DECIDE`` (another backend's physics: one step's decisions of every agent -- the
    command rows ``cmd`` and the true currents ``LS.cw`` -- with the executed action clipped
    and its energy in ``LS.en``) or ``JUDGE`` (after that backend moved the agents and wrote
    each move's status into ``LS.code``: the accounting and the judge of the step).

    Parameters
    ----------
    begin, pre_step, cue, after_agent, post_step, finish : function
        The task's env hooks (module docstring).
    plan, act : function
        The policy's hooks.
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    vp : (PARAM_DIM,) float64
        Vehicle parameters (:func:`oneocean.engine.dynamics.vehicle_params`).
    LP : LoopParams
        The loop's params.
    P, W
        The task's params and per-episode work arrays (its ``make``).
    M : NamedTuple
        The method's params.
    LS : LoopState
        The loop's per-episode state, updated.
    t0 : (E,) float64
        Start time of each episode, s since the grid's ``time0``.
    state : (E, N, STATE_DIM) float64
        True vehicle states (layout: :mod:`oneocean.engine.dynamics`), advanced in place.
    cmd : (E, N, CMD_DIM) float64
        Command rows.
    ext : (E, N, 3) float64
        External actions, m s-1 (``LP.policy == EXTERNAL``).
    obs : (E, n_steps, N, OBS_DIM) float64
        Observation record (zero-length step axis unless recording).
    act_rec : (E, n_steps, N, 3) float64
        Action record.
    res : (E, C) float64
        Result rows; row ``e`` written when the episode ends.
    e : int
        Episode index.
    k_stop : int
        Stop before this step; negative: advance ``-k_stop`` steps.
    """
    if LS.status[e] == FINISHED:
        return
    n_ag = state.shape[1]
    n_steps = LP.n_steps
    dt = LP.dt
    stop = False
    if LS.status[e] == NEW:
        LS.status[e] = RUNNING
        stop = begin(grid, P, W, state, e)
    k = LS.k[e]
    k_lim = k_stop if k_stop >= 0 else k - k_stop
    energy = LS.energy[e]
    viol = LS.viol[e]
    coll = LS.coll[e]
    dmin = LS.dmin[e]
    cur = LS.cur[e]
    counting = LS.k_succ[e] < 0   # standard metrics accumulate up to success (REACHED)
    if LP.phase == FULL:
        while k < n_steps and k < k_lim and not stop:
            t = t0[e] + k * dt
            pre_step(grid, P, W, state, e, k, t)
            X = known_state(LP, LS, state, e)   # the policy's view (the truth for the oracle)
            if LP.policy != EXTERNAL and LP.plan != 0:
                plan(grid, P, W, M, X, e, k, t)
            for i in range(n_ag):
                cur, ce, cn = decide_agent(cue, act, grid, P, W, M, LP, LS, X, state, cmd, ext,
                                           obs, act_rec, e, k, i, t, counting, cur)
                en, code = advance_agent(grid, LP.model, vp, state[e, i], cmd[e, i], ce, cn,
                                         LP.v_max, dt, LP.land_thr, LP.clearance)
                energy, viol = account_agent(after_agent, grid, P, W, LP, LS, state, e, k, i,
                                             en, code, counting, energy, viol)
            k, stop, counting, coll, dmin = end_step(post_step, grid, P, W, LP, LS, state, e,
                                                     k, t, counting, coll, dmin)
    elif LP.phase == DECIDE:
        if k < n_steps and k < k_lim and not stop:
            t = t0[e] + k * dt
            pre_step(grid, P, W, state, e, k, t)
            X = known_state(LP, LS, state, e)
            if LP.policy != EXTERNAL and LP.plan != 0:
                plan(grid, P, W, M, X, e, k, t)
            for i in range(n_ag):
                cur, ce, cn = decide_agent(cue, act, grid, P, W, M, LP, LS, X, state, cmd, ext,
                                           obs, act_rec, e, k, i, t, counting, cur)
                c = cmd[e, i]
                ax, ay, az = clip_action(c[0], c[1], c[2], LP.v_max)
                c[0] = ax
                c[1] = ay
                c[2] = az
                LS.en[e, i] = (ax * ax + ay * ay + az * az) * dt
                LS.cw[e, i, 0] = ce
                LS.cw[e, i, 1] = cn
    else:   # JUDGE: the backend moved every agent of step k
        if k < n_steps and k < k_lim and not stop:
            t = t0[e] + k * dt
            for i in range(n_ag):
                energy, viol = account_agent(after_agent, grid, P, W, LP, LS, state, e, k, i,
                                             LS.en[e, i], LS.code[e, i], counting, energy,
                                             viol)
            k, stop, counting, coll, dmin = end_step(post_step, grid, P, W, LP, LS, state, e,
                                                     k, t, counting, coll, dmin)
    LS.k[e] = k
    LS.energy[e] = energy
    LS.viol[e] = viol
    LS.coll[e] = coll
    LS.dmin[e] = dmin
    LS.cur[e] = cur
    if stop or (k >= n_steps and LP.phase != DECIDE):
        finish_episode(finish, grid, P, W, LP, LS, state, res, e, k)


@hot_kernel(inline="always")
def noop_pre_step(grid, P, W, state, e, k, t):
    """A ``pre_step`` hook that does nothing (for a task without physics before the moves).

    Parameters
    ----------
    grid : Grid
        The grid export.
    P, W
        The task's params and per-episode work arrays.
    state : (E, N, STATE_DIM) float64
        True vehicle states.
    e : int
        Episode index.
    k : int
        Step index.
    t : float
        Time, s since the grid's ``time0``.
    """
    return


@hot_kernel(inline="always")
def noop_after_agent(grid, P, W, state, e, k, i, code):
    """An ``after_agent`` hook that does nothing.

    Parameters
    ----------
    grid : Grid
        The grid export.
    P, W
        The task's params and per-episode work arrays.
    state : (E, N, STATE_DIM) float64
        True vehicle states.
    e : int
        Episode index.
    k : int
        Step index.
    i : int
        Agent index.
    code : int
        Status of the agent's move (:mod:`oneocean.engine.status`).
    """
    return


@hot_kernel(inline="always")
def noop_plan(grid, P, W, M, state, e, k, t):
    """A policy ``plan`` hook that does nothing (a policy without a team-level decision).

    Parameters
    ----------
    grid : Grid
        The grid export.
    P, W
        The task's params and per-episode work arrays.
    M : NamedTuple
        The method's params.
    state : (E, N, STATE_DIM) float64
        The vehicle states the method knows.
    e : int
        Episode index.
    k : int
        Step index.
    t : float
        Time, s since the grid's ``time0``.
    """
    return
