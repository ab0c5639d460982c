"""Task adapters of the LLM planner: what the model is asked, and how its answer becomes the
plan the fused heuristic ``act`` follows.

The planner works only at the high level, on the public view (the briefing, the observation,
the team observation and the heuristic's own memory; never the task's work arrays). Before
each K-step segment of a batch (:meth:`oneocean.tasks.episodes.Episodes.run_planned`, built
with ``fused_plan=False``: the observation of the next step is taken), for every live
episode ``e`` at its step ``k`` the task's adapter

1. :meth:`~Adapter.decide`: writes the deterministic fallback -- what the fused heuristic
   would plan now -- into the heuristic's memory ``H`` (so it is in place whatever the model
   does) and returns a :class:`Decision` (summary text, agents, targets, the fallback as
   ints) if there is a choice to make now, else None (no call);
2. :meth:`~Adapter.apply`: writes a *valid* assignment into the memory ``H``.

An assignment is one integer per agent in ``[0, n_targets)`` (:mod:`.plan`). The summaries hold
only what every method is given: the briefing (the spill report, the survey region, the
pipeline sections), the observation (the agents' navigation estimates), the task's team
observation (the aerial map) and the heuristic's own plan and report (its waypoints, its leak
claims).

``SPC`` (source assignment; :class:`SPCAdapter`)
    At the aerial map's steps (the team observation's ``t_map`` is the step's time) the
    heuristic's plan hook assigns the mapped blocks greedily (``H.tgt``, ``H.tmap``). Targets:
    the mapped blocks heavier than ``MIN_BLOCK_FRAC`` of the mapped mass, heaviest first (ties
    by block index), at most ``N + EXTRA_CANDIDATES``; the fallback gives each agent the
    candidate its greedy target is (the greedy picks among the N heaviest, so it is listed).
    Applying sets ``H.tgt[e, i]`` to candidate ``a[i]``'s centroid, ``H.tmap[e] = t``. Step 0
    (the ring around the report) and other steps are no decision. K must be a multiple of the
    map period (default: the map period, so every map step is a planning step).
``AS``, ``PI`` (waypoint skipping; :class:`WaypointAdapter`)
    Each agent follows its list ``H.wps[e, i, :H.wcount[e, i]]``; ``H.widx[e, i]`` is the
    waypoint it heads for. Target ``j`` of an agent = offset ``j`` from ``widx``: head for
    waypoint ``widx + j`` next, skipping the ``j`` before it (0 = the heuristic's order, the
    fallback, which writes nothing). ``n_targets`` = the fewest remaining waypoints over the
    agents, at most ``HORIZON``; with fewer than 2 there is no choice, so no call (an agent
    that has finished its list has none left). PI: an agent still in transit to its section
    start (``widx == 0``: detection is off until it arrives) has no choice either -- skipping
    the start would survey from the transit -- and a finished section (``H.done``) has nothing
    left. Default K: 30 steps.
"""

from __future__ import annotations

from typing import NamedTuple, Sequence

import numpy as np
from ...errors import ConfigError
from ...tasks import spc as SPC_TASK
from ...tasks.common import O_DEPTH, O_X, O_Z
from ..heuristic import spc as SPC_POLICY

#: SPC: candidate blocks offered beyond the team size.
EXTRA_CANDIDATES = 6
#: AS, PI: waypoints ahead an agent may choose among (offsets 0 .. HORIZON-1 from ``widx``).
HORIZON = 4
#: AS, PI: default planning period, steps.
WAYPOINT_EVERY = 30


class Decision(NamedTuple):
    """A choice to put to the model for one episode now.

    Attributes
    ----------
    summary : str
        The state as the heuristic knows it (the user message's text).
    n_agents : int
        Agents to assign.
    n_targets : int
        Targets to choose among.
    fallback : tuple of int
        The heuristic's own plan as an assignment.
    options : ndarray
        What :meth:`Adapter.apply` needs to turn an assignment into plan tokens (SPC: the
        candidates' centroids (n_targets, 2), m; AS/PI: unused, empty).
    """

    summary: str
    n_agents: int
    n_targets: int
    fallback: tuple[int, ...]
    options: np.ndarray


def _now(ep, e: int) -> tuple[int, float]:
    """Step ``k`` and time ``t = t0[e] + k dt`` (s) of episode ``e`` (as the loop computes it)."""
    k = int(ep.k[e])
    return k, float(ep.t0[e] + k * ep.dt)


