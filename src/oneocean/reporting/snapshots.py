"""Fig. 5: one-episode snapshots of SPC, UPL, AS and FH over the bathymetry.

:func:`episode_frames` runs ONE episode of a (task, tier, method) cell and records it at a few
fractions of its length: the agents (positions, depth, trails so far) and what the task's world
holds at that step (SPC the oil field, UPL the object and its slots, AS the coverage map, FH the
school). :func:`plot_snapshots` draws one row per task and one column per snapshot time over
the bathymetry of the episode's area of interest, in the paper's style
(:func:`oneocean.reporting.figures.paper_style`; PNG + PDF byte-stable through
:func:`oneocean.reporting.figures.save_figure`).

Which episode. Row ``episode`` of ``Cell(grid, task, tier).reset(episodes, seed)``: the episode
the rollout cell of that seed runs as its episode ``episode`` when ``episodes`` is that cell's
episode count (the workflow's ``rollouts.episodes``; default ``episode + 1``, which is the same
episode unless the tier's current regime depends on the candidates drawn, as it may for tasks
whose regime points vary in depth, AS and UPL). Episodes ``0 .. episode`` are run together
(their random streams are keyed by the episode index, so the batch is cut after ``episode``,
never re-indexed); the others are dropped before the run.

Which steps. A snapshot at fraction ``f`` is the state after ``round(f * k_end)`` steps, where
``k_end`` is the episode's ACTUAL length: the time limit, or the step it stopped at (UPL, AS and
FH stop at success; SPC always runs to its metric horizon). ``k_end`` comes from an
uninterrupted run of the batch (:meth:`Episodes.run`), which also gives the episode's success
and metrics; a second run in segments (:meth:`Episodes.run` with ``k_stop``: the loop resumes
bit for bit) stops every ``trail_every`` steps for the trails and at every snapshot step, and
must end in exactly the uninterrupted run's state (checked).

The per-task part is one small table, :data:`VIEWS`: what of the task's work arrays ``W`` is
fixed geometry, what is drawn at a step, which point is tracked (UPL's object, FH's school
centroid), and how it is drawn. A task without an entry (any other registered task) is drawn
with its agents only.
"""

from __future__ import annotations

import math
import re
import textwrap
from typing import Callable, NamedTuple

import numpy as np

from ..errors import ConfigError, NotApplicable
from .figures import LAND_RGBA, PAGE_IN, new_figure, palette, paper_style, save_figure

__all__ = ["Frame", "EpisodeFrames", "TaskView", "VIEWS", "FIG5_TASKS", "episode_frames",
           "plot_snapshots", "area_of_interest"]

#: The tasks of Fig. 5, in row order.
FIG5_TASKS = ("SPC", "UPL", "AS", "FH")
#: Snapshot times, fractions of the episode's actual length.
DEFAULT_TIMES = (0.0, 0.5, 1.0)
#: Trail sampling, steps.
TRAIL_EVERY = 5
#: Raster of the bathymetry per row (cells per side).
BATHY_PX = 240
#: Margin of the area of interest: this fraction of its larger side, plus ``AOI_PAD_M``.
AOI_MARGIN = 0.08
AOI_PAD_M = 15.0
#: SPC cells whose concentration exceeds this fraction of the initial peak define the plume's
#: extent (crop and drawing).
PLUME_FLOOR = 0.01


class Frame(NamedTuple):
    """One snapshot of an episode (the state after ``k`` steps).

    Attributes
    ----------
    frac : float
        Requested fraction of the episode's actual length.
    k : int
        Steps taken.
    t_s : float
        Time since the episode's start, s (``k dt``).
    xz : numpy.ndarray
        (N, 2) agents' horizontal positions (x east, z north), m.
    depth : numpy.ndarray
        (N,) agents' depths, m (positive down).
    trail : numpy.ndarray
        (N, m, 2) agents' (x, z) at the steps ``trail_k`` (last: ``xz``), m.
    trail_k : numpy.ndarray
        (m,) int64 steps of the trail samples (0 .. k).
    track : numpy.ndarray
        (m, 2) the task's tracked point at ``trail_k`` ((0, 2) if none), m.
    field : dict
        The task's arrays at this step (:data:`VIEWS`).
    stats : dict
        The task's numbers at this step (floats).
    """
    frac: float             # requested fraction of the episode's actual length
    k: int                  # steps taken
    t_s: float              # time since the episode's start, s (k dt)
    xz: np.ndarray          # (N, 2) agents' horizontal positions (x east, z north), m
    depth: np.ndarray       # (N,) agents' depths, m (positive down)
    trail: np.ndarray       # (N, m, 2) agents' (x, z) at the steps ``trail_k`` (last: ``xz``), m
    trail_k: np.ndarray     # (m,) int64 steps of the trail samples (0 .. k)
    track: np.ndarray       # (m, 2) the task's tracked point at ``trail_k`` ((0, 2) if none), m
    field: dict             # the task's arrays at this step (:data:`VIEWS`)
    stats: dict             # the task's numbers at this step (floats)


