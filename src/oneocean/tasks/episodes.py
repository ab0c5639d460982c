"""Python side of the one episode loop: a batch of episodes of one task, resumable.

:class:`Episodes` holds everything a rollout needs (the loop's params and state, the task's
params ``P`` and work arrays ``W``, the method's params ``M``, agent states, buffers) and
advances all episodes together with the task's kernel (:func:`oneocean.tasks.loop.run_episode`
for each episode; blocks of episodes on numba's thread count: :func:`over_episodes`).
``run()`` runs to the end; ``run(k_stop)`` stops every episode before step ``k_stop`` so a
planner or the step API can act in between (``observe`` gives the next observation,
``set_actions`` the external actions of the next segment).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..engine.constraints import DEFAULT_LAND_THRESHOLD, DEFAULT_R_COLL_M
from ..engine.dynamics import CMD_DIM, model_id, new_state
from ..errors import ConfigError
from .common import (ACT_FIELDS, CLEARANCE_M, OBS_DIM, STANDARD, episode_steps, need_tier,
                     rollout_results)
from .loop import (EXTERNAL, FUSED, FINISHED, LEARNED, LoopParams, env_io, new_loop_state,
                   step_args)


def learned_method(method: str) -> bool:
    """Whether ``method`` is registered with kind ``learned`` (a network the loop evaluates,
    :mod:`oneocean.tasks.learned`).

    Parameters
    ----------
    method : str
        Method name.

    Returns
    -------
    bool
        True for a registered learned method (e.g. ``bc``); False otherwise, an
        unregistered name included.
    """
    from ..registry import method_spec

    try:
        return method_spec(method).kind == "learned"
    except ConfigError:
        return False


_EXECUTOR: ThreadPoolExecutor | None = None


def _executor(n_threads: int) -> ThreadPoolExecutor:
    """A process-wide thread pool of at least ``n_threads`` workers (kept between calls: the
    step API calls the kernels every step)."""
    global _EXECUTOR
    if _EXECUTOR is None or _EXECUTOR._max_workers < n_threads:
        _EXECUTOR = ThreadPoolExecutor(max_workers=n_threads)
    return _EXECUTOR


def over_range(kernel, lo: int, hi: int, *args) -> None:
    """Run ``kernel(*args, e_lo, e_hi)`` over episodes ``lo .. hi-1`` on
    ``numba.get_num_threads()`` threads, each a contiguous block of episodes.

    Task kernels are serial ``njit(cache=True, nogil=True)`` loops over a block of episodes,
    so threads run them without the GIL; ``prange`` is not used, since numba's parfor pass
    more than doubles every task kernel's compile time. Every episode is computed by one
    thread with counter-based random streams, so results do not depend on the thread count
    (tested).

    Parameters
    ----------
    kernel : callable
        A compiled kernel taking ``(*args, e_lo, e_hi)``.
    lo, hi : int
        The episodes ``lo .. hi-1`` to run (one block, in the calling thread, when
        ``hi - lo <= 1``).
    *args
        The kernel's leading arguments, passed to every block.
    """
    lo, hi = int(lo), int(hi)
    if hi - lo <= 1:               # one episode: no split (and no thread-count query)
        kernel(*args, lo, hi)
        return
    import numba

    n_thr = max(1, min(int(numba.get_num_threads()), hi - lo))
    if n_thr == 1:
        kernel(*args, lo, hi)
        return
    bounds = np.linspace(lo, hi, n_thr + 1).astype(np.int64)
    futures = [_executor(n_thr).submit(kernel, *args, int(bounds[j]), int(bounds[j + 1]))
               for j in range(n_thr)]
    for f in futures:
        f.result()


#: Scalar classes :func:`_type_key` keys by their class alone.
_SCALAR_TYPES = frozenset((complex, np.float64, np.float32, np.int64, np.int32, np.uint64,
                           np.uint32, np.uint8, np.int8, np.bool_, np.complex128))
#: fast_entry's entry points: (dispatcher, argument type key) -> entry
_FAST: dict = {}
_MAX_FAST = 256


class _Unkeyed(Exception):
    """An argument whose numba type :func:`_type_key` does not derive."""


def _type_key(v):
    """A hashable key that determines numba's argument type of ``v`` (``typeof(v,
    Purpose.argument)``): for an ndarray its dtype, ndim, layout flags, writeability and alignment
    (what numba's ``_typeof_ndarray`` reads), for a tuple or NamedTuple its class and its items'
    keys, for a Python int its bit-length class (``_typeof_int``), for the other scalars
    their class. Anything else raises :class:`_Unkeyed`."""
    t = type(v)
    if t is np.ndarray:
        f = v.flags
        return (v.dtype, v.ndim, f.c_contiguous, f.f_contiguous, f.writeable, f.aligned)
    if t is float or t is bool or v is None or t in _SCALAR_TYPES:
        return t
    if t is int:
        n = v.bit_length()
        return (int, n < 32, n < 64, n == 64 and v >= 0)
    if isinstance(v, tuple):
        return (t,) + tuple(_type_key(x) for x in v)
    raise _Unkeyed


def fast_entry(dispatcher, args):
    """The compiled entry point of the numba ``dispatcher`` for the types of ``args``.

    The entry point skips numba's per-call type resolution (about 20 us with the loop's
    NamedTuple arguments, several times a small batch's step). Valid while the arguments keep
    their types. Found once per dispatcher and argument types: later calls with arguments of
    the same types (every batch of a cell) look it up by :func:`_type_key`, which costs a
    small part of numba's type resolution of the same arguments.

    Parameters
    ----------
    dispatcher : numba dispatcher
        A compiled (``njit``) function.
    args : tuple
        All its arguments, as a call would pass them.

    Returns
    -------
    callable
        The compiled entry point; the dispatcher itself where no compiled version matches or
        numba's internals differ.
    """
    try:
        key = (dispatcher, _type_key(tuple(args)))
    except _Unkeyed:
        key = None
    hit = _FAST.get(key) if key is not None else None
    if hit is not None:
        return hit
    try:
        sig = tuple(dispatcher.typeof_pyval(a) for a in args)
        cres = dispatcher.overloads.get(sig)
    except Exception:   # pragma: no cover - a numba without these internals
        return dispatcher
    if cres is None:
        return dispatcher
    if key is not None:
        if len(_FAST) >= _MAX_FAST:
            _FAST.clear()
        _FAST[key] = cres.entry_point
    return cres.entry_point


def over_episodes(kernel, n_episodes: int, *args) -> None:
    """:func:`over_range` over episodes ``0 .. n_episodes-1``.

    Parameters
    ----------
    kernel : callable
        A compiled kernel taking ``(*args, e_lo, e_hi)``.
    n_episodes : int
        Episodes E.
    *args
        The kernel's leading arguments.
    """
    over_range(kernel, 0, n_episodes, *args)


class Episodes:
    """E episodes of one task under one method, advanced by the task's fused kernel: the core
    backend's :class:`~oneocean.backends.protocol.Rollout`.

    Parameters
    ----------
    mod : module
        The task module (``TASK_ID``, ``METRICS``, ``make``); its compiled loop (``POLICY``,
        ``_kernel``, ``_observe_kernel``) is its spec's kernel module
        (:func:`oneocean.kernels.kernel_module`).
    grid : Grid
        Forcing applied (``run_cell`` sets the tier's gain or switches the current off).
    tier : dict
        Tier parameters plus ``dt_s``.
    init : dict
        The task's ``reset`` output (``pos0`` (E, N, 3), ``psi0`` (E, N), ``t0`` (E,), ...).
    method : str
        A fused method the task's policy module knows (``heuristic``, ``oracle``), a method
        of kind ``learned`` such as ``bc`` (the heuristic's mission layer with the action
        from the network ``net``; the heuristic's sensors), or ``None`` for external actions
        (the step API; the sensor models).
    dyn : str
        Dynamics model name (:data:`oneocean.vocab.DYNAMICS`: ``kinematic``, ``3dof``,
        ``4dof``, ``6dof``).
    vehicle : Vehicle
        The vehicle (:class:`oneocean.engine.dynamics.Vehicle`): its ``params`` and speed
        limit ``v_max``, m s-1.
    seed : int
        Run seed (sensor-error streams).
    record : bool
        Record every agent's per-step observation and action.
    fused_plan : bool
        Call the fused policy's ``plan`` hook every step (default). ``False``: the plan
        tokens in ``W`` are written by a Python planner between segments
        (:meth:`run_planned`), and the fused ``act`` follows them.
    net : dict
        A learned method only: the network's arrays
        (:func:`oneocean.tasks.learned.load_weights`).
    info : str
        What the method knows instead of its sensors (:data:`oneocean.sensing.INFO_LEVELS`):
        default the method's own (``SENSING`` of its policy module: ``sensors``, or
        ``truth`` for the oracle); ``true_current`` / ``true_position`` are the information
        ablations of a non-oracle method.
    e0 : int
        The cell's episode of the first row: row ``e`` draws the random streams of the cell's
        episode ``e0 + e`` (0: a whole cell; a shard of episodes ``[a, b)`` runs with
        ``e0 = a``, :meth:`oneocean.tasks.Cell.run`).
    """

    #: The execution backend (:data:`oneocean.backends.protocol.BACKENDS`).
    backend = "core"

    def __init__(self, mod, grid, tier: dict, init: dict, method: str | None, dyn: str,
                 vehicle, seed: int, *, record: bool = False, fused_plan: bool = True,
                 net: dict | None = None, info: str | None = None, e0: int = 0):
        from ..kernels import kernel_module
        from .learned import make_net, no_net
        from ..sensing import nav_aid, sensing_params
        from .common import shared_task_table
        from ..sensing.kernels import init_sensing

        need_tier(mod.TASK_ID, tier, "time_limit_s", "dt_s")
        self.kern = kernel_module(mod.TASK_ID)
        pol = self.kern.POLICY
        learned = method is not None and learned_method(method)
        if learned:
            if net is None:
                raise ConfigError(f"task {mod.TASK_ID}: method {method!r} needs its trained "
                                  "weights")
            method = "heuristic"   # the mission layer it keeps (and its sensors)
        if method is not None and method not in pol.SENSING:
            raise ConfigError(f"task {mod.TASK_ID}: method {method!r} has no fused policy "
                              f"here; fused methods: {', '.join(sorted(pol.SENSING))}")
        self.mod = mod
        self.grid = grid
        self.vehicle = vehicle
        pos0 = np.ascontiguousarray(init["pos0"], dtype=np.float64)
        n_ep, n_ag = pos0.shape[:2]
        self.n_episodes, self.n_agents = n_ep, n_ag
        self.n_steps = episode_steps(tier)
        dt = float(tier["dt_s"])
        self.dt = dt
        # the plan tokens the task carries for the policy (sized or filled by it)
        plan_tokens = getattr(pol, "plan_tokens", None)
        if plan_tokens is None:
            self.P, self.W = mod.make(grid, tier, init)
        else:
            self.P, self.W = mod.make(grid, tier, init, plan_tokens(grid, tier, init))
        self.M = pol.params(method or "heuristic", tier, vehicle)
        if info is None:
            info = pol.SENSING[method] if method is not None else "sensors"
        self.info = info
        kind = LEARNED if learned else FUSED if method is not None else EXTERNAL
        self.LP = LoopParams(model_id(dyn), kind,
                             int(bool(fused_plan)), self.n_steps, int(seed), dt,
                             float(vehicle.v_max),
                             sensing_params(info, dt,
                                            nav_aid(shared_task_table(mod.TASK_ID),
                                                    f"task {mod.TASK_ID}"),
                                            tier.get("forecast_lead_h")),
                             DEFAULT_LAND_THRESHOLD,
                             float(getattr(mod, "CLEARANCE_M", CLEARANCE_M)),
                             float(getattr(mod, "R_COLL_M", DEFAULT_R_COLL_M)),
                             make_net(net, mod.TASK_ID, n_ep, n_ag) if learned else no_net(),
                             e0=int(e0))
        self.LS = new_loop_state(n_ep, n_ag)
        self._entries: dict = {}   # compiled entry points of the kernels (fast_entry)
        self.t0 = np.ascontiguousarray(init["t0"], dtype=np.float64)
        #: which of the task's candidate episodes these are (:meth:`oneocean.tasks.Cell.reset`)
        self.candidate = np.asarray(init.get("candidate", np.arange(n_ep)), dtype=np.int64)
        self.state = new_state(n_ep, n_ag, pos0, init["psi0"])
        LS = self.LS
        init_sensing(self.LP.sens, self.LP.seed, self.state, LS.fc, LS.cb, LS.navc, LS.nerr,
                     self.LP.e0)
        self.cmd = np.zeros((n_ep, n_ag, CMD_DIM))
        self.ext = np.zeros((n_ep, n_ag, len(ACT_FIELDS)))
        steps = self.n_steps if record else 0
        self.record = bool(record)
        self.obs = np.full((n_ep, steps, n_ag, OBS_DIM), np.nan)
        self.act = np.full((n_ep, steps, n_ag, len(ACT_FIELDS)), np.nan)
        self.columns = STANDARD + tuple(mod.METRICS)
        self.res = np.zeros((n_ep, len(self.columns)))
        # a method that plans in Python before the first step (e.g. AS's lawnmower, the G2G
        # and RF routes) writes its plan tokens into W now, from what it knows: the loop's
        # params and state (its information level LP.sens, the episode's forecast LS.fc) and
        # the agents' known state; with external actions these are the heuristic's plan,
        # the task's default mission plan, which the observation's goal cue reads (skipped
        # where the cue does not read it: the policy's PREPARE_EXTERNAL = False)
        prepare = getattr(pol, "prepare", None)
        if prepare is not None and (method is not None
                                    or getattr(pol, "PREPARE_EXTERNAL", True)):
            prepare(grid, self.P, self.W, self.M, self.t0, self.LP, self.LS, self.known_state)

    # ------------------------------------------------------------------ stepping
    @property
    def k(self) -> np.ndarray:
        """(E,) steps taken by each episode."""
        return self.LS.k

    @property
    def known_state(self) -> np.ndarray:
        """(E, N, STATE_DIM) the agents' state as the method knows it (what its policy
        hooks see: the navigation estimate, the truth for a method given the true position).
        A Python planner reads this, never :attr:`state`."""
        if self.LP.sens.true_position:
            return self.state
        nav = self.state.copy()
        nav[..., 0] += self.LS.nerr[..., 0]
        nav[..., 2] += self.LS.nerr[..., 1]
        return nav

    @property
    def done(self) -> np.ndarray:
        """(E,) bool: the episode has ended (success, termination or time limit)."""
        return self.LS.status == FINISHED

    def run(self, k_stop: int | None = None) -> "Episodes":
        """Advance every running episode up to step ``k_stop`` (default: to its end).

        Parameters
        ----------
        k_stop : int, optional
            Stop every episode before this step; a negative ``k_stop`` advances each by
            ``-k_stop`` steps from where it is (the step API, whose episodes may be at
            different steps). None: run to the end.

        Returns
        -------
        Episodes
            ``self``.
        """
        k_stop = self.n_steps if k_stop is None else int(k_stop)
        args = (self.grid, self.vehicle.params, self.LP, self.P, self.W, self.M, self.LS,
                self.t0, self.state, self.cmd, self.ext, self.obs, self.act, self.res, k_stop)
        fn = self._entries.get("run")
        over_episodes(fn or self.kern._kernel, self.n_episodes, *args)
        if fn is None:     # compiled (or loaded) now: later calls skip numba's dispatch
            self._entries["run"] = fast_entry(self.kern._kernel, args + (0, 1))
        return self

    def run_planned(self, planner, every: int) -> "Episodes":
        """Run to the end in segments of ``every`` steps, calling ``planner(self)`` before
        each segment.

        The planner kind of method: it reads the batch, e.g. ``W`` and ``known_state``, and
        writes plan tokens into ``W``; build the batch with ``fused_plan=False``. Planner
        and segments see the same step counter ``k``.

        Parameters
        ----------
        planner : callable
            ``planner(episodes)``, called before every segment.
        every : int
            Segment length, steps (at least 1).

        Returns
        -------
        Episodes
            ``self``, every episode ended.

        Raises
        ------
        ConfigError
            ``every`` below 1.
        """
        every = int(every)
        if every < 1:
            raise ConfigError(f"run_planned: every must be >= 1, got {every}")
        self.run(0)
        while not self.done.all():
            planner(self)
            live = ~self.done
            self.run(int(self.k[live].max()) + every)
        return self

    def set_actions(self, actions) -> None:
        """Set the external actions for the next step(s).

        Parameters
        ----------
        actions : (E, N, 3) array_like
            Desired velocity relative to the water, world frame (x east, y down, z north),
            m s-1; clipped to ``v_max`` by the loop.

        Raises
        ------
        ConfigError
            ``actions`` of another shape.
        """
        a = np.asarray(actions, dtype=np.float64)
        if a.shape != self.ext.shape:
            raise ConfigError(f"actions: expected shape {self.ext.shape}, got {a.shape}")
        self.ext[...] = a

    def observe(self, lo: int = 0, hi: int | None = None) -> np.ndarray:
        """The observation of every agent before its next step.

        Parameters
        ----------
        lo : int
            First episode observed.
        hi : int, optional
            End of the episodes observed (``lo .. hi-1``); None: every episode.

        Returns
        -------
        (E, N, OBS_DIM) float64
            The observations (:data:`oneocean.tasks.common.OBS_FIELDS`); rows outside
            ``lo .. hi-1`` are NaN. A finished episode's is that of its last state: check
            :attr:`done`.
        """
        hi = self.n_episodes if hi is None else int(hi)
        nobs = np.full((self.n_episodes, 1, self.n_agents, OBS_DIM), np.nan)
        nact = np.zeros((self.n_episodes, 1, self.n_agents, len(ACT_FIELDS)))
        if hi > lo:
            args = (self.grid, self.LP, self.P, self.W, self.LS, self.t0, self.state, nobs,
                    nact)
            fn = self._entries.get("observe")
            over_range(fn or self.kern._observe_kernel, lo, hi, *args)
            if fn is None:
                self._entries["observe"] = fast_entry(self.kern._observe_kernel,
                                                      args + (0, 1))
        return nobs[:, 0]

    def step_observe(self, lo: int = 0, hi: int | None = None) -> np.ndarray:
        """Advance every running episode of ``lo .. hi-1`` by one step and return the next
        observation of every agent.

        ``run(-1)`` then ``observe(lo, hi)`` in one compiled call (the step API's step).
        Every running episode must lie in ``lo .. hi-1``.

        Parameters
        ----------
        lo : int
            First episode stepped.
        hi : int, optional
            End of the episodes stepped (``lo .. hi-1``); None: every episode.

        Returns
        -------
        (E, N, OBS_DIM) float64
            The next observations, rows ``lo .. hi-1`` valid. The batch's own buffer,
            overwritten by the next call: copy what you keep.
        """
        hi = self.n_episodes if hi is None else int(hi)
        if not self._fused_step(lo, hi, None):       # a plugin's kernel without the fused step
            self.run(-1)
            return self.observe(lo, hi)
        return self._nobs[:, 0]

    def env_step(self, io, lo: int, hi: int) -> bool:
        """:meth:`step_observe` with the step API's side in the same compiled call: the
        sub-envs' actions written, their observations and end flags read.

        Parameters
        ----------
        io : EnvIO
            The step API's side (:class:`~oneocean.tasks.loop.EnvIO`: episode ``e`` is
            sub-env ``io.rows[e]``).
        lo, hi : int
            The episodes ``lo .. hi-1`` stepped.

        Returns
        -------
        bool
            True when stepped; False (nothing done) for a kernel module without the fused
            step.
        """
        call = self._entries.get("step")
        if call is not None and hi - lo == 1:          # the common case, kept lean
            call[0](*call[1], io, lo, hi)
            return True
        return self._fused_step(int(lo), int(hi), io)

    def _fused_step(self, lo: int, hi: int, io) -> bool:
        call = self._entries.get("step")
        if call is None:
            kern = getattr(self.kern, "_step_kernel", None)
            if kern is None:
                return False
            self._nobs = np.full((self.n_episodes, 1, self.n_agents, OBS_DIM), np.nan)
            nact = np.zeros((self.n_episodes, 1, self.n_agents, len(ACT_FIELDS)))
            self._no_io = env_io(0, self.n_agents, OBS_DIM)
            # the arguments are the batch's own arrays, updated in place: built once (in one
            # struct where the kernel module reads one: a call unboxes one object)
            args = (self.grid, self.vehicle.params, self.LP, self.P, self.W, self.M, self.LS,
                    self.t0, self.state, self.cmd, self.ext, self.obs, self.act, self.res,
                    self._nobs, nact)
            boxed = getattr(self.kern, "_step_boxed", None)
            if boxed is not None:
                kern, args = boxed, (step_args(*args),)
            io = self._no_io if io is None else io
            over_range(kern, lo, hi, *args, io)        # compiles (or loads) on first use
            self._entries["step"] = (fast_entry(kern, args + (io, 0, 1)), args)
            return True
        fn, args = call
        io = self._no_io if io is None else io
        if hi - lo == 1:
            fn(*args, io, lo, hi)
        else:
            over_range(fn, lo, hi, *args, io)
        return True

    def results(self) -> dict:
        """The per-episode result columns.

        Returns
        -------
        dict
            One (E,) array per column of ``STANDARD`` and the task's ``METRICS``
            (:func:`~oneocean.tasks.common.rollout_results`; the task's ``INT_METRICS`` as
            int64), plus ``obs`` / ``act`` when recording.

        Raises
        ------
        RuntimeError
            An episode has not ended.
        """
        if not self.done.all():
            raise RuntimeError(f"task {self.mod.TASK_ID}: results requested before every "
                               "episode ended")
        out = rollout_results(self.res, self.columns, self.obs, self.act, self.record)
        for k in getattr(self.mod, "INT_METRICS", ()):
            out[k] = out[k].astype(np.int64)
        return out


def rollout(mod, grid, tier: dict, init: dict, method: str, dyn: str, vehicle, seed: int, *,
            record: bool = False, net: dict | None = None, info: str | None = None) -> dict:
    """Run every episode of ``init`` to its end with one fused method (or ``bc`` with its
    ``net``).

    Parameters
    ----------
    mod : module
        The task module.
    grid : Grid
        The grid export, forcing applied.
    tier : dict
        Tier parameters plus ``dt_s``.
    init : dict
        The task's ``reset`` output.
    method : str
        A fused method (``heuristic``, ``oracle``) or a learned one (``bc``).
    dyn : str
        Dynamics model name.
    vehicle : Vehicle
        The vehicle (:class:`oneocean.engine.dynamics.Vehicle`).
    seed : int
        Run seed.
    record : bool
        Also return every agent's per-step observation and action.
    net : dict, optional
        A learned method's network (:func:`oneocean.tasks.learned.load_weights`).
    info : str, optional
        What the method knows instead of its sensors (:class:`Episodes`).

    Returns
    -------
    dict
        The per-episode columns (``STANDARD`` + the task's ``METRICS``, plus ``obs`` /
        ``act`` when ``record``; :meth:`Episodes.results`).
    """
    return Episodes(mod, grid, tier, init, method, dyn, vehicle, seed, record=record,
                    net=net, info=info).run().results()