def _xz(x: float, z: float) -> str:
    """A horizontal position rounded to 1 m."""
    return f"({x:.0f}, {z:.0f})"


def _check_assignment(assignment: Sequence[int], d: Decision) -> list[int]:
    """``assignment`` as ints; ``ValueError`` unless it has ``d.n_agents`` entries in
    ``[0, d.n_targets)`` (the planner validated it: a violation is a caller's bug)."""
    a = [int(v) for v in assignment]
    if len(a) != d.n_agents or not all(0 <= v < d.n_targets for v in a):
        raise ValueError(f"assignment {a} is not {d.n_agents} targets in [0, {d.n_targets})")
    return a


class Adapter:
    """The interface of a task adapter (module doc)."""

    task = ""

    def default_every(self, params: dict, vehicle) -> int:
        """The planning period K when none is given.

        Parameters
        ----------
        params : dict
            The cell's tier parameters plus ``dt_s`` and ``v_max``
            (:attr:`oneocean.tasks.Cell.params`).
        vehicle : Vehicle
            The task's vehicle (:class:`oneocean.engine.dynamics.Vehicle`).

        Returns
        -------
        int
            Steps (:data:`WAYPOINT_EVERY`).
        """
        return WAYPOINT_EVERY

    def every(self, params: dict, vehicle, every: int | None) -> int:
        """The planning period to use: ``every`` (checked) or :meth:`default_every`.

        Parameters
        ----------
        params : dict
            The cell's tier parameters plus ``dt_s`` and ``v_max``
            (:attr:`oneocean.tasks.Cell.params`).
        vehicle : Vehicle
            The task's vehicle (:class:`oneocean.engine.dynamics.Vehicle`).
        every : int or None
            The requested period, steps (>= 1); None: the default.

        Returns
        -------
        int
            The period, steps.

        Raises
        ------
        ConfigError
            If ``every`` is not an integer >= 1.
        """
        if every is None:
            return self.default_every(params, vehicle)
        if isinstance(every, bool) or not isinstance(every, (int, np.integer)) or every < 1:
            raise ConfigError(f"llm planner: every must be an integer >= 1 (steps), got "
                              f"{every!r}")
        return int(every)

    def decide(self, ep, e: int) -> Decision | None:
        """Write the fallback into the memory ``H`` and return the choice to put to the model,
        if any.

        The fallback (what the fused heuristic would plan now) is in place whatever the model
        does.

        Parameters
        ----------
        ep : Episodes
            The batch (:class:`oneocean.tasks.episodes.Episodes`, built with ``fused_plan=False``).
        e : int
            Episode index.

        Returns
        -------
        Decision or None
            The summary, counts, fallback and options of the choice; None when there is no choice
            now (no call).
        """
        raise NotImplementedError

    def apply(self, ep, e: int, d: Decision, assignment: Sequence[int]) -> None:
        """Write a valid assignment into the heuristic's memory ``H``.

        Parameters
        ----------
        ep : Episodes
            The batch (:class:`oneocean.tasks.episodes.Episodes`, built with ``fused_plan=False``).
        e : int
            Episode index.
        d : Decision
            The decision it answers (:meth:`decide`).
        assignment : sequence of int
            ``d.n_agents`` targets in ``[0, d.n_targets)`` (validated by the planner).

        Raises
        ------
        ValueError
            If the assignment does not fit ``d`` (a caller's bug).
        """
        raise NotImplementedError


# ------------------------------------------------------------------------------ SPC

def spc_candidates(bm: np.ndarray, total: float, n_agents: int) -> np.ndarray:
    """Block indices offered as SPC targets.

    Blocks with a mass above ``MIN_BLOCK_FRAC * total``, heaviest first (ties by block index),
    the first ``n_agents + EXTRA_CANDIDATES``.

    Parameters
    ----------
    bm : (nb,) float64
        The aerial map's block masses, kg.
    total : float
        The mapped mass, kg.
    n_agents : int
        Team size N.

    Returns
    -------
    (n,) int64
        Block indices.
    """
    valid = np.flatnonzero(bm > SPC_POLICY.MIN_BLOCK_FRAC * total)
    order = valid[np.lexsort((valid, -bm[valid]))]
    return order[:n_agents + EXTRA_CANDIDATES]