class EpisodeFrames(NamedTuple):
    """One episode and its snapshots (:func:`episode_frames`).

    Attributes
    ----------
    task : str
        The task id.
    tier : int
        The tier.
    method : str
        The method.
    seed : int
        The cell's seed.
    episode : int
        Row of ``Cell.reset(episodes, seed)``.
    candidate : int
        The task's candidate episode it is (``init["candidate"]``).
    dt : float
        Step, s.
    n_steps : int
        Time limit, steps.
    k_end : int
        Actual length, steps.
    success : bool
        Whether the episode succeeded.
    metrics : dict
        The episode's result row (STANDARD + the task's METRICS), floats.
    static : dict
        The task's fixed geometry (:data:`VIEWS`).
    frames : tuple of Frame
        One per requested time, in the order given.
    """
    task: str
    tier: int
    method: str
    seed: int
    episode: int            # row of ``Cell.reset(episodes, seed)``
    candidate: int          # the task's candidate episode it is (``init["candidate"]``)
    dt: float               # step, s
    n_steps: int            # time limit, steps
    k_end: int              # actual length, steps
    success: bool
    metrics: dict           # the episode's result row (STANDARD + the task's METRICS), floats
    static: dict            # the task's fixed geometry (:data:`VIEWS`)
    frames: tuple           # Frame per requested time, in the order given


class TaskView(NamedTuple):
    """What of a task's work arrays Fig. 5 shows.

    Functions of an :class:`~oneocean.tasks.Episodes` batch ``ep`` and the episode index
    ``e``, or of the recorded episode.

    Attributes
    ----------
    static : callable
        ``(ep, e) -> dict`` of the episode's fixed geometry.
    field : callable
        ``(ep, e) -> (dict of arrays, dict of floats)`` at the current step.
    track : callable or None
        ``(ep, e) ->`` (2,) tracked point (x, z), m; None: nothing tracked.
    extent : callable
        ``(EpisodeFrames) ->`` (n, 2) points the crop must hold, m.
    draw : callable
        ``(ax, EpisodeFrames, Frame, centre, style) -> None``.
    legend : callable
        ``(style) ->`` list of legend handles.
    label : callable
        ``(Frame) ->`` one or two short lines of numbers for the panel.
    """
    static: Callable        # (ep, e) -> dict of the episode's fixed geometry
    field: Callable         # (ep, e) -> (dict of arrays, dict of floats) at the current step
    track: Callable | None  # (ep, e) -> (2,) tracked point (x, z), or None
    extent: Callable        # (EpisodeFrames) -> (n, 2) points the crop must hold
    draw: Callable          # (ax, EpisodeFrames, Frame, centre, style) -> None
    legend: Callable        # (style) -> list of legend handles
    label: Callable         # (Frame) -> one or two short lines of numbers for the panel


# ------------------------------------------------------------------------------------------
# running one episode
# ------------------------------------------------------------------------------------------

def _cut(init: dict, n_keep: int, n_all: int) -> dict:
    """The first ``n_keep`` episodes of a reset dict (arrays with a leading episode axis are
    cut; everything is copied, so runs never share arrays)."""
    from ..tasks.spawn import episode_rows

    return {key: (v.copy() if isinstance(v, np.ndarray) else v)
            for key, v in episode_rows(init, slice(0, n_keep), n_all).items()}


