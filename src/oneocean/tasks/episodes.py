"""Python side of the one episode loop: a batch of episodes of one task, resumable.

:class:`Episodes` holds everything a rollout needs (the loop's params and state, the task's
params ``P`` and work arrays ``W``, the method's params ``M``, agent states, buffers) and
advances all episodes together with the task's kernel (:func:`oneocean.tasks.loop.run_episode`
for each episode; blocks of episodes on numba's thread count: :func:`~oneocean.engine.dispatch.over_range`).
``run()`` runs to the end; ``run(k_stop)`` stops every episode before step ``k_stop`` so a
planner or the step API can act in between (``observe`` gives the next observation,
``set_actions`` the external actions of the next segment).
"""

from __future__ import annotations

import numpy as np

from ..engine.constraints import DEFAULT_LAND_THRESHOLD, DEFAULT_R_COLL_M
from ..engine.dynamics import CMD_DIM, model_id, new_state
from ..engine.dispatch import fast_entry, over_range
from ..errors import ConfigError
from .common import ACT_FIELDS, CLEARANCE_M, OBS_DIM, STANDARD, rollout_results
from .tiers import episode_steps, need_tier
from .loop import (ACT_DIM, EXTERNAL, FUSED, FINISHED, LEARNED, Batch, Ctx, LoopParams, env_io,
                   new_loop_state, step_args)


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