def spc_summary(t_rel: float, k: int, report, pos, cents, masses) -> str:
    """The SPC state as the heuristic knows it, as text for the model.

    Time, the spill report, the aerial map's candidate blocks and the agents' positions.

    Parameters
    ----------
    t_rel : float
        Time since the episode's start, s.
    k : int
        Step index.
    report : (2,) float64
        The spill's reported initial centroid (x, z), m.
    pos : (N, 2) float64
        The agents' known positions (x, z), m.
    cents : (n_targets, 2) float64
        The candidate blocks' mass centroids (x, z), m.
    masses : (n_targets,) float64
        The candidate blocks' masses, kg.

    Returns
    -------
    str
        The summary, one fact per line.
    """
    lines = [f"Task: surface oil-spill cleanup with {len(pos)} surface vehicles. Time "
             f"{t_rel:.0f} s since the start (step {k}). The slick drifts with the current; "
             "each vehicle removes oil around itself.",
             f"Spill reported at start at (x, z) = {_xz(*report)} m (x east, z north).",
             f"Aerial map now: {len(cents)} candidate target blocks "
             "(index: mass centroid (x, z) m, oil mass kg), heaviest first:"]
    lines += [f"  {j}: {_xz(c[0], c[1])} {m:.1f} kg" for j, (c, m) in enumerate(zip(cents, masses))]
    lines.append("Agents (index: position (x, z) m):")
    lines += [f"  {i}: {_xz(p[0], p[1])}" for i, p in enumerate(pos)]
    lines.append("Target = the candidate block an agent heads for (several agents may share "
                 "one).")
    return "\n".join(lines)


class SPCAdapter(Adapter):
    """Source assignment at the aerial map steps (module doc)."""

    task = "SPC"

    def default_every(self, params: dict, vehicle) -> int:
        """The planning period K when none is given: the heuristic's aerial-map period.

        Parameters
        ----------
        params : dict
            The cell's tier parameters plus ``dt_s`` and ``v_max``
            (:attr:`oneocean.tasks.Cell.params`).
        vehicle : Vehicle
            The task's vehicle (:class:`oneocean.engine.dynamics.Vehicle`).

        Returns
        -------
        int
            Steps (the aerial map's period, :func:`oneocean.tasks.spc.aerial_steps`).
        """
        return SPC_TASK.aerial_steps(params)

    def every(self, params: dict, vehicle, every: int | None) -> int:
        """The planning period to use: ``every`` (checked) or :meth:`default_every`.

        Parameters
        ----------
        params : dict
            The cell's tier parameters plus ``dt_s`` and ``v_max``
            (:attr:`oneocean.tasks.Cell.params`).
        vehicle : Vehicle
            The task's vehicle (:class:`oneocean.engine.dynamics.Vehicle`).
        every : int or None
            The requested period, steps (>= 1); None: the default.

        Returns
        -------
        int
            The period, steps: a multiple of the aerial-map period.

        Raises
        ------
        ConfigError
            If ``every`` is not an integer >= 1 or not a multiple of the map period.
        """
        k = super().every(params, vehicle, every)
        period = self.default_every(params, vehicle)
        if k % period:
            raise ConfigError(f"llm planner: SPC plans at the aerial map steps, so every must "
                              f"be a multiple of the map period ({period} steps), got {k}")
        return k

    def decide(self, ep, e: int) -> Decision | None:
        """Write the fallback into ``W`` and return the choice to put to the model, if any.

        The fallback (what the fused heuristic would plan now) is in place whatever the model
        does.

        Parameters
        ----------
        ep : Episodes
            The batch (:class:`oneocean.tasks.episodes.Episodes`, built with ``fused_plan=False``).
        e : int
            Episode index.

        Returns
        -------
        Decision or None
            The summary, counts, fallback and options of the choice; None when there is no choice
            now (no call).

        Notes
        -----
        A decision is made at the heuristic's map steps after step 0 when the greedy gave every
        agent a target; the fallback is each agent's greedy target among the candidates
        (:func:`spc_candidates`).
        """
        k, t = _now(ep, e)
        C = ep.C
        SPC_POLICY.plan(C, e, k)          # the fallback: the ring at step 0, the greedy at a map
        if k == 0 or not C.T.t_map[e] == t:   # no map now: nothing to choose
            return None
        H = C.H
        n_ag = ep.n_agents
        if not (H.done[e] == 1).all():   # the greedy left an agent without a target
            return None
        bm = C.T.mass[e]
        cand = spc_candidates(bm, float(C.T.total[e]), n_ag)
        cents = np.column_stack([C.T.x[e, cand], C.T.z[e, cand]])
        fallback = []
        for i in range(n_ag):
            hit = np.flatnonzero((cents[:, 0] == H.tgt[e, i, 0]) & (cents[:, 1] == H.tgt[e, i, 1]))
            if hit.size == 0:
                return None   # cannot happen (module doc); keep the heuristic's plan
            fallback.append(int(hit[0]))
        summary = spc_summary(t - float(ep.t0[e]), k, C.B.report[e],
                              C.O[e][:, [O_X, O_Z]], cents, bm[cand])
        return Decision(summary, n_ag, len(cand), tuple(fallback), cents)

    def apply(self, ep, e: int, d: Decision, assignment: Sequence[int]) -> None:
        """Write a valid assignment into the plan tokens of ``W``.

        Parameters
        ----------
        ep : Episodes
            The batch (:class:`oneocean.tasks.episodes.Episodes`, built with ``fused_plan=False``).
        e : int
            Episode index.
        d : Decision
            The decision it answers (:meth:`decide`).
        assignment : sequence of int
            ``d.n_agents`` targets in ``[0, d.n_targets)`` (validated by the planner).

        Raises
        ------
        ValueError
            If the assignment does not fit ``d`` (a caller's bug).

        Notes
        -----
        Sets ``H.tgt[e, i]`` to candidate ``assignment[i]``'s centroid and ``H.tmap[e] = t``.
        """
        a = _check_assignment(assignment, d)
        _, t = _now(ep, e)
        ep.H.tgt[e] = d.options[a]
        ep.H.tmap[e] = t