def episode_frames(grid, task: str, tier: int = 2, method: str = "heuristic",
                   seed: int = 1000, episode: int = 0, times=DEFAULT_TIMES,
                   dynamics: str = "6dof", *, episodes: int | None = None,
                   trail_every: int = TRAIL_EVERY, n_agents: int | None = None
                   ) -> EpisodeFrames:
    """Run one episode of a cell and record it at a few fractions of its actual length.

    See the module docstring for which episode and which steps.

    Parameters
    ----------
    grid : Grid or path-like
        A loaded grid export or its ``.npz`` path (:class:`oneocean.tasks.Cell`).
    task : str
        The task id.
    tier : int, default 2
        The tier.
    method : str, default "heuristic"
        A fused method (the task's heuristic or oracle).
    seed : int, default 1000
        The cell's seed.
    episode : int, default 0
        The row of ``Cell.reset(episodes, seed)`` to run.
    times : sequence of float, default ``DEFAULT_TIMES``
        Snapshot times, fractions in [0, 1] of the episode's actual length.
    dynamics : str, default "6dof"
        Vehicle model: ``kinematic``, ``3dof``, ``4dof`` or ``6dof``.
    episodes : int, optional
        Episodes of the rollout cell the episode is drawn from (``Cell.reset(episodes,
        seed)``); default ``episode + 1``.
    trail_every : int, default ``TRAIL_EVERY``
        Trail sampling interval, steps.
    n_agents : int, optional
        Team size (default: the task's own).

    Returns
    -------
    EpisodeFrames
        The episode, its result and one :class:`Frame` per time.

    Raises
    ------
    NotApplicable
        The region cannot host the cell (from :meth:`Cell.reset`).
    ConfigError
        Bad ``times``, ``episode`` or ``trail_every``.
    """
    from ..tasks import Cell

    fr = [float(f) for f in times]
    if not fr or any(not 0.0 <= f <= 1.0 for f in fr):
        raise ConfigError(f"episode_frames: times must be fractions in [0, 1], got {times}")
    episode = int(episode)
    n_all = episode + 1 if episodes is None else int(episodes)
    if not 0 <= episode < n_all:
        raise ConfigError(f"episode_frames: episode {episode} outside the cell's {n_all} "
                          "episodes")
    trail_every = int(trail_every)
    if trail_every < 1:
        raise ConfigError(f"episode_frames: trail_every must be >= 1, got {trail_every}")
    cell = Cell(grid, task, tier, n_agents=n_agents)
    init = cell.reset(n_all, int(seed))            # NotApplicable propagates
    n_keep = episode + 1

    def batch():
        return cell.episodes(_cut(init, n_keep, n_all), method, dynamics, seed)

    e = episode
    ref = batch().run()
    res = ref.results()
    k_end = int(ref.k[e])
    metrics = {k: float(v[e]) for k, v in res.items() if np.ndim(v) == 1}
    steps = [int(round(f * k_end)) for f in fr]

    view = VIEWS.get(task, GENERIC)
    ep = batch()
    stops = sorted(set(range(0, k_end, trail_every)) | set(steps) | {k_end})
    trail, track, snaps = [], [], {}
    for s in stops:
        ep.run(s)                     # s = 0: the loop's begin hook only
        if int(ep.k[e]) != s:
            raise RuntimeError(f"{task}: the segmented run is at step {int(ep.k[e])}, "
                               f"expected {s} (the uninterrupted run ended at {k_end})")
        S = ep.state[e]
        trail.append(S[:, [0, 2]].copy())
        if view.track is not None:
            track.append(np.asarray(view.track(ep, e), dtype=np.float64).copy())
        if s in steps:
            arrays, stats = view.field(ep, e)
            snaps[s] = (len(trail), S[:, 1].copy(), arrays, stats)
    if not np.array_equal(ep.state[e], ref.state[e]):
        raise RuntimeError(f"{task}: the run in segments ended in another state than the "
                           "uninterrupted run")
    static = view.static(ep, e)
    frames = []
    for f, s in zip(fr, steps):
        m, depth, arrays, stats = snaps[s]
        tk = np.asarray(stops[:m], dtype=np.int64)
        frames.append(Frame(f, s, s * cell.params["dt_s"], trail[m - 1].copy(), depth,
                            np.stack(trail[:m], axis=1), tk,
                            np.asarray(track[:m]).reshape(-1, 2), arrays, stats))
    return EpisodeFrames(task, int(tier), str(method), int(seed), e,
                         int(init["candidate"][e]), float(cell.params["dt_s"]),
                         int(ep.n_steps), k_end, bool(res["success"][e]), metrics, static,
                         tuple(frames))


# ------------------------------------------------------------------------------------------
# the per-task views: what of W is drawn, and how
# ------------------------------------------------------------------------------------------

def _agents_extent(ef: EpisodeFrames) -> np.ndarray:
    return np.concatenate([f.trail.reshape(-1, 2) for f in ef.frames])


def _circle(c, r, n=24):
    """``n`` points on a circle, with scalar libm sin/cos: numpy's SIMD kernels may round the
    last bit differently depending on where an element falls in the buffer, and these points
    set the row's crop, hence every coordinate written into the PDF."""
    pts = [(c[0] + r * math.sin(2.0 * math.pi * k / n), c[1] + r * math.cos(2.0 * math.pi * k / n))
           for k in range(n)]
    return np.array(pts, dtype=np.float64)


# ---- SPC: the oil field on its local grid

def _spc_static(ep, e):
    W, P = ep.W, ep.P
    return {"origin": W.origin[e].copy(), "h": float(P.h), "land": W.land[e].copy(),
            "report": W.report[e].copy()}


def _spc_field(ep, e):
    W, P = ep.W, ep.P
    C = W.C[e, 0].copy()
    a = W.acc[e]
    return ({"C": C}, {"mass_kg": float(C.sum() * P.h * P.h), "initial_kg": float(a[0]),
                       "removed_kg": float(a[1]), "escaped_kg": float(a[2])})


def _spc_cells(ef):
    """Cell centres (x, z) of the field's local grid, (nz, nx) each."""
    st = ef.static
    nz, nx = st["land"].shape
    return (st["origin"][0] + st["h"] * np.arange(nx),
            st["origin"][1] + st["h"] * np.arange(nz))


def _spc_extent(ef):
    xs, zs = _spc_cells(ef)
    peak = max(float(f.field["C"].max()) for f in ef.frames)
    pts = []
    for f in ef.frames:
        j, i = np.nonzero(f.field["C"] > PLUME_FLOOR * peak)
        pts.append(np.stack([xs[i], zs[j]], axis=1))
    return np.concatenate(pts + [_agents_extent(ef)])


def _spc_draw(ax, ef, fr, c, sty):
    from matplotlib.colors import PowerNorm

    xs, zs = _spc_cells(ef)
    h = ef.static["h"]
    C = fr.field["C"] * 1e3                                          # g m-2
    vmax = sty["spc_vmax"]
    img = np.ma.masked_less(C, PLUME_FLOOR * vmax)
    ax.imshow(img, origin="lower", cmap=sty["plume_cmap"], norm=PowerNorm(0.5, 0.0, vmax),
              extent=(xs[0] - 0.5 * h - c[0], xs[-1] + 0.5 * h - c[0],
                      zs[0] - 0.5 * h - c[1], zs[-1] + 0.5 * h - c[1]),
              interpolation="nearest", alpha=0.85, zorder=2, rasterized=True)


