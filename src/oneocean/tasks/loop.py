"""The one episode loop every task runs on, and the contract of a task's and a policy's hooks.

A task (``oneocean.tasks.<id>``) says what the world does; a method (``oneocean.methods``)
says what the agents do. This loop owns everything they share, so no task re-implements it:
time, current sampling at every agent, sensing and navigation (the sensor models of
:mod:`oneocean.sensing` for every non-oracle method, the truth for the oracle), the
observation, the action (through :func:`advance_agent`: clipping to ``v_max``, dynamics,
feasibility), the energy proxy (eq. 7), rejected moves, near-collisions (eq. 4, one
``r_coll``), termination, success and ``T``, and the metric horizon (below) -- in resumable
segments of steps (``k_stop``), so a Python planner or the step API can act between them.

What a method knows (the public view, docs/policy.md)
    A method is a policy of two things only: the task's **briefing** ``B`` (what the mission
    gives before the episode: the forecast field, the goal / route / region / chart / slots /
    zone / report, the vehicle's limits and power model, the tier's tolerances, time limit and
    energy allocation; a typed NamedTuple of the task module, ``brief``) and the
    **observation** ``O`` (E, N, D) of every agent at every step (the common head
    :data:`oneocean.tasks.common.OBS_FIELDS` -- the task's cue, the current estimate, depth,
    altitude, the probe, teammates' offsets, the navigation estimate, velocity, time, energy,
    position fixes -- then the task's own fields ``OBS_EXTRA``: acoustic fixes of the object
    or the school, the attachment state, ...), plus the task's team-level observation ``T``
    (e.g. SPC's aerial oil map). The oracle gets the same in the same shape, with the truth.
    A fused policy reads them through its context :class:`Ctx`; an external policy (the step
    API, ``oneocean evaluate``) gets the same arrays. Nothing else: not the grid, not the
    task's params or work arrays, not the loop's state.

Per step ``k`` of episode ``e`` (``t = t0[e] + k dt``), the same code for every policy::

    sense    env.pre_step (task physics before the agents act); env.sense (the task's own
             observation fields and its team observation T: perception, fixes); the true
             current at every agent (kept for its move); the common head of every agent's
             observation O[e] (the task's cue on the navigation estimate, the current
             estimate, ...)
    decide   policy.plan(C, e, k); a = policy.act(C, e, k, i) for every agent i -- or the
             learned controller's action on the same view, or the external action ext[e, i]
             (the step API); record observation and action when asked
    move     advance_agent(a, c) on the true state for every agent; energy, rejected moves;
             env.after_agent
    judge    near-collisions (eq. 4) and the closest pair; code = env.post_step (task physics
             after the moves, metrics, termination); dead reckoning over the step; k += 1
    then the next step's sense, so that the observation of step k + 1 is ready when a segment
    (or a step of the step API) returns; at the end: env.finish(...) -> success, T = k dt on
    success (k_succ dt after REACHED), else the time limit; then a last observation of the
    final state (no pre_step).

Every observation is taken once, before any agent of the step moves, so a fused policy and an
external policy that receives the step API's observation see exactly the same values, and the
heuristic run through the step API gives the same episodes as its fused cell
(``tests/test_parity.py``).

Termination and the metric horizon. ``post_step`` returns a stop code: ``GO`` (0 / False:
continue), ``STOP`` (1 / True: the episode ends now: success or a terminal failure, as
``finish`` then says) or ``REACHED`` (2: the task's success was reached at this step, but the
episode runs on to its time limit, the task's fixed *metric horizon*, for metrics measured
over that horizon, e.g. SPC's cleanup rate). The loop latches the first ``REACHED`` step in
``LoopState.k_succ``; from then on the standard metrics are frozen: ``T`` is ``k_succ dt``,
and ``E``, ``violations``, the near-collision ratio (``coll / k_succ``) and the closest pair
distance ``LoopState.dmin`` cover the steps up to success. Everything else runs to the
horizon, and ``finish`` sees the final step.

Env hooks take one context, ``ctx`` (:class:`EnvCtx`: the grid, the task's params ``P`` and
per-episode work arrays ``W``, the true states, the agents' states as the method knows them
``X`` -- the truth for the oracle --, this step's observations, the positions before the step,
each agent's move status, the result rows and the clock; documented once, there), then the
episode ``e``, the step ``k`` and the agent ``i``::

    begin(ctx, e) -> stop                 before step 0 (ctx.state holds the start)
    pre_step(ctx, e, k)                   world physics before the agents act
    cue(ctx, e, k, i) -> (gx, gy, gz, probe)   the task's cue (world m, on ctx.X) and probe
    sense(ctx, e, k)                      the task's observation fields (ctx.O[e, :, D0:])
                                          and team observation (in W)
    after_agent(ctx, e, k, i)             right after agent i moved (its status:
                                          ctx.code[e, i])
    post_step(ctx, e, k) -> GO | STOP | REACHED   after every agent moved (positions before
                                          the step: ctx.prev; a bool is GO / STOP)
    finish(ctx, e, k) -> success          writes the task's metric columns (ctx.res[e])
    report(C, e, k)                       the task's reference report rule (PI: claim every
                                          logged event), which a learned policy files by;
                                          on the policy's context

Step ``k`` of episode ``e`` starts at ``t = ctx.t0[e] + k * ctx.dt`` (s since the grid's
time0).

Policy hooks (``C``: the policy's context :class:`Ctx` -- briefing, observation, team
observation, the method's params and memory, the report it files)::

    plan(C, e, k)                                  the team's decision, once per step
    act(C, e, k, i) -> (ax, ay, az, psi)           desired velocity relative to the water
                                                   (world m s-1) and heading (rad, NaN: free)

Hooks are plain ``@hot_kernel`` functions of the task module (the env) and of its policy
module; neither imports the other. Each is compiled once, on its own (what is inlined and
why: :mod:`oneocean.engine._jit`). A task's kernel module (:mod:`oneocean.kernels`) passes
them to :func:`run_episode` (``inline="always"``) in its ``_kernel``, the one compiled loop
over a block of episodes that serves the fused cells, the step API (one step and the next
observation per call, :class:`EnvIO`) and the scene backend's phases;
:func:`oneocean.engine.dispatch.over_range` runs the blocks on numba's thread count (no
``prange``: the parfor pass more than doubles every task kernel's compile time). Functions
must reach the loop as module globals of the caller and the loop must be inlined there: a
kernel that receives functions as run-time arguments cannot be cached.

NamedTuple classes crossing into a kernel need package-unique names (numba's parfor lowering
resolves them by name), so they carry the task id.
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
from ..engine.rng import PURPOSE_TASK
from ..engine.step import advance_agent
from .learned import LearnedNet, learned_act
from ..sensing import SensingParams
from ..sensing.kernels import current_estimate, draw, nav_fill, nav_update
from .common import OBS_DIM, OK, current_at, observe_common, record_step

#: The loop's arguments, documented once for every function of this module (a function's
#: docstring says what it does with them).
VOCABULARY = {
    "ctx": "EnvCtx: the env hooks' context (the grid, P, W, the states, ...)",
    "K": "Batch: a batch's kernel arguments (the grid, vp, LP, P, W, C, LS, t0, state, ...)",
    "grid": "Grid: the grid export (oneocean.engine.grid.Grid), the truth",
    "vp": "(PARAM_DIM,) float64: vehicle parameters (oneocean.engine.dynamics)",
    "LP": "LoopParams: the loop's params",
    "P": "NamedTuple: the task's params (its make)",
    "W": "NamedTuple: the task's per-episode work arrays (its make)",
    "C": "Ctx: the policy's context",
    "LS": "LoopState: the loop's per-episode state",
    "t0": "(E,) float64: start time of each episode, s since the grid's time0",
    "state": "(E, N, STATE_DIM) float64: true vehicle states (oneocean.engine.dynamics)",
    "cmd": "(E, N, CMD_DIM) float64: command rows",
    "ext": "(E, N, ACT_DIM) float64: external actions (velocity m s-1, heading rad)",
    "rec_o": "(E, S, N, D) float64: observation record (S = 0: none)",
    "rec_a": "(E, S, N, 3) float64: action record",
    "res": "(E, C) float64: result rows (the C_* columns, then the task's)",
    "O": "(E, N, D) float64: this step's observations",
    "io": "EnvIO: the step API's side of a call",
    "e": "int: episode (row of the batch)",
    "k": "int: step",
    "i": "int: agent",
    "t": "float: time at the step's start, s since the grid's time0",
    "k_stop": "int: stop before this step; negative: advance -k_stop steps",
    "e_lo": "int: first episode of the block",
    "e_hi": "int: end of the block",
    "begin": "function: the task's begin hook",
    "pre_step": "function: the task's pre_step hook",
    "cue": "function: the task's cue hook",
    "sense": "function: the task's sense hook",
    "after_agent": "function: the task's after_agent hook",
    "post_step": "function: the task's post_step hook",
    "finish": "function: the task's finish hook",
    "report": "function: the task's reference report hook (a learned policy files by it)",
    "plan": "function: the policy's plan hook",
    "act": "function: the policy's act hook",
    "final": "int: 1 for the observation of an ended episode's final state",
    "counting": "bool: the standard metrics still accumulate (no REACHED yet)",
    "energy": "float: the team's energy proxy so far, m2 s-1",
    "viol": "int: the team's rejected moves so far",
    "cur": "float: the episode's sum of true current speeds so far, m s-1",
    "coll": "int: steps with a near-collision so far",
    "dmin": "float: smallest pair distance so far, m",
    "en": "float: energy proxy of the agent's executed action, m2 s-1",
    "code": "int: status of the agent's move (oneocean.engine.status)",
    "was": "bool: the episode had ended before the step",
    "ks": "(E,) int64: each episode's step (< 0: skip the episode)",
    "out": "(E, N, ACT_DIM) float64: the policy's actions, written",
    "n_episodes": "int: episodes E",
    "n_agents": "int: team size N",
    "n": "int: sub-envs",
    "obs_dim": "int: observation width D",
}

#: Policy kinds inside the loop: the task's fused policy (heuristic, oracle, ...), an
#: external action per agent and step (``ext``; the step API and Python callables), or a
#: learned controller (a network on the same public view, :mod:`oneocean.tasks.learned`).
FUSED, EXTERNAL, LEARNED = 0, 1, 2

#: Columns every task writes first in its result row (then its metrics).
N_STANDARD = 6
C_SUCCESS, C_T, C_E, C_COLL, C_VIOL, C_CUR = range(N_STANDARD)

#: Width of an action row: desired velocity relative to the water (x east, y down, z north,
#: m s-1) and the commanded heading (rad from north, NaN: free).
ACT_DIM = 4
#: Random-stream purpose of the teacher noise (``LoopParams.noise``).
PURPOSE_TEACHER = PURPOSE_TASK + 9


class LoopParams(NamedTuple):
    """Parameters of the loop (one rollout, all episodes)."""
    model: int          # dynamics model id (engine.dynamics.model_id)
    policy: int         # FUSED, EXTERNAL or LEARNED
    plan: int           # 1: call the fused policy's plan hook every step; 0: the plan in the
                        # method's memory comes from a Python planner between segments
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
    noise: float = 0.0  # a fused policy's teacher noise: each executed velocity component
                        # disturbed by N(0, (noise v_max)^2), the recorded action clean
                        # (behaviour cloning's demonstrations: DART; 0: none)
    expert: int = 0     # 1: a learned policy runs with the fused policy as its shadow expert:
                        # the recorded action is the expert's on the same observation, the
                        # executed one the network's (behaviour cloning's DAgger rounds)


class LoopState(NamedTuple):
    """Per-episode state of the loop, kept between segments."""
    k: np.ndarray           # (E,) int64 steps taken
    status: np.ndarray      # (E,) int64 NEW / RUNNING / FINISHED
    energy: np.ndarray      # (E,) float64 team energy proxy, m2 s-1
    viol: np.ndarray        # (E,) int64 rejected moves (team)
    coll: np.ndarray        # (E,) int64 steps with a near-collision
    prev: np.ndarray        # (E, N, 3) positions before the current step, m
    k_succ: np.ndarray      # (E,) int64 steps to the REACHED success (-1: not reached)
    dmin: np.ndarray        # (E,) float64 smallest pair distance after a step, m (inf: N < 2)
    # what the method knows (oneocean.sensing.kernels): its navigation estimate of every
    # agent's state, position errors, dead-reckoning constants, filtered forecast corrections
    # and the episode's forecast error
    nav: np.ndarray         # (E, N, STATE_DIM) float64
    nerr: np.ndarray        # (E, N, 2) float64 horizontal position error (x, z), m
    navc: np.ndarray        # (E, N, 3) float64 1 + scale factor, cos / sin heading bias
    cb: np.ndarray          # (E, N, 2) float64 filtered forecast correction (east, north)
    fc: np.ndarray          # (E, 5) float64 forecast error (1 + gain, cos, sin, bias e, n)
    cur: np.ndarray         # (E,) float64 sum over agents and steps of the true current speed
    en: np.ndarray          # (E, N) float64 energy proxy of each agent's executed action, m2 s-1
    cw: np.ndarray          # (E, N, 2) float64 true current at each agent this step (e, n), m s-1
    code: np.ndarray        # (E, N) int64 status of each agent's move (engine.status)
    sensed: np.ndarray      # (E,) int64 the step whose observation O[e] holds (-1: none)
    eag: np.ndarray         # (E, N) float64 each agent's energy proxy so far, m2 s-1
    nfix: np.ndarray        # (E, N) int64 1: an absolute position fix at the last step


class EnvCtx(NamedTuple):
    """An env hook's context: the world as the task's hooks see it (one per call of the
    loop; every field is shared, not copied).

    ``grid`` the grid export (the truth); ``P`` / ``W`` the task's params and per-episode
    work arrays (its ``make``); ``state`` (E, N, STATE_DIM) the true vehicle states; ``X`` the
    agents' states as the method knows them (its navigation estimate; ``state`` itself for
    the oracle), the frame of the task's cue; ``O`` (E, N, D) this step's observations (a
    ``sense`` hook writes the task's fields ``O[e, :, D0:]``); ``prev`` (E, N, 3) the
    positions before the current step; ``code`` (E, N) the status of each agent's last move
    (:mod:`oneocean.engine.status`); ``res`` (E, C) the result rows (``finish`` writes
    ``res[e]``); ``t0`` (E,) the start times (s since the grid's time0) and ``dt`` the step,
    s: step ``k`` of episode ``e`` starts at ``t0[e] + k * dt``."""
    grid: tuple
    P: tuple
    W: tuple
    state: np.ndarray
    X: np.ndarray
    O: np.ndarray
    prev: np.ndarray
    code: np.ndarray
    res: np.ndarray
    t0: np.ndarray
    dt: float


class Ctx(NamedTuple):
    """A policy's context: everything a method may read, and what it keeps and files.

    ``B`` the task's briefing (its ``brief``); ``O`` (E, N, D) this step's observation of every
    agent (:data:`oneocean.tasks.common.OBS_FIELDS`, then the task's ``OBS_EXTRA``); ``T`` the
    task's team observation (a NamedTuple of E-leading arrays, its ``team_obs``); ``M`` the
    method's params; ``H`` the method's memory (its own arrays: plans, estimates); ``R`` the
    report the method files (the task's ``report``: PI's leak claims; an empty array
    elsewhere), which the task's judge reads."""
    B: tuple
    O: np.ndarray
    T: tuple
    M: tuple
    H: tuple
    R: np.ndarray


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
    (``k_succ = -1``), no pair distance yet (``dmin = inf``), nothing sensed, everything else
    zero.

    Returns
    -------
    LoopState
    """
    E, N = n_episodes, n_agents
    return LoopState(np.zeros(E, np.int64), np.zeros(E, np.int64),
                     np.zeros(E), np.zeros(E, np.int64),
                     np.zeros(E, np.int64), np.zeros((E, N, 3)),
                     np.full(E, -1, np.int64), np.full(E, np.inf),
                     np.zeros((E, N, STATE_DIM)), np.zeros((E, N, 2)), np.zeros((E, N, 3)),
                     np.zeros((E, N, 2)), np.zeros((E, 5)), np.zeros(E),
                     np.zeros((E, N)), np.zeros((E, N, 2)), np.zeros((E, N), np.int64),
                     np.full(E, -1, np.int64), np.zeros((E, N)), np.zeros((E, N), np.int64))


#: ``flags`` bits of a step API step (:func:`env_step_out`): the episode ended at this step;
#: it ended in success; it ended at the time limit without success.
ENV_ENDED, ENV_SUCCESS, ENV_TRUNCATED = 1, 2, 4


class EnvIO(NamedTuple):
    """The step API's side of a call of a kernel module's ``_kernel`` for ``n`` sub-envs; no
    rows: a fused call (nothing in, nothing out)."""
    a: np.ndarray        # (n, N, 3 or ACT_DIM) float64 actions (velocity m s-1 or units of
                         # v_max, then the heading, rad, NaN: free)
    out: np.ndarray      # (n, N, D) float64 the next observations
    flags: np.ndarray    # (n,) int64 ENV_* bits
    rows: np.ndarray     # (E,) int64 the sub-env of each episode of the batch (-1: none)
    normalized: int      # 1: ``a`` in units of v_max, its norm clipped to 1
    clean: int           # 1: undefined (non-finite) observation values written as 0


def env_io(n: int, n_agents: int, obs_dim: int) -> EnvIO:
    """An :class:`EnvIO` with no rows (a fused call).

    Returns
    -------
    EnvIO
    """
    return EnvIO(np.zeros((n, n_agents, 3)), np.zeros((n, n_agents, obs_dim)),
                 np.zeros(n, np.int64), np.zeros(0, np.int64), 0, 0)


class Batch(NamedTuple):
    """A batch's arguments of a kernel module's ``_kernel``, before the step API's side
    ``io``: the grid export (the truth), the vehicle parameters ``vp``, :class:`LoopParams`,
    the task's params ``P`` and work arrays ``W``, the policy's context :class:`Ctx`,
    :class:`LoopState`, the start times ``t0`` (E,), the true states ``state`` (E, N,
    STATE_DIM), the command rows ``cmd``, the external actions ``ext`` (E, N, ACT_DIM), the
    observation / action records ``rec_o`` (E, S, N, D) / ``rec_a`` (E, S, N, 3) (S = 0: no
    record) and the result rows ``res`` (E, C). Every array is shared, not copied."""
    grid: tuple
    vp: np.ndarray
    LP: LoopParams
    P: tuple
    W: tuple
    C: Ctx
    LS: LoopState
    t0: np.ndarray
    state: np.ndarray
    cmd: np.ndarray
    ext: np.ndarray
    rec_o: np.ndarray
    rec_a: np.ndarray
    res: np.ndarray


#: The fields of :class:`Batch` (and of :class:`StepArgs`).
STEP_FIELDS = Batch._fields


@structref.register
class StepArgsType(types.StructRef):
    """The numba type of :class:`StepArgs`."""

    def preprocess_fields(self, fields):
        """The struct's fields with literal types widened (one type per field whatever the
        values).

        Parameters
        ----------
        fields : sequence of (str, numba type)

        Returns
        -------
        tuple of (str, numba type)
        """
        return tuple((name, types.unliteral(t)) for name, t in fields)


class StepArgs(structref.StructRefProxy):
    """A batch's kernel arguments (:data:`STEP_FIELDS`: its own arrays, shared, not copied)
    in one numba struct: a compiled call unboxes one object instead of every array of the grid
    and the loop (about 6 us a call with them; a step of one env is a few us of work). Built by
    :func:`step_args`; read by a kernel module's ``_step_boxed`` (:func:`step_fields`)."""


structref.define_proxy(StepArgs, StepArgsType, STEP_FIELDS)


@njit(cache=True)
def step_args(K):
    """The :class:`StepArgs` of a batch's kernel arguments ``K`` (:class:`Batch`; compiled
    per argument types, cached); the arrays are shared, not copied.

    Returns
    -------
    StepArgs
    """
    return StepArgs(K.grid, K.vp, K.LP, K.P, K.W, K.C, K.LS, K.t0, K.state, K.cmd, K.ext,
                    K.rec_o, K.rec_a, K.res)


# A StepArgs' fields, read the way numba reads a struct's field (``A.grid``) but without
# taking a reference to every array in it: a field read in jit code counts a reference to
# each array it holds (about 60 of them) and the end of the call gives them back, which
# cost about 0.9 us of a step() at one env. The StepArgs keeps its arrays alive for the call
# (its Python owner holds it), so a kernel may borrow them. A kernel module's ``_step_boxed``
# (compiled with reference counting: the struct it unboxes is given back at its end) calls its
# ``_step_fields``, compiled without (``step_kernel``), which reads the fields by
# :func:`step_fields` and calls the module's ``_kernel``: nothing is counted there, so nothing
# is given back either. The payload is found the way numba's own ``NRT_MemInfo_data_fast``
# finds it (its MemInfo layout, ``_meminfo_struct_type``); without that name (another numba)
# the fields are read by numba's own getattr instead.
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
        """The fields of the :class:`StepArgs` ``A`` as a :class:`Batch`, borrowed (no
        reference counted): only in a kernel compiled without reference counting
        (:data:`step_kernel`) and called from jit code that holds ``A``."""
        tys = [A.field_dict[f] for f in STEP_FIELDS]
        tup = types.NamedTuple(tys, Batch)

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
        """The fields of the :class:`StepArgs` ``A`` as a :class:`Batch`."""
        return Batch(A.grid, A.vp, A.LP, A.P, A.W, A.C, A.LS, A.t0, A.state, A.cmd, A.ext,
                     A.rec_o, A.rec_a, A.res)

    step_kernel = njit(cache=True, nogil=True)


@hot_kernel(inline="always")
def env_step_in(LP, LS, ext, io, e):
    """Before a step API step of episode ``e``: its sub-env's action (if it has one) into
    ``ext[e]``; with ``io.normalized`` the velocity is ``v_max * a / max(|a|, 1)`` (numpy's
    arithmetic; a non-finite norm propagates). A heading column, if ``io.a`` has one, is
    copied as is; without one the heading is free (NaN).

    Returns
    -------
    bool
        Whether the episode had already ended before the step.
    """
    was = LS.status[e] == FINISHED
    if io.rows.shape[0] > 0 and io.rows[e] >= 0:
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
            ext[e, i, 3] = io.a[j, i, 3] if io.a.shape[2] > 3 else math.nan
    return was


@hot_kernel(inline="always")
def env_step_out(LP, LS, res, O, io, e, was):
    """After a step API step of episode ``e``: its next observation ``O[e]`` into its
    sub-env's row of ``io.out`` (non-finite values as 0 with ``io.clean``), and its
    :data:`ENV_ENDED` / ``ENV_SUCCESS`` / ``ENV_TRUNCATED`` bits (set only at the step the
    episode ended) into ``io.flags``. Nothing for an episode without a sub-env."""
    if io.rows.shape[0] == 0 or io.rows[e] < 0:
        return
    j = io.rows[e]
    o = O[e]
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
def sense_step(cue, sense, ctx, LP, LS, e, k, final):
    """The observation ``ctx.O[e]`` of every agent before step ``k`` (every policy, every
    backend): the agents' known states ``ctx.X[e]`` refreshed (the navigation estimate: true
    state plus the horizontal position error; depth, attitude and velocity are measured; the
    truth for a method given the true position), then the task's own fields and team
    observation (its ``sense``: perception, fixes, which its cue may use), then for each agent
    the true current (``LS.cw``, the current its move will meet), the method's current
    estimate (its filter updated with this step's in-situ sample) and the common head
    (:func:`oneocean.tasks.common.observe_common` on the task's cue). ``final``: the
    observation of an ended episode's final state (no filter update).
    """
    grid, state = ctx.grid, ctx.state
    n_ag = state.shape[1]
    t = ctx.t0[e] + k * LP.dt
    if LP.sens.true_position == 0:
        for i in range(n_ag):
            nav_fill(state, LS.nerr, LS.nav, e, i)
    sense(ctx, e, k)
    for i in range(n_ag):
        s = state[e, i]
        ce, cn = current_at(grid, s[0], s[1], s[2], t)
        LS.cw[e, i, 0] = ce
        LS.cw[e, i, 1] = cn
        pe, pn = current_estimate(LP.sens, LP.seed, LS.cb, LS.fc, e, k, i, n_ag, ce, cn,
                                  1 - final, LP.e0)
        gx, gy, gz, pr = cue(ctx, e, k, i)
        observe_common(ctx.O[e, i], grid, ctx.X, state, e, i, gx, gy, gz, pe, pn, pr,
                       k * LP.dt, LS.eag[e, i], LS.nfix[e, i])
    LS.sensed[e] = k


@hot_kernel(inline="always")
def decide_step(plan, act, report, C, LP, ext, cmd, rec_o, rec_a, e, k):
    """The action of every agent at step ``k`` into its command row ``cmd[e, i]`` (unclipped,
    thrust on): the fused policy on its context ``C``, the learned controller on the same
    view (its report, where the task judges one, by the task's reference rule), or the
    external action ``ext[e, i]``; the observation and action recorded when ``rec_o`` has a
    step axis (with ``LP.expert`` a learned policy's recorded action is the fused policy's on
    the same observation); a fused policy's executed action disturbed by ``LP.noise`` (the
    recorded action clean)."""
    n_ag = C.O.shape[1]
    if LP.policy == FUSED and LP.plan != 0:
        plan(C, e, k)
    elif LP.policy == LEARNED:
        report(C, e, k)
        if LP.expert != 0:   # the shadow expert plans on the learner's observations
            plan(C, e, k)
    for i in range(n_ag):
        if LP.policy == FUSED:
            ax, ay, az, psi = act(C, e, k, i)
            lx, ly, lz = ax, ay, az
        elif LP.policy == LEARNED:
            ax, ay, az = learned_act(LP.net, C.B.t_lim, C.O, e, i, LP.v_max)
            psi = math.nan
            lx, ly, lz = ax, ay, az
            if LP.expert != 0:
                lx, ly, lz, _ = act(C, e, k, i)
        else:
            ax = ext[e, i, 0]
            ay = ext[e, i, 1]
            az = ext[e, i, 2]
            psi = ext[e, i, 3]
            lx, ly, lz = ax, ay, az
        if k < rec_o.shape[1]:
            record_step(rec_o, rec_a, C.O, e, k, i, lx, ly, lz)
        if LP.noise > 0.0 and LP.policy == FUSED:   # the teacher's disturbed execution
            std = LP.noise * LP.v_max
            cnt = 3 * (k * n_ag + i)
            ax += draw(LP.seed, LP.e0 + e, PURPOSE_TEACHER, cnt, std)
            ay += draw(LP.seed, LP.e0 + e, PURPOSE_TEACHER, cnt + 1, std)
            az += draw(LP.seed, LP.e0 + e, PURPOSE_TEACHER, cnt + 2, std)
        c = cmd[e, i]
        c[0] = ax
        c[1] = ay
        c[2] = az
        c[3] = psi
        c[4] = 1.0


@hot_kernel(inline="always")
def account_agent(after_agent, ctx, LS, e, k, i, en, counting, energy, viol, cur):
    """The accounting of agent ``i``'s step after it moved (every backend): the energy proxy
    ``en`` of its executed action and the move's status ``ctx.code[e, i]`` (a rejected move or
    a contact) counted up to success, the true current speed it met (the metric
    ``current_speed_ms``), its own energy so far (its observation), the task's
    ``after_agent``.

    Returns
    -------
    energy, viol, cur
        The team's updated energy proxy (m2 s-1), violation count and current-speed sum.
    """
    LS.eag[e, i] += en
    if counting:
        energy += en
        if ctx.code[e, i] != OK:
            viol += 1
        ce = LS.cw[e, i, 0]
        cn = LS.cw[e, i, 1]
        cur += math.sqrt(ce * ce + cn * cn)
    after_agent(ctx, e, k, i)
    return energy, viol, cur


@hot_kernel(inline="always")
def end_step(post_step, ctx, LP, LS, e, k, counting, coll, dmin):
    """The end of step ``k`` once every agent moved (every backend): near-collisions (eq. 4)
    and the closest pair (while counting), the task's ``post_step`` judge, dead reckoning over
    the step (and whether an absolute fix came, ``LS.nfix``), the ``REACHED`` latch
    (``LS.k_succ[e]``).

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
    state = ctx.state
    S = state[e]
    if S.shape[0] > 1 and counting:
        d = min_pairwise_distance(S)
        if d <= LP.r_coll:
            coll += 1
        if d < dmin:
            dmin = d
    rc = int(post_step(ctx, e, k))
    for i in range(S.shape[0]):   # dead reckoning over the step's ground displacement
        LS.nfix[e, i] = nav_update(LP.sens, LP.seed, LS.navc, LS.nerr, state, LS.prev, e, k,
                                   i, S.shape[0], LP.dt, LP.e0)
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
def finish_episode(finish, ctx, LP, LS, e, k):
    """Close episode ``e`` after ``k`` steps (every backend): the task's ``finish`` judge
    writes its metrics into ``ctx.res[e]``, the loop the standard columns over the steps up to
    success. ``T`` is the steps to success times ``dt`` on success, else the time limit; the
    near-collision ratio and the mean current speed are per step (and agent) up to success."""
    LS.status[e] = FINISHED
    row = ctx.res[e]
    success = finish(ctx, e, k)
    k_end = LS.k_succ[e] if LS.k_succ[e] >= 0 else k   # the steps the metrics cover
    dt = LP.dt
    n_ag = ctx.state.shape[1]
    row[C_SUCCESS] = 1.0 if success else 0.0
    row[C_T] = k_end * dt if success else LP.n_steps * dt
    row[C_E] = LS.energy[e]
    row[C_COLL] = LS.coll[e] / k_end if k_end > 0 else 0.0
    row[C_VIOL] = LS.viol[e]
    row[C_CUR] = LS.cur[e] / (k_end * n_ag) if k_end > 0 else 0.0


@hot_kernel(inline="always")
def run_episode(begin, pre_step, cue, sense, after_agent, post_step, finish, report, plan, act,
                ctx, K, e, k_stop):
    """Advance episode ``e`` up to step ``k_stop`` (or its end; a negative ``k_stop``
    advances it by ``-k_stop`` steps from where it is, so episodes at different steps move
    together); write ``res[e]`` when it ends. Serial; a task's ``_kernel`` runs it for every
    episode of its block. The arguments are the module docstring's: the task's hooks, the
    policy's hooks, the env hooks' context :class:`EnvCtx` and the batch's arguments
    :class:`Batch`.

    A call with ``k_stop = 0`` starts a new episode and takes its first observation.
    ``LP.phase`` says which part of a step this call runs: ``FULL`` (the core backend: whole
    steps), ``DECIDE`` (another backend's physics: one step's observation and decisions -- the
    command rows and the true currents ``LS.cw`` -- with the executed action clipped and its
    energy in ``LS.en``) or ``JUDGE`` (after that backend moved the agents and wrote each
    move's status into ``LS.code``: the accounting and the judge of the step, then the next
    observation).
    """
    vp, LP, C, LS, cmd, ext, rec_o, rec_a = K.vp, K.LP, K.C, K.LS, K.cmd, K.ext, K.rec_o, K.rec_a
    if LS.status[e] == FINISHED:
        return
    grid, state = ctx.grid, ctx.state
    n_ag = state.shape[1]
    n_steps = LP.n_steps
    dt = LP.dt
    stop = False
    if LS.status[e] == NEW:
        LS.status[e] = RUNNING
        stop = begin(ctx, e)
    k = LS.k[e]
    k_lim = k_stop if k_stop >= 0 else k - k_stop
    energy = LS.energy[e]
    viol = LS.viol[e]
    coll = LS.coll[e]
    dmin = LS.dmin[e]
    cur = LS.cur[e]
    counting = LS.k_succ[e] < 0   # standard metrics accumulate up to success (REACHED)
    judge = LP.phase == JUDGE
    while not stop and k < n_steps:
        if not judge:
            if LS.sensed[e] != k:
                pre_step(ctx, e, k)
                sense_step(cue, sense, ctx, LP, LS, e, k, 0)
            if k >= k_lim:
                break
            decide_step(plan, act, report, C, LP, ext, cmd, rec_o, rec_a, e, k)
            for i in range(n_ag):
                s = state[e, i]
                LS.prev[e, i, 0] = s[0]
                LS.prev[e, i, 1] = s[1]
                LS.prev[e, i, 2] = s[2]
            if LP.phase == DECIDE:   # another backend moves the agents
                for i in range(n_ag):
                    c = cmd[e, i]
                    ax, ay, az = clip_action(c[0], c[1], c[2], LP.v_max)
                    c[0] = ax
                    c[1] = ay
                    c[2] = az
                    LS.en[e, i] = (ax * ax + ay * ay + az * az) * dt
                break
            for i in range(n_ag):
                en, code = advance_agent(grid, LP.model, vp, state[e, i], cmd[e, i],
                                         LS.cw[e, i, 0], LS.cw[e, i, 1], LP.v_max, dt,
                                         LP.land_thr, LP.clearance)
                LS.code[e, i] = code
                energy, viol, cur = account_agent(after_agent, ctx, LS, e, k, i, en, counting,
                                                  energy, viol, cur)
        else:   # JUDGE: the backend moved every agent of step k
            if k >= k_lim:
                break
            for i in range(n_ag):
                energy, viol, cur = account_agent(after_agent, ctx, LS, e, k, i, LS.en[e, i],
                                                  counting, energy, viol, cur)
            judge = False
            k_lim = k + 1   # then the next step's observation, and no further
        k, stop, counting, coll, dmin = end_step(post_step, ctx, LP, LS, e, k, counting, coll,
                                                 dmin)
    LS.k[e] = k
    LS.energy[e] = energy
    LS.viol[e] = viol
    LS.coll[e] = coll
    LS.dmin[e] = dmin
    LS.cur[e] = cur
    if stop or (k >= n_steps and LP.phase != DECIDE):
        finish_episode(finish, ctx, LP, LS, e, k)
        # the observation of the final state (the step API's last observation)
        sense_step(cue, sense, ctx, LP, LS, e, k, 1)


@hot_kernel(inline="always")
def run_block(begin, pre_step, cue, sense, after_agent, post_step, finish, report, plan, act,
              K, io, k_stop, e_lo, e_hi):
    """:func:`run_episode` for the episodes ``[e_lo, e_hi)``, with the step API's side
    ``io`` (:class:`EnvIO`; no rows: nothing in or out): each episode's sub-env action in
    before its steps, its next observation and end flags out after them. The env hooks'
    context :class:`EnvCtx` is built here, once per call."""
    LP, LS, state = K.LP, K.LS, K.state
    X = state if LP.sens.true_position != 0 else LS.nav
    ctx = EnvCtx(K.grid, K.P, K.W, state, X, K.C.O, LS.prev, LS.code, K.res, K.t0, LP.dt)
    for e in range(e_lo, e_hi):
        was = env_step_in(LP, LS, K.ext, io, e)
        run_episode(begin, pre_step, cue, sense, after_agent, post_step, finish, report, plan,
                    act, ctx, K, e, k_stop)
        env_step_out(LP, LS, K.res, K.C.O, io, e, was)


@hot_kernel(inline="always")
def noop_pre_step(ctx, e, k):
    """A ``pre_step`` hook that does nothing (a task without physics before the moves)."""
    return


@hot_kernel(inline="always")
def noop_after_agent(ctx, e, k, i):
    """An ``after_agent`` hook that does nothing."""
    return


@hot_kernel(inline="always")
def noop_sense(ctx, e, k):
    """A ``sense`` hook that does nothing (a task without observation fields of its own)."""
    return


@hot_kernel(inline="always")
def noop_report(C, e, k):
    """A report hook that does nothing (a task that judges no report)."""
    return


@hot_kernel(inline="always")
def noop_plan(C, e, k):
    """A policy ``plan`` hook that does nothing (a policy without a team-level decision)."""
    return


@hot_kernel(inline="always")
def policy_block(plan, act, C, ks, out, e_lo, e_hi):
    """A fused policy outside the loop (its Python driver,
    :class:`oneocean.methods.heuristic.FusedPolicy`): for every episode of ``[e_lo, e_hi)``
    with a step ``ks[e] >= 0``, ``plan(C, e, k)`` then every agent's ``act`` into
    ``out[e, i]`` (ax, ay, az, psi), exactly as the loop's decide phase calls them."""
    for e in range(e_lo, e_hi):
        k = ks[e]
        if k < 0:
            continue
        plan(C, e, k)
        for i in range(out.shape[1]):
            ax, ay, az, psi = act(C, e, k, i)
            out[e, i, 0] = ax
            out[e, i, 1] = ay
            out[e, i, 2] = az
            out[e, i, 3] = psi