# ------------------------------------------------------------------------------ AS, PI

class WaypointAdapter(Adapter):
    """Waypoint skipping along each agent's list (module doc).

    Subclasses say what the team knows of its progress and which agents have no choice.
    """

    label = ""

    def choices(self, H, e: int) -> np.ndarray:
        """Waypoints each agent may head for next: its remaining ones, at most ``HORIZON``.

        Parameters
        ----------
        H : NamedTuple
            The task's work arrays (:class:`oneocean.tasks.as_.ASWork` or
            :class:`oneocean.tasks.pi.PIWork`).
        e : int
            Episode index.

        Returns
        -------
        (N,) int64
            Per agent: 0 (list finished or nothing to choose), 1 (no choice) up to ``HORIZON``.
        """
        return np.clip(H.wcount[e] - H.widx[e], 0, HORIZON)

    def progress(self, ep, e: int) -> list[str]:
        """Task-level lines of the summary (what the team knows of its progress).

        Parameters
        ----------
        ep : Episodes
            The batch (:class:`oneocean.tasks.episodes.Episodes`, built with ``fused_plan=False``).
        e : int
            Episode index.

        Returns
        -------
        list of str
            Summary lines.
        """
        return []

    def decide(self, ep, e: int) -> Decision | None:
        """Write the fallback into the memory ``H`` and return the choice to put to the model,
        if any.

        The fallback (what the fused heuristic would plan now) is in place whatever the model
        does.

        Parameters
        ----------
        ep : Episodes
            The batch (:class:`oneocean.tasks.episodes.Episodes`, built with ``fused_plan=False``).
        e : int
            Episode index.

        Returns
        -------
        Decision or None
            The summary, counts, fallback and options of the choice; None when there is no choice
            now (no call).

        Notes
        -----
        No decision when some agent has fewer than two waypoints to choose among; the fallback is
        0 for every agent (the planned order).
        """
        H = ep.H
        left = self.choices(H, e)
        n_t = int(left.min())
        if n_t < 2:   # some agent has no choice: the only valid assignment is the fallback
            return None
        k, t = _now(ep, e)
        lines = [f"Task: {self.label} with {ep.n_agents} vehicle(s), each following its "
                 f"planned waypoint list. Time {t - float(ep.t0[e]):.0f} s since the start "
                 f"(step {k}).", *self.progress(ep, e),
                 "Agents (position (x, z) m, x east, z north, and depth m; waypoints reached "
                 "of the list; next waypoints as offset: (x, z) m):"]
        O = ep.C.O[e]        # where the agents think they are (their observations)
        for i in range(ep.n_agents):
            o = O[i]
            w, nw = int(H.widx[e, i]), int(H.wcount[e, i])
            nxt = ", ".join(f"{j}: {_xz(*H.wps[e, i, w + j])}" for j in range(int(left[i])))
            lines.append(f"  {i}: at {_xz(o[O_X], o[O_Z])} depth {o[O_DEPTH]:.0f}; reached "
                         f"{w} of {nw}; next {nxt}")
        lines.append("Target = the offset of the waypoint an agent heads for next: 0 keeps "
                     "the planned order, j skips the j waypoints before it.")
        return Decision("\n".join(lines), ep.n_agents, n_t, (0,) * ep.n_agents,
                        np.zeros((0, 2)))

    def apply(self, ep, e: int, d: Decision, assignment: Sequence[int]) -> None:
        """Write a valid assignment into the heuristic's memory ``H``.

        Parameters
        ----------
        ep : Episodes
            The batch (:class:`oneocean.tasks.episodes.Episodes`, built with ``fused_plan=False``).
        e : int
            Episode index.
        d : Decision
            The decision it answers (:meth:`decide`).
        assignment : sequence of int
            ``d.n_agents`` targets in ``[0, d.n_targets)`` (validated by the planner).

        Raises
        ------
        ValueError
            If the assignment does not fit ``d`` (a caller's bug).

        Notes
        -----
        Agent ``i`` skips ``assignment[i]`` waypoints: ``H.widx[e, i]`` advances by it.
        """
        a = _check_assignment(assignment, d)
        for i, j in enumerate(a):
            if j > 0:
                ep.H.widx[e, i] += j