def _spc_legend(sty):
    from matplotlib.patches import Patch

    return [Patch(facecolor=sty["plume_cmap"](0.7), alpha=0.85, label="oil (surface)")]


def _spc_label(fr):
    s = fr.stats
    return f"{s['mass_kg']:.0f} kg on grid\nremoved {s['removed_kg']:.0f} kg"


# ---- UPL: the object, its slots, the site and the hold circle (no plume in this task)

def _upl_static(ep, e):
    W, P = ep.W, ep.P
    return {"site": W.site[e].copy(), "hold_r": float(P.hold_r),
            "success_depth": float(P.succ_d), "slot_off": W.slot_off[e].copy()}


def _upl_field(ep, e):
    W = ep.W
    obj = W.obj[e].copy()
    site = W.site[e]
    return ({"obj": obj, "slots": obj + W.slot_off[e], "att": W.att[e].copy()},
            {"object_depth_m": float(obj[1]), "attached": float((W.att[e] >= 0).sum()),
             "drift_m": float(math.hypot(obj[0] - site[0], obj[2] - site[2]))})


def _upl_extent(ef):
    st = ef.static
    site = st["site"][[0, 2]]
    return np.concatenate([_circle(site, st["hold_r"]), _agents_extent(ef)]
                          + [f.track for f in ef.frames])


def _upl_draw(ax, ef, fr, c, sty):
    st = ef.static
    site = st["site"][[0, 2]] - c
    ax.add_patch(sty["Circle"](tuple(site), st["hold_r"], fill=False, ls="--", lw=0.6,
                               ec=sty["zone"], zorder=3))
    ax.plot(*site, marker="*", ms=6, mfc="white", mec="k", mew=0.5, ls="none", zorder=4)
    if len(fr.track) > 1:
        ax.plot(fr.track[:, 0] - c[0], fr.track[:, 1] - c[1], color="k", lw=0.6, zorder=4)
    o = fr.field["obj"]
    ax.plot(o[0] - c[0], o[2] - c[1], marker="s", ms=4.5, mfc=sty["object"], mec="k",
            mew=0.5, ls="none", zorder=6)


def _upl_legend(sty):
    from matplotlib.lines import Line2D

    return [Line2D([], [], marker="s", ms=4.5, mfc=sty["object"], mec="k", mew=0.5, ls="none",
                   label="object (+ track)"),
            Line2D([], [], marker="*", ms=6, mfc="white", mec="k", mew=0.5, ls="none",
                   label="site (vessel)"),
            Line2D([], [], color=sty["zone"], ls="--", lw=0.6, label="hold radius")]


def _upl_label(fr):
    s = fr.stats
    return (f"object {s['object_depth_m']:.1f} m deep\n"
            f"agents {np.mean(fr.depth):.1f} m deep, {s['attached']:.0f}/5 attached")


# ---- AS: the region, its coverage map and the lawnmower plan

def _as_static(ep, e):
    W, P, H = ep.W, ep.P, ep.H     # the lawnmower: the fused method's plan (its memory)
    plan = tuple(H.wps[e, i, :int(H.wcount[e, i])].copy() for i in range(H.wps.shape[1]))
    return {"region": W.region[e].copy(), "cell": float(P.cell),
            "ncell": W.ncell[e].copy(), "plan": plan}


def _as_field(ep, e):
    W = ep.W
    ncx, ncz = (int(n) for n in W.ncell[e])
    cov = W.cov[e, :ncx * ncz].reshape(ncz, ncx).astype(bool)
    return ({"cov": cov}, {"coverage": float(W.cnt[e, 0]) / (ncx * ncz)})


def _as_extent(ef):
    x0, z0, x1, z1 = ef.static["region"]
    return np.concatenate([np.array([[x0, z0], [x1, z1]]), _agents_extent(ef)])


def _as_draw(ax, ef, fr, c, sty):
    from matplotlib.colors import ListedColormap

    st = ef.static
    x0, z0, x1, z1 = st["region"]
    ncx, ncz = st["ncell"]
    cell = st["cell"]
    for wp in st["plan"]:
        ax.plot(wp[:, 0] - c[0], wp[:, 1] - c[1], color="0.3", lw=0.4, ls=":", zorder=2)
    cov = np.ma.masked_array(np.ones(fr.field["cov"].shape), mask=~fr.field["cov"])
    ax.imshow(cov, origin="lower", cmap=ListedColormap([sty["cover"]]), vmin=0, vmax=1,
              extent=(x0 - c[0], x0 + ncx * cell - c[0], z0 - c[1], z0 + ncz * cell - c[1]),
              interpolation="nearest", alpha=0.55, zorder=2, rasterized=True)
    ax.add_patch(sty["Rectangle"]((x0 - c[0], z0 - c[1]), x1 - x0, z1 - z0, fill=False,
                                  ec="k", lw=0.6, ls="--", zorder=3))