class Episodes:
    """E episodes of one task under one method, advanced by the task's compiled loop: the
    core backend's :class:`~oneocean.backends.protocol.Rollout`.

    The batch builds the method's public view once: the task's briefing ``B`` (its
    ``brief``, from what the method is given: the forecast or the truth), the observation
    array ``O`` (E, N, D) the loop fills every step, the task's team observation and report,
    and for a fused method its params ``M`` and memory ``H`` (its policy module's ``params``
    and ``memory`` of the briefing; its ``prepare``, a Python planner on the briefing, runs
    here). All of it is the policy's context ``C`` (:class:`oneocean.tasks.loop.Ctx`).

    Parameters
    ----------
    mod : module
        The task module (``TASK_ID``, ``METRICS``, ``make``, ``brief``); its compiled loop
        (``POLICY``, ``_kernel``) is its spec's kernel module
        (:func:`oneocean.kernels.kernel_module`).
    grid : Grid
        Forcing applied (``run_cell`` sets the tier's gain or switches the current off).
    tier : dict
        Tier parameters plus ``dt_s``.
    init : dict
        The task's ``reset`` output (``pos0`` (E, N, 3), ``psi0`` (E, N), ``t0`` (E,), ...).
    method : str
        A fused method the task's policy module knows (``heuristic``, ``oracle``), a method
        of kind ``learned`` such as ``bc`` (a network on the same public view, ``net``; the
        sensor models), or ``None`` for external actions (the step API; the sensor models).
    dyn : str
        Dynamics model name (:data:`oneocean.vocab.DYNAMICS`).
    vehicle : Vehicle
        The vehicle (:class:`oneocean.engine.dynamics.Vehicle`).
    seed : int
        Run seed (sensor-error streams).
    record : bool
        Record every agent's per-step observation and action.
    fused_plan : bool
        Call the fused policy's ``plan`` hook every step (default). ``False``: the plan in the
        method's memory ``H`` is written by a Python planner between segments
        (:meth:`run_planned`), and the fused ``act`` follows it.
    net : dict
        A learned method only: the network's arrays
        (:func:`oneocean.tasks.learned.load_weights`).
    info : str
        What the method knows instead of its sensors (:data:`oneocean.sensing.INFO_LEVELS`):
        default the method's own (``SENSING`` of its policy module: ``sensors``, or
        ``truth`` for the oracle); the others are the information ablations of a non-oracle
        method (its briefing and observation with one item true).
    e0 : int
        The cell's episode of the first row: row ``e`` draws the random streams of the cell's
        episode ``e0 + e`` (0: a whole cell; a shard of episodes ``[a, b)`` runs with
        ``e0 = a``, :meth:`oneocean.tasks.Cell.run`).
    noise : float
        A fused method's teacher noise (``LoopParams.noise``, in units of ``v_max``; 0: none).
    expert : bool
        A learned method with the fused heuristic as its shadow expert: the recorded actions
        are the heuristic's on the learner's observations (``LoopParams.expert``, DAgger).
    """

    #: The execution backend (:data:`oneocean.backends.protocol.BACKENDS`).
    backend = "core"

    def __init__(self, mod, grid, tier: dict, init: dict, method: str | None, dyn: str,
                 vehicle, seed: int, *, record: bool = False, fused_plan: bool = True,
                 net: dict | None = None, info: str | None = None, e0: int = 0,
                 noise: float = 0.0, expert: bool = False):
        from ..kernels import kernel_module
        from .learned import make_net, no_net
        from .public import Mission
        from ..sensing import nav_aid, sensing_params
        from .tiers import shared_task_table
        from ..sensing.kernels import init_sensing

        need_tier(mod.TASK_ID, tier, "time_limit_s", "dt_s")
        self.kern = kernel_module(mod.TASK_ID)
        pol = self.kern.POLICY
        learned = method is not None and learned_method(method)
        if learned and net is None:
            raise ConfigError(f"task {mod.TASK_ID}: method {method!r} needs its trained "
                              "weights")
        fused = method is not None and not learned
        if fused and method not in pol.SENSING:
            raise ConfigError(f"task {mod.TASK_ID}: method {method!r} has no fused policy "
                              f"here; fused methods: {', '.join(sorted(pol.SENSING))}")
        self.mod = mod
        self.grid = grid
        self.vehicle = vehicle
        self.method = method
        pos0 = np.ascontiguousarray(init["pos0"], dtype=np.float64)
        n_ep, n_ag = pos0.shape[:2]
        self.n_episodes, self.n_agents = n_ep, n_ag
        self.n_steps = episode_steps(tier)
        dt = float(tier["dt_s"])
        self.dt = dt
        self.P, self.W = mod.make(grid, tier, init)
        if info is None:
            info = pol.SENSING[method] if fused else "sensors"
        self.info = info
        kind = LEARNED if learned else FUSED if fused else EXTERNAL
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
                             e0=int(e0), noise=float(noise), expert=int(bool(expert)))
        self.LS = new_loop_state(n_ep, n_ag)
        self._entries: dict = {}   # compiled entry points of the kernels (fast_entry)
        self.t0 = np.ascontiguousarray(init["t0"], dtype=np.float64)
        # the reset's candidate of each episode (its reset stream); default: the episode itself
        self.candidate = np.asarray(init.get("candidate", np.arange(n_ep)), dtype=np.int64)
        self.state = new_state(n_ep, n_ag, pos0, init["psi0"])
        LS = self.LS
        init_sensing(self.LP.sens, self.LP.seed, self.state, LS.fc, LS.cb, LS.navc, LS.nerr,
                     self.LP.e0)
        # the public view: briefing, observation, team observation, report; the method's
        # params and memory (a fused method's; an external or learned batch carries the
        # heuristic's, unused, so that one compiled loop serves every kind)
        B = mod.brief(self.P, self.W, init,
                      Mission(grid, tier, vehicle, self.LP.sens, LS.fc, self.known_state,
                              self.t0, self.LP.seed, self.LP.e0))
        M = pol.params(method if fused else "heuristic", B)
        H = pol.memory(B, M)
        self.obs_dim = OBS_DIM + len(getattr(mod, "OBS_EXTRA", ()))
        team = getattr(mod, "team_obs", None)
        report = getattr(mod, "report", None)
        self.C = Ctx(B, np.full((n_ep, n_ag, self.obs_dim), np.nan),
                     team(self.W) if team is not None else (),
                     M, H, report(self.W) if report is not None else np.zeros(0))
        self.cmd = np.zeros((n_ep, n_ag, CMD_DIM))
        self.ext = np.zeros((n_ep, n_ag, ACT_DIM))
        self.ext[..., 3] = np.nan
        steps = self.n_steps if record else 0
        self.record = bool(record)
        self.obs = np.full((n_ep, steps, n_ag, self.obs_dim), np.nan)
        self.act = np.full((n_ep, steps, n_ag, len(ACT_FIELDS)), np.nan)
        self.columns = STANDARD + tuple(mod.METRICS)
        self.res = np.zeros((n_ep, len(self.columns)))
        self._no_io = env_io(0, n_ag, self.obs_dim)
        prepare = getattr(pol, "prepare", None)
        if (fused or expert) and prepare is not None:
            prepare(B, M, H)

    @property
    def B(self):
        """The briefing (the task's ``<ID>Briefing``) of every episode."""
        return self.C.B

    @property
    def M(self):
        """The fused method's params."""
        return self.C.M

    @property
    def H(self):
        """The fused method's memory."""
        return self.C.H

    @property
    def k(self) -> np.ndarray:
        """(E,) int64 steps taken."""
        return self.LS.k

    @property
    def known_state(self) -> np.ndarray:
        """(E, N, STATE_DIM) the agents' states as the method knows them now (its navigation
        estimate; the truth for a method given the true position)."""
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

    def _args(self) -> Batch:
        return Batch(self.grid, self.vehicle.params, self.LP, self.P, self.W, self.C, self.LS,
                     self.t0, self.state, self.cmd, self.ext, self.obs, self.act, self.res)

    def _call(self, k_stop: int, lo: int, hi: int) -> None:
        args = (self._args(), self._no_io, int(k_stop))
        fn = self._entries.get("run")
        over_range(fn or self.kern._kernel, lo, hi, *args)
        if fn is None:     # compiled (or loaded) now: later calls skip numba's dispatch
            self._entries["run"] = fast_entry(self.kern._kernel, args + (0, 1))

    def run(self, k_stop: int | None = None) -> "Episodes":
        """Advance every running episode up to step ``k_stop`` (default: to its end).

        Parameters
        ----------
        k_stop : int, optional
            Stop before this step (``0``: start the new episodes and take their first
            observation); negative: advance every running episode by ``-k_stop`` steps.
            Episodes past it or finished are left as they are. The next step's observation
            is ready in ``C.O`` when it returns.

        Returns
        -------
        Episodes
            ``self``.
        """
        self._call(self.n_steps if k_stop is None else int(k_stop), 0, self.n_episodes)
        return self

    def run_planned(self, planner, every: int) -> "Episodes":
        """Run to the end in segments of ``every`` steps, calling ``planner(self)`` before
        every segment (the batch's observation ``C.O`` holds the next step's).

        Parameters
        ----------
        planner : callable
            ``planner(batch)``: a method's planning step between segments (it reads the
            public view, ``B`` and ``C.O``, and writes the plan into the method's memory
            ``H``); the batch is built with ``fused_plan=False``.
        every : int
            Segment length, steps (>= 1).

        Returns
        -------
        Episodes
            ``self``.
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

    def set_actions(self, actions, rows=None) -> None:
        """Set the external actions for the next step(s).

        Parameters
        ----------
        actions : (E, N, 3) or (E, N, 4) array_like
            Desired velocity relative to the water per episode and agent, world frame, m
            s-1 (clipped to ``v_max`` by the engine); a fourth column is the commanded
            heading, rad (NaN: free).
        rows : (n,) int array_like, optional
            The episodes ``actions`` are for (its leading axis is then n); default all.
        """
        a = np.asarray(actions, dtype=np.float64)
        ext = self.ext if rows is None else self.ext[np.asarray(rows)]
        if a.ndim != 3 or a.shape[:2] != ext.shape[:2] or a.shape[2] not in (3, 4):
            raise ConfigError(f"actions: expected shape {ext.shape[:2] + (3,)} or "
                              f"{ext.shape}, got {a.shape}")
        ext[..., :3] = a[..., :3]
        ext[..., 3] = a[..., 3] if a.shape[2] == 4 else np.nan
        if rows is not None:
            self.ext[np.asarray(rows)] = ext

    def observe(self, lo: int = 0, hi: int | None = None) -> np.ndarray:
        """The observation of every agent before its next step (new episodes of ``lo ..
        hi-1`` begin and take their first).

        Parameters
        ----------
        lo, hi : int
            Episodes to start (default all).

        Returns
        -------
        (E, N, D) float64
            The observations (:data:`oneocean.tasks.common.OBS_FIELDS` then the task's
            ``OBS_EXTRA``), a copy; an ended episode's is its final state's.
        """
        hi = self.n_episodes if hi is None else int(hi)
        if hi > lo:
            self._call(0, lo, hi)
        return self.C.O.copy()

    def step_observe(self, lo: int = 0, hi: int | None = None) -> np.ndarray:
        """Advance every running episode of ``lo .. hi-1`` by one step and return the next
        observation (as :meth:`observe`, rows outside ``lo .. hi-1`` as they were).

        Parameters
        ----------
        lo, hi : int
            Episodes to step (default all).

        Returns
        -------
        (E, N, D) float64
            ``C.O`` itself (not a copy).
        """
        hi = self.n_episodes if hi is None else int(hi)
        self._call(-1, lo, hi)
        return self.C.O

    def env_step(self, io, lo: int, hi: int) -> bool:
        """One step of the episodes ``lo .. hi-1`` with the step API's side ``io``
        (:class:`oneocean.tasks.loop.EnvIO`: their sub-envs' actions in, observations and end
        flags out) in one compiled call (the kernel module's ``_step_boxed``, else its
        ``_kernel``).

        Parameters
        ----------
        io : EnvIO
            The step API's side.
        lo, hi : int
            Episodes of the batch.

        Returns
        -------
        bool
            True (the step is done).
        """
        call = self._entries.get("step")
        if call is None:
            kern = getattr(self.kern, "_step_boxed", None)
            if kern is None:   # a plugin's kernel module without it: the plain kernel
                over_range(self.kern._kernel, lo, hi, self._args(), io, -1)
                return True
            # k_stop -1 (one step) from Python, an int64 like the fused cells' k_stop: the
            # same compiled _kernel serves both (a -1 literal inside the kernel module would
            # type as Literal[int](-1) and compile the whole loop a second time)
            args = (step_args(self._args()),)
            over_range(kern, lo, hi, *args, io, -1)    # compiles (or loads) on first use
            self._entries["step"] = (fast_entry(kern, args + (io, -1, 0, 1)), args)
            return True
        fn, args = call
        if hi - lo == 1:
            fn(*args, io, -1, lo, hi)
        else:
            over_range(fn, lo, hi, *args, io, -1)
        return True

    def results(self) -> dict:
        """The rollout's results (every episode must have ended).

        Returns
        -------
        dict
            One (E,) array per standard and task metric column (``success`` bool,
            ``violations`` and the task's ``INT_METRICS`` int64, the rest float64), plus
            ``obs`` (E, n_steps, N, D) and ``act`` (E, n_steps, N, 3) when recording.
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