class ASAdapter(WaypointAdapter):
    """AS: skip along the lawnmower (run-in waypoint, then the strips' ends)."""

    task = "AS"
    label = "area scan (lawnmower survey imaging the seafloor of a region)"

    def progress(self, ep, e: int) -> list[str]:
        """The survey region and the share of its seafloor imaged so far.

        Parameters
        ----------
        ep : Episodes
            The batch (:class:`oneocean.tasks.episodes.Episodes`, built with ``fused_plan=False``).
        e : int
            Episode index.

        Returns
        -------
        list of str
            Summary lines.
        """
        B = ep.B
        x0, z0, x1, z1 = B.region[e]
        return [f"Survey region: x {x0:.0f}..{x1:.0f} m, z {z0:.0f}..{z1:.0f} m. Success: "
                f"at least {100.0 * B.coverage_threshold:.1f}% of its seafloor imaged."]


class PIAdapter(WaypointAdapter):
    """PI: skip along one's pipeline section.

    No choice in transit to the section start (``widx == 0``) nor once the section is
    finished (``H.done``).
    """

    task = "PI"
    label = ("pipeline inspection for leaks (each vehicle surveys its section of the "
             "pipeline)")

    def choices(self, H, e: int) -> np.ndarray:
        """Waypoints each agent may head for next (none in transit or once finished).

        Parameters
        ----------
        H : NamedTuple
            The task's work arrays (:class:`oneocean.tasks.as_.ASWork` or
            :class:`oneocean.tasks.pi.PIWork`).
        e : int
            Episode index.

        Returns
        -------
        (N,) int64
            Per agent: 0 (list finished or nothing to choose), 1 (no choice) up to ``HORIZON``.
        """
        left = super().choices(H, e)
        left = np.where(H.widx[e] == 0, np.minimum(left, 1), left)
        return np.where(H.done[e] == 1, 0, left)

    def progress(self, ep, e: int) -> list[str]:
        """The leak claims the team has filed so far.

        Parameters
        ----------
        ep : Episodes
            The batch (:class:`oneocean.tasks.episodes.Episodes`, built with ``fused_plan=False``).
        e : int
            Episode index.

        Returns
        -------
        list of str
            Summary lines.
        """
        R = ep.C.R[e]        # the report the heuristic files (its claims)
        rows = np.flatnonzero(np.isfinite(R[:, 0]) & np.isfinite(R[:, 1]))
        n = rows.size
        claims = "; ".join(_xz(R[j, 0], R[j, 1]) for j in rows)
        return [f"Leak claims filed so far: {n}" + (f", at {claims} m." if n else ".")]


#: The adapter of each task the LLM planner drives.
ADAPTERS: dict[str, Adapter] = {
    "SPC": SPCAdapter(),
    "AS": ASAdapter(),
    "PI": PIAdapter(),
}


def adapter_for(task: str) -> Adapter:
    """The adapter of ``task``.

    Parameters
    ----------
    task : str
        Task id (``SPC``, ``AS`` or ``PI``).

    Returns
    -------
    Adapter
        Its entry of :data:`ADAPTERS`.

    Raises
    ------
    ConfigError
        One line, for a task without an adapter.
    """
    try:
        return ADAPTERS[task]
    except KeyError:
        raise ConfigError(f"llm planner: no adapter for task {task!r}; tasks: "
                          f"{', '.join(sorted(ADAPTERS))}") from None