def _as_legend(sty):
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    return [Line2D([], [], color="k", ls="--", lw=0.6, label="scan region"),
            Patch(facecolor=sty["cover"], alpha=0.55, label="covered cells"),
            Line2D([], [], color="0.3", ls=":", lw=0.6, label="planned strips")]


def _as_label(fr):
    return f"covered {100.0 * fr.stats['coverage']:.0f} %"


# ---- FH: the school, its centroid and the safe zone

def _fh_static(ep, e):
    return {"zone": ep.W.zone[e].copy(), "zone_r": float(ep.P.zone_r),
            "hold_s": float(ep.P.hold)}


def _fh_field(ep, e):
    W = ep.W
    F = W.fish[e, int(W.fcur[e])]
    fish = np.stack([F[0], F[1]], axis=1).copy()
    cen = W.school[e, :2].copy()
    zone = W.zone[e]
    d = float(math.hypot(cen[0] - zone[0], cen[1] - zone[1]))
    inside = float(np.mean(np.hypot(fish[:, 0] - zone[0], fish[:, 1] - zone[1])
                           <= ep.P.zone_r))
    return ({"fish": fish, "centroid": cen},
            {"centroid_dist_m": d, "fraction_inside": inside, "hold_s": float(W.school[e, 4])})


def _fh_extent(ef):
    st = ef.static
    return np.concatenate([_circle(st["zone"], st["zone_r"]), _agents_extent(ef)]
                          + [f.field["fish"] for f in ef.frames] + [f.track for f in ef.frames])


def _fh_draw(ax, ef, fr, c, sty):
    st = ef.static
    z = st["zone"] - c
    ax.add_patch(sty["Circle"](tuple(z), st["zone_r"], fc=sty["cover"], alpha=0.35, ec="none",
                               zorder=2))
    ax.add_patch(sty["Circle"](tuple(z), st["zone_r"], fill=False, ec=sty["zone"], lw=0.7,
                               zorder=3))
    f = fr.field["fish"]
    ax.scatter(f[:, 0] - c[0], f[:, 1] - c[1], s=1.2, c=sty["fish"], linewidths=0, zorder=4,
               rasterized=True)
    if len(fr.track) > 1:
        ax.plot(fr.track[:, 0] - c[0], fr.track[:, 1] - c[1], color=sty["fish"], lw=0.6,
                zorder=4)
    cen = fr.field["centroid"] - c
    ax.plot(*cen, marker="X", ms=4.5, mfc=sty["fish"], mec="white", mew=0.4, ls="none",
            zorder=6)


def _fh_legend(sty):
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    return [Line2D([], [], marker="o", ms=1.6, color=sty["fish"], ls="none", label="fish"),
            Line2D([], [], marker="X", ms=4.5, mfc=sty["fish"], mec="white", mew=0.4,
                   color=sty["fish"], lw=0.6, label="school centroid (+ track)"),
            Patch(facecolor=sty["cover"], alpha=0.35, edgecolor=sty["zone"], label="safe zone")]


def _fh_label(fr):
    s = fr.stats
    txt = f"centroid {s['centroid_dist_m']:.0f} m from zone"
    if s["hold_s"] > 0:
        txt += f"\nheld inside {s['hold_s']:.0f} s"
    return txt


# ---- any other task: agents only

def _none_static(ep, e):
    return {}


def _none_field(ep, e):
    return {}, {}


def _none_draw(ax, ef, fr, c, sty):
    return


#: Fig. 5's view of each task (:class:`TaskView`); other tasks: :data:`GENERIC`.
VIEWS = {
    "SPC": TaskView(_spc_static, _spc_field, None, _spc_extent, _spc_draw, _spc_legend,
                    _spc_label),
    "UPL": TaskView(_upl_static, _upl_field, lambda ep, e: ep.W.obj[e, [0, 2]], _upl_extent,
                    _upl_draw, _upl_legend, _upl_label),
    "AS": TaskView(_as_static, _as_field, None, _as_extent, _as_draw, _as_legend, _as_label),
    "FH": TaskView(_fh_static, _fh_field, lambda ep, e: ep.W.school[e, :2], _fh_extent,
                   _fh_draw, _fh_legend, _fh_label),
}
GENERIC = TaskView(_none_static, _none_field, None, _agents_extent, _none_draw,
                   lambda sty: [], lambda fr: "")


# ------------------------------------------------------------------------------------------
# the figure
# ------------------------------------------------------------------------------------------

def area_of_interest(ef: EpisodeFrames) -> tuple[float, float, float]:
    """The square crop of an episode's row.

    It holds the agents' trails and the task's extent (:data:`VIEWS`) with a margin
    (:data:`AOI_MARGIN`, :data:`AOI_PAD_M`).

    Parameters
    ----------
    ef : EpisodeFrames
        The recorded episode (:func:`episode_frames`).

    Returns
    -------
    tuple of float
        ``(cx, cz, half_side)``: centre (x east, z north) and half the side, m.
    """
    pts = np.asarray(VIEWS.get(ef.task, GENERIC).extent(ef), dtype=np.float64)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    c = 0.5 * (lo + hi)
    half = 0.5 * float((hi - lo).max())
    half += AOI_MARGIN * 2.0 * half + AOI_PAD_M
    return float(c[0]), float(c[1]), half


def _bilinear_nodes(a: np.ndarray, grid, x: np.ndarray, z: np.ndarray) -> np.ndarray:
    """A node field ``a`` (ny, nx) of ``grid`` at points (x, z), bilinear, clamped to the grid
    (the engine's rule for the land mask)."""
    fx = np.clip((x - grid.x0) * grid.inv_dx, 0.0, grid.nx - 1.0)
    fz = np.clip((z - grid.z0) * grid.inv_dz, 0.0, grid.ny - 1.0)
    i0 = np.minimum(fx.astype(np.int64), grid.nx - 2)
    j0 = np.minimum(fz.astype(np.int64), grid.ny - 2)
    wx, wz = fx - i0, fz - j0
    a = np.asarray(a, dtype=np.float64)
    return ((1 - wz) * ((1 - wx) * a[j0, i0] + wx * a[j0, i0 + 1])
            + wz * ((1 - wx) * a[j0 + 1, i0] + wx * a[j0 + 1, i0 + 1]))


def _bathymetry(grid, cx: float, cz: float, half: float, n: int = BATHY_PX):
    """Seafloor depth (n, n) m (NaN on land) and the land mask at the crop's pixel centres."""
    from ..engine.constraints import DEFAULT_LAND_THRESHOLD
    from ..engine.grid import sample_elevation_points

    px = (np.arange(n) + 0.5) / n * 2.0 * half - half
    X, Z = np.meshgrid(cx + px, cz + px)
    xz = np.ascontiguousarray(np.stack([X.ravel(), Z.ravel()], axis=1))
    elev = sample_elevation_points(grid, xz, np.empty(xz.shape[0])).reshape(n, n)
    land = _bilinear_nodes(grid.land, grid, X, Z) >= DEFAULT_LAND_THRESHOLD
    depth = np.where(land, np.nan, -elev)
    return px, depth, land


def _style() -> dict:
    import seaborn as sns
    from matplotlib import colormaps
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Circle, Rectangle

    col = palette(10)
    return {"agent": col[4], "object": col[1], "zone": col[2], "cover": col[2],
            "fish": "0.15", "Circle": Circle, "Rectangle": Rectangle,
            "depth_cmap": ListedColormap(colormaps["Blues"](np.linspace(0.06, 0.62, 256))),
            "plume_cmap": sns.color_palette("YlOrBr", as_cmap=True)}


def _draw_bathymetry(ax, px, depth, land, norm, sty):
    from matplotlib.colors import ListedColormap
    from matplotlib.ticker import MaxNLocator

    ext = (px[0] - 0.5 * (px[1] - px[0]), px[-1] + 0.5 * (px[1] - px[0]))
    ext = ext + ext
    ax.imshow(np.ma.masked_invalid(depth), origin="lower", extent=ext, cmap=sty["depth_cmap"],
              norm=norm, interpolation="nearest", zorder=0, rasterized=True)
    if land.any():
        ax.imshow(np.ma.masked_array(np.ones(land.shape), mask=~land), origin="lower",
                  extent=ext, cmap=ListedColormap([LAND_RGBA]), vmin=0, vmax=1,
                  interpolation="nearest", zorder=1, rasterized=True)
    lo, hi = norm.vmin, norm.vmax
    # whole metres only: a flat crop (a metre or two of relief) gets one contour or none
    levels = [lv for lv in MaxNLocator(4, integer=True, steps=[1, 2, 2.5, 5, 10])
              .tick_values(lo, hi) if lo < lv < hi]
    if levels:
        cs = ax.contour(px, px, np.ma.masked_invalid(depth), levels=levels, colors="0.25",
                        linewidths=0.35, alpha=0.7, zorder=1)
        ax.clabel(cs, fontsize=5, fmt=lambda d: f"{d:g} m", inline=True, inline_spacing=1)


def _draw_agents(ax, fr, c, sty):
    col = sty["agent"]
    for tr in fr.trail:
        ax.plot(tr[:, 0] - c[0], tr[:, 1] - c[1], color=col, lw=0.55, alpha=0.7, zorder=5,
                solid_capstyle="round")
    ax.plot(fr.xz[:, 0] - c[0], fr.xz[:, 1] - c[1], marker="o", ms=3.0, mfc=col, mec="white",
            mew=0.4, ls="none", zorder=7)


def _agent_legend(sty):
    from matplotlib.lines import Line2D

    return [Line2D([], [], marker="o", ms=3.0, mfc=sty["agent"], mec="white", mew=0.4,
                   color=sty["agent"], lw=0.55, label="agents (+ trails)")]


def _label_corner(pts, c, half: float):
    """Where a panel's numbers go: the corner (axes fraction x, y, ha, va) whose box (half
    the width, a fifth of the height) holds the fewest of the row's points ``pts`` (n, 2),
    lower left on a tie; the agents are drawn above it anyway."""
    u = (np.asarray(pts, dtype=np.float64) - c + half) / (2.0 * half)
    best, where = None, None
    for x, y, ha, va in ((0.03, 0.03, "left", "bottom"), (0.97, 0.03, "right", "bottom"),
                         (0.03, 0.97, "left", "top"), (0.97, 0.97, "right", "top")):
        inx = (u[:, 0] <= 0.5) if ha == "left" else (u[:, 0] >= 0.5)
        iny = (u[:, 1] <= 0.2) if va == "bottom" else (u[:, 1] >= 0.8)
        n = int(np.count_nonzero(inx & iny))
        if best is None or n < best:
            best, where = n, (x, y, ha, va)
    return where


def _outcome(ef: EpisodeFrames) -> str:
    from ..registry import task_spec

    prim = task_spec(ef.task).metrics[0]
    T = ef.metrics.get("T_s", math.nan)
    res = f"success, T = {T:.0f} s" if ef.success else "failure"
    return (f"episode {ef.episode} (seed {ef.seed}), {ef.method}\n{res}\n"
            f"{prim} = {ef.metrics.get(prim, math.nan):.3g}")


def _note(task: str, tier: int, reason: str, width: int = 135) -> str:
    """The note of a row the region cannot host: the reason without the prefixes naming the
    cell and the reset, at most two lines."""
    why = re.sub(rf"^{re.escape(task)} tier \d+: ", "", reason.strip())
    why = re.sub(r"^task \S+ reset \(episode \d+\): ", "", why)
    lines = textwrap.wrap(f"{task} (tier {tier}): not applicable in this region: {why}", width)
    if len(lines) > 2:
        lines = [lines[0], textwrap.shorten(" ".join(lines[1:]), width, placeholder=" ...")]
    return "\n".join(lines)


def _summary(ef: EpisodeFrames, aoi) -> dict:
    """The numbers of one row (plain JSON-able values)."""
    out = {"applicable": True, "reason": "", "episode": ef.episode,
           "candidate": ef.candidate, "success": ef.success, "k_end": ef.k_end,
           "n_steps": ef.n_steps, "dt_s": ef.dt,
           "times_s": [float(f.t_s) for f in ef.frames],
           "steps": [int(f.k) for f in ef.frames],
           "fracs": [float(f.frac) for f in ef.frames],
           "metrics": {k: float(v) for k, v in ef.metrics.items()},
           "aoi": {"cx_m": aoi[0], "cz_m": aoi[1], "half_m": aoi[2]},
           "n_agents": int(ef.frames[0].xz.shape[0])}
    keys = sorted({k for f in ef.frames for k in f.stats})
    out["stats"] = {k: [float(f.stats.get(k, math.nan)) for f in ef.frames] for k in keys}
    return out


def plot_snapshots(grid_path, out_png, tasks=FIG5_TASKS, tier: int = 2, seed: int = 1000,
                   method: str = "heuristic", *, episode: int = 0,
                   episodes: int | None = None, times=DEFAULT_TIMES,
                   dynamics: str = "6dof") -> dict:
    """Draw Fig. 5: one episode per task (rows) at ``times`` (columns) over the bathymetry.

    Each row runs :func:`episode_frames` (``episode`` of ``Cell.reset(episodes, seed)``) and
    crops every panel to the same square area of interest (:func:`area_of_interest`; axes in
    metres from its centre, east and north). A panel: the seafloor depth (shaded, a few
    labelled contours; land in the land colour), the task's world (SPC the surface oil,
    square-root scale in g m-2, colour bar per row; UPL the object, its track, the site and
    the hold radius; AS the scan region, covered cells and the planned strips; FH the fish,
    the school centroid's track and the safe zone), the agents and their trails so far; its
    title gives the time since the episode's start; a box gives the task's numbers at that
    step. The last column holds the row's legend, its outcome and colour bars. A task the
    region cannot host (:class:`~oneocean.errors.NotApplicable`) gets a one-line note row.

    Parameters
    ----------
    grid_path : path-like
        The grid export (``.npz``).
    out_png : path-like
        The PNG (the PDF goes beside it: :func:`oneocean.reporting.figures.save_figure`).
    tasks : sequence of str, default ``FIG5_TASKS``
        The rows, in order.
    tier : int, default 2
        The tier.
    seed : int, default 1000
        The cells' seed.
    method : str, default "heuristic"
        A fused method.
    episode : int, default 0
        The row of ``Cell.reset(episodes, seed)`` shown.
    episodes : int, optional
        As :func:`episode_frames`.
    times : sequence of float, default ``DEFAULT_TIMES``
        The columns: fractions in [0, 1] of each episode's actual length.
    dynamics : str, default "6dof"
        Vehicle model.

    Returns
    -------
    dict
        ``tasks``: per task a JSON-able summary (``applicable``, ``reason``, ``episode``,
        ``candidate``, ``success``, ``k_end``, ``n_steps``, ``dt_s``, ``times_s``,
        ``steps``, ``fracs``, ``metrics``, ``aoi``, ``n_agents``, ``stats`` per frame; only
        the first two for a task that is not applicable); ``tier``, ``seed``, ``method``,
        ``episode``, ``episodes``, ``dynamics``, ``png``, ``pdf``.

    Raises
    ------
    ConfigError
        No tasks, or bad ``times`` / ``episode`` (:func:`episode_frames`).
    """
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize, PowerNorm
    from matplotlib.ticker import MaxNLocator

    from ..engine import load_grid

    grid = load_grid(grid_path)
    tasks = [str(t) for t in tasks]
    if not tasks:
        raise ConfigError("plot_snapshots: no tasks")
    rows = []
    for task in tasks:
        try:
            ef = episode_frames(grid, task, tier, method, seed, episode, times, dynamics,
                                episodes=episodes)
        except NotApplicable as exc:
            rows.append((task, None, str(exc)))
            continue
        rows.append((task, ef, ""))
    nt = len(tuple(times))
    summary = {"tier": int(tier), "seed": int(seed), "method": str(method),
               "episode": int(episode), "episodes": episodes, "dynamics": str(dynamics),
               "tasks": {}}

    panel = (PAGE_IN - 0.45 - 1.5) / nt             # panel side, in
    heights = [panel + 0.22 if ef is not None else 0.36 for _, ef, _ in rows]
    with paper_style():
        sty = _style()
        fig = new_figure(PAGE_IN, sum(heights) + 0.15)
        fig.get_layout_engine().set(w_pad=0.02, h_pad=0.03, wspace=0.02, hspace=0.02)
        gs = fig.add_gridspec(len(rows), nt + 1, height_ratios=heights,
                              width_ratios=[1.0] * nt + [1.5 / panel])
        for r, (task, ef, reason) in enumerate(rows):
            if ef is None:
                ax = fig.add_subplot(gs[r, :])
                ax.axis("off")
                ax.text(0.0, 0.5, _note(task, tier, reason), transform=ax.transAxes,
                        ha="left", va="center", fontsize=6.5, color="0.3")
                summary["tasks"][task] = {"applicable": False, "reason": reason}
                continue
            view = VIEWS.get(task, GENERIC)
            cx, cz, half = area_of_interest(ef)
            c = np.array([cx, cz])
            px, depth, land = _bathymetry(grid, cx, cz, half)
            water = depth[np.isfinite(depth)]
            dlo, dhi = (float(water.min()), float(water.max())) if water.size else (0.0, 1.0)
            if dhi - dlo < 1.0:
                dlo, dhi = dlo - 0.5, dhi + 0.5
            norm = Normalize(dlo, dhi)
            if task == "SPC":
                sty["spc_vmax"] = max(float(f.field["C"].max()) for f in ef.frames) * 1e3 or 1.0
            corner = _label_corner(view.extent(ef), c, half)
            for j, fr in enumerate(ef.frames):
                ax = fig.add_subplot(gs[r, j])
                _draw_bathymetry(ax, px, depth, land, norm, sty)
                view.draw(ax, ef, fr, c, sty)
                _draw_agents(ax, fr, c, sty)
                ax.set_xlim(-half, half)
                ax.set_ylim(-half, half)
                ax.set_aspect("equal")
                ax.tick_params(labelsize=6, pad=1)
                ax.locator_params(nbins=4)
                end = " (end)" if fr.k == ef.k_end else ""
                ax.set_title(f"t = {fr.t_s:.0f} s{end}", fontsize=7.5, pad=2)
                lab = view.label(fr)
                if lab:
                    ax.text(corner[0], corner[1], lab, transform=ax.transAxes,
                            ha=corner[2], va=corner[3], fontsize=5.5, zorder=6.5,
                            bbox={"boxstyle": "round,pad=0.2", "fc": "white", "ec": "none",
                                  "alpha": 0.8})
                if j == 0:
                    ax.set_ylabel(f"{task} (tier {ef.tier})\nnorth (m)", fontsize=7)
                else:
                    ax.tick_params(labelleft=False)
                if r == len(rows) - 1 or rows[r + 1][1] is None:
                    ax.set_xlabel("east (m)", fontsize=7, labelpad=1)
            lax = fig.add_subplot(gs[r, nt])
            lax.axis("off")
            lax.legend(handles=_agent_legend(sty) + view.legend(sty), loc="upper left",
                       fontsize=6, handlelength=1.6, borderaxespad=0.0, labelspacing=0.35)
            lax.text(0.0, 0.56, _outcome(ef), transform=lax.transAxes, fontsize=5.5,
                     va="top", ha="left", color="0.2", linespacing=1.3)
            bars = [(ScalarMappable(norm=norm, cmap=sty["depth_cmap"]), "seafloor depth (m)")]
            if task == "SPC":
                bars.append((ScalarMappable(norm=PowerNorm(0.5, 0.0, sty["spc_vmax"]),
                                            cmap=sty["plume_cmap"]), "oil (g m$^{-2}$)"))
            for b, (sm, label) in enumerate(bars):
                cax = lax.inset_axes((0.02, 0.05 + 0.17 * b, 0.9, 0.045))
                fig.colorbar(sm, cax=cax, orientation="horizontal")
                cax.xaxis.set_major_locator(MaxNLocator(4))
                cax.tick_params(labelsize=5, pad=1, length=2)
                cax.set_title(label, fontsize=5.5, pad=1.5)
            summary["tasks"][task] = _summary(ef, (cx, cz, half))
        png, pdf = save_figure(fig, out_png)
    summary.update(png=str(png), pdf=str(pdf))
    return summary
