"""Route planning through a time-varying 2-D current field, and the vehicle power model.

Zermelo's navigation problem on a grid graph: a vehicle moving at speed ``u`` through the
water, steering by crabbing (it cancels the cross-track current and spends the rest of ``u``
along its track, the steering of :func:`oneocean.methods.steering.seek_max`), has the ground speed
``g = c_par + sqrt(u^2 - c_perp^2)`` along a unit direction in a current ``c`` (``c_par``,
``c_perp``: along- and cross-track parts); it cannot hold a track whose cross current reaches
``u`` (less a headroom ``hold``) or whose ground speed is below ``G_MIN``.

:func:`plan_route` finds the best route between two points by a time-dependent Dijkstra search
over a regular node lattice with 16 edge directions (the 8 neighbours and the 8 knight moves),
every edge integrated piecewise along it through the field at the time the vehicle gets there
(directed by A*'s estimate of the cost to the goal, the straight distance at the least cost per
metre any current on the lattice allows: the same route, fewer nodes searched), then shortens
the lattice path by string pulling (a vertex is skipped when the straight segment past it is
passable and no dearer) and schedules the result piece by piece
(:func:`schedule`, also the planner of a fixed route). The cost is the time (the time-optimal
route; each piece at the fastest of the given speeds, one speed: the fixed-speed problem) or,
given a power model ``P(u) = hotel + k u^3``, the energy (the least-energy route and speed
schedule; each piece at the speed with the least energy). In a uniform current the route is
the straight line and its time ``distance / g`` exactly (tested).

Everything here is arrays in, arrays out: the field is given as node arrays (``cur`` currents
at the lattice nodes at ``times``, ``free`` > 0 where the vehicle may go), sampled bilinearly
between nodes and linearly in time (clamped outside), exactly what the planner "knows": the
caller fills them from the truth (the oracle) or from its forecast of it
(:func:`field_from_grid`, :func:`forecast_field`; :func:`plan_mission` does both for a task).
No BLAS, no ``fastmath``, plain IEEE arithmetic and a heap keyed on (cost, node index): the
same bits on every CPU. The kernels the episode loop inlines to fly a plan are
:func:`follow_path` and :func:`hold_speed`.

The power model (:class:`PowerModel`, ``data/vehicles.yaml`` ``power:``) is the electrical
power of a vehicle at speed ``u`` through the water; its maximum-range speed
``(hotel / 2k)^(1/3)`` (least energy per metre in still water) is the cruise speed of a
vehicle that flies one speed (:func:`cruise_speed`).
"""

from __future__ import annotations

import math
from functools import lru_cache
from pathlib import Path
from typing import NamedTuple

import numpy as np
import yaml
from numba import njit

from ..engine._jit import hot_kernel
from ..engine.dynamics import vehicles_file
from ..engine import libm
from ..engine.grid import (current_from_parts, locate_time, point_cell, sample_elevation,
                           sample_land, synthetic_tide, time_slab)
from ..errors import ConfigError
from ..sensing.kernels import forecast

#: Edge directions of the lattice: (di, dj) node offsets (x, z), 8 neighbours + 8 knight moves.
EDGES = np.array([(1, 0), (0, 1), (-1, 0), (0, -1), (1, 1), (-1, 1), (-1, -1), (1, -1),
                  (2, 1), (1, 2), (-1, 2), (-2, 1), (-2, -1), (-1, -2), (1, -2), (2, -1)],
                 dtype=np.int64)
#: Slowest ground speed along a track that counts as progress, m s-1 (slower: impassable;
#: the steering speeds up to keep it, :func:`hold_speed`).
G_MIN = 0.05
#: Longest piece of a segment integrated with one current sample, in node spacings.
PIECE = 0.5


# ------------------------------------------------------------------------------ power model

class PowerModel(NamedTuple):
    """Electrical power of a vehicle: ``P(u) = hotel_w + k u^3`` W at ``u`` m/s through the
    water; ``battery_wh`` usable energy."""
    battery_wh: float
    hotel_w: float
    k: float          # propulsion coefficient, W s3 m-3

    def power(self, u):
        """The electrical power ``P(u) = hotel_w + k u^3``.

        Parameters
        ----------
        u : float or array_like
            Speed through the water, m s-1.

        Returns
        -------
        float64 or ndarray
            Power, W (the shape of ``u``).
        """
        return self.hotel_w + self.k * libm.power(u, 3.0)

    @property
    def range_speed(self) -> float:
        """The maximum-range speed: least energy per metre in still water, m s-1."""
        return (self.hotel_w / (2.0 * self.k)) ** (1.0 / 3.0)


def briefing_power(hotel_w: float, pk: float) -> PowerModel | None:
    """The power model a briefing gives (``hotel_w``, ``pk``; no battery: energy per metre
    only), or None when it gives none (both 0).

    Parameters
    ----------
    hotel_w : float
        Hotel load, W.
    pk : float
        Propulsion coefficient, W s3 m-3.

    Returns
    -------
    PowerModel or None
    """
    return None if hotel_w <= 0.0 and pk <= 0.0 else PowerModel(1.0, hotel_w, pk)


def power_model(vehicle: str, path: str | Path | None = None) -> PowerModel:
    """The :class:`PowerModel` of a vehicle.

    Parameters
    ----------
    vehicle : str
        Vehicle name (a key of the ``power:`` section).
    path : str or Path, optional
        The vehicle file; default ``data/vehicles.yaml``
        (:func:`oneocean.engine.dynamics.vehicles_file`).

    Returns
    -------
    PowerModel
        Cached per file version.

    Raises
    ------
    ConfigError
        If the file cannot be read, has no power model for ``vehicle``, or one of its values
        is not a number > 0.
    """
    f = Path(path) if path is not None else vehicles_file()
    try:
        mtime = f.stat().st_mtime_ns
    except OSError as exc:
        raise ConfigError(f"{f}: cannot read vehicle file ({exc.strerror})") from None
    return _power_model(vehicle, str(f), mtime)


@lru_cache(maxsize=64)
def _power_model(vehicle: str, path: str, mtime: int) -> PowerModel:
    f = Path(path)
    doc = yaml.safe_load(f.read_text())
    entry = (doc.get("power") or {}).get(vehicle) if isinstance(doc, dict) else None
    if not isinstance(entry, dict):
        raise ConfigError(f"{f}: no power model for vehicle {vehicle!r} (section 'power')")
    vals = []
    for key in ("battery_wh", "hotel_w", "propulsion_w_s3_m3"):
        v = entry.get(key)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not v > 0:
            raise ConfigError(f"{f}: power.{vehicle}.{key} must be a number > 0, got {v!r}")
        vals.append(float(v))
    return PowerModel(*vals)


# ------------------------------------------------------------------------------ kernels

@hot_kernel
def _time_weights(times, t):
    n = times.shape[0]
    if n == 1 or t <= times[0]:
        return 0, 0, 0.0
    if t >= times[n - 1]:
        return n - 1, n - 1, 0.0
    i = 0
    while i < n - 2 and times[i + 1] <= t:
        i += 1
    return i, i + 1, (t - times[i]) / (times[i + 1] - times[i])


@hot_kernel
def _cell(nx, ny, x0, z0, h, x, z):
    fx = (x - x0) / h
    fz = (z - z0) / h
    if fx < 0.0:
        fx = 0.0
    elif fx > nx - 1:
        fx = float(nx - 1)
    if fz < 0.0:
        fz = 0.0
    elif fz > ny - 1:
        fz = float(ny - 1)
    i = min(int(fx), max(nx - 2, 0))
    j = min(int(fz), max(ny - 2, 0))
    return i, j, fx - i, fz - j


@hot_kernel
def _bil(a, i, j, wx, wz):
    ny, nx = a.shape[0], a.shape[1]
    i1 = min(i + 1, nx - 1)
    j1 = min(j + 1, ny - 1)
    return ((1.0 - wz) * ((1.0 - wx) * a[j, i] + wx * a[j, i1])
            + wz * ((1.0 - wx) * a[j1, i] + wx * a[j1, i1]))


@hot_kernel
def _bil4(cur, t, c, i, j, wx, wz):
    ny, nx = cur.shape[1], cur.shape[2]
    i1 = min(i + 1, nx - 1)
    j1 = min(j + 1, ny - 1)
    return ((1.0 - wz) * ((1.0 - wx) * cur[t, j, i, c] + wx * cur[t, j, i1, c])
            + wz * ((1.0 - wx) * cur[t, j1, i, c] + wx * cur[t, j1, i1, c]))


@hot_kernel
def _current(cur, times, x0, z0, h, x, z, t):
    """Current (east, north) at (x, z) and time t: bilinear between nodes, linear in time."""
    ny, nx = cur.shape[1], cur.shape[2]
    i, j, wx, wz = _cell(nx, ny, x0, z0, h, x, z)
    t0, t1, wt = _time_weights(times, t)
    ce = (1.0 - wt) * _bil4(cur, t0, 0, i, j, wx, wz) + wt * _bil4(cur, t1, 0, i, j, wx, wz)
    cn = (1.0 - wt) * _bil4(cur, t0, 1, i, j, wx, wz) + wt * _bil4(cur, t1, 1, i, j, wx, wz)
    return ce, cn


@hot_kernel
def _free(free, x0, z0, h, x, z):
    """Passability margin at (x, z) (> 0: passable); -1 outside the lattice."""
    ny, nx = free.shape
    if x < x0 or z < z0 or x > x0 + (nx - 1) * h or z > z0 + (ny - 1) * h:
        return -1.0
    i, j, wx, wz = _cell(nx, ny, x0, z0, h, x, z)
    return _bil(free, i, j, wx, wz)


@njit(cache=True)
def ground_speed(ce, cn, ux, uz, u):
    """Crab-steering ground speed along a unit direction in a current.

    Parameters
    ----------
    ce, cn : float
        Current (east, north), m s-1.
    ux, uz : float
        Unit track direction (x, z).
    u : float
        Speed through the water, m s-1.

    Returns
    -------
    float
        Ground speed along the track, m s-1 (``c_par + sqrt(u^2 - c_perp^2)``); -1 when the
        cross current reaches ``u``.
    """
    c_par = ce * ux + cn * uz
    qx = ce - c_par * ux
    qz = cn - c_par * uz
    q2 = qx * qx + qz * qz
    if q2 >= u * u:
        return -1.0
    return c_par + math.sqrt(u * u - q2)


@hot_kernel
def _piece(ce, cn, ux, uz, L, speeds, ph, pk, hold):
    """The best speed over a piece of length ``L`` along (ux, uz) in the current (ce, cn):
    (time s, cost, speed index); cost = time when ``ph == pk == 0``, else the energy
    ``(ph + pk u^3) * time`` J; the fastest (time) or most frugal (energy) speed whose cross
    current leaves ``hold`` m/s to spare and whose ground speed exceeds G_MIN; (inf, inf, -1)
    when there is none. Ties go to the earlier speed."""
    c_par = ce * ux + cn * uz
    qx = ce - c_par * ux
    qz = cn - c_par * uz
    q2 = qx * qx + qz * qz
    q = math.sqrt(q2)
    energy = ph > 0.0 or pk > 0.0
    best_c = math.inf
    best_t = math.inf
    best_i = -1
    for s in range(speeds.shape[0]):
        u = speeds[s]
        if u - q < hold or q2 >= u * u:
            continue
        g = c_par + math.sqrt(u * u - q2)
        if not g > G_MIN:
            continue
        dt = L / g
        c = (ph + pk * u * u * u) * dt if energy else dt
        if c < best_c:
            best_c = c
            best_t = dt
            best_i = s
    return best_t, best_c, best_i


@hot_kernel
def _n_pieces(L, step):
    n = int(math.ceil(L / step))
    return 1 if n < 1 else n


@hot_kernel
def _segment(cur, times, free, x0, z0, h, ax, az, bx, bz, speeds, ph, pk, hold, t, step,
             check_start, out_speed):
    """Arrival time and cost of the straight segment a -> b leaving at time t (inf, inf when
    impassable), integrated in ``_n_pieces(L, step)`` equal pieces, each flown at its own best
    speed (:func:`_piece`) with the current at the piece's middle at the time the vehicle
    starts it; each piece's speed index into ``out_speed[:n]`` when it is long enough."""
    dx = bx - ax
    dz = bz - az
    L = math.sqrt(dx * dx + dz * dz)
    if L <= 0.0:
        return t, 0.0
    ux = dx / L
    uz = dz / L
    n = _n_pieces(L, step)
    if check_start and not _free(free, x0, z0, h, ax, az) > 0.0:
        return math.inf, math.inf
    cost = 0.0
    for p in range(n):
        s0 = L * p / n
        s1 = L * (p + 1) / n
        sm = 0.5 * (s0 + s1)
        mx = ax + sm * ux
        mz = az + sm * uz
        if not (_free(free, x0, z0, h, mx, mz) > 0.0
                and _free(free, x0, z0, h, ax + s1 * ux, az + s1 * uz) > 0.0):
            return math.inf, math.inf
        ce, cn = _current(cur, times, x0, z0, h, mx, mz, t)
        dt, c, si = _piece(ce, cn, ux, uz, s1 - s0, speeds, ph, pk, hold)
        if si < 0:
            return math.inf, math.inf
        if out_speed.shape[0] >= n:
            out_speed[p] = si
        t += dt
        cost += c
    return t, cost


@hot_kernel
def _heap_push(hc, hn, size, c, n):
    """Push (c, n) on the binary min-heap ``hc``/``hn`` of ``size`` entries (ordered on
    (cost, node), as heapq orders the tuples); returns the new size (capacity: the caller's)."""
    k = size
    while k > 0:
        p = (k - 1) >> 1
        pc = hc[p]
        if pc < c or (pc == c and hn[p] < n):
            break
        hc[k] = pc
        hn[k] = hn[p]
        k = p
    hc[k] = c
    hn[k] = n
    return size + 1


@hot_kernel
def _heap_pop(hc, hn, size):
    """Remove the root of the heap of ``size`` entries; returns the new size."""
    size -= 1
    if size == 0:
        return 0
    c = hc[size]
    n = hn[size]
    k = 0
    while True:
        a = 2 * k + 1
        if a >= size:
            break
        b = a + 1
        if b < size and (hc[b] < hc[a] or (hc[b] == hc[a] and hn[b] < hn[a])):
            a = b
        if c < hc[a] or (c == hc[a] and n < hn[a]):
            break
        hc[k] = hc[a]
        hn[k] = hn[a]
        k = a
    hc[k] = c
    hn[k] = n
    return size


@njit(cache=True)
def _local_cmax(cur, reach):
    """(ny, nx): the fastest current speed (over every time) at the nodes within ``reach``
    cells of each node (the window ``i - reach .. i + reach + 1``, clamped): every current
    an edge of at most ``reach`` cells from the node interpolates is no faster. inf where
    that window holds a current that is not finite."""
    nt, ny, nx = cur.shape[0], cur.shape[1], cur.shape[2]
    node = np.zeros((ny, nx))
    for t in range(nt):
        for j in range(ny):
            for i in range(nx):
                ce = cur[t, j, i, 0]
                cn = cur[t, j, i, 1]
                s2 = ce * ce + cn * cn
                if not math.isfinite(s2):
                    node[j, i] = math.inf
                elif s2 > node[j, i]:
                    node[j, i] = s2
    row = np.empty((ny, nx))
    for j in range(ny):
        for i in range(nx):
            m = 0.0
            for a in range(max(i - reach, 0), min(i + reach + 2, nx)):
                if node[j, a] > m:
                    m = node[j, a]
            row[j, i] = m
    out = np.empty((ny, nx))
    for j in range(ny):
        for i in range(nx):
            m = 0.0
            for b in range(max(j - reach, 0), min(j + reach + 2, ny)):
                if row[b, i] > m:
                    m = row[b, i]
            out[j, i] = math.sqrt(m)
    return out


@hot_kernel
def _cost_rate(cmax, speeds, ph, pk):
    """A lower bound of the cost per metre of a piece where no current is faster than
    ``cmax``: the ground speed is at most ``cmax + u``, so ``min_u P(u) / (cmax + u)``
    (``P = 1`` for time), less 1e-6 of it for round-off; 0 when ``cmax`` is not finite."""
    if not math.isfinite(cmax):
        return 0.0
    energy = ph > 0.0 or pk > 0.0
    rate = math.inf
    for s in range(speeds.shape[0]):
        u = speeds[s]
        r = ((ph + pk * u * u * u) if energy else 1.0) / (cmax + u)
        if r < rate:
            rate = r
    if not (math.isfinite(rate) and rate > 0.0):
        return 0.0
    return (1.0 - 1e-6) * rate


@njit(cache=True)
def _dijkstra(cur, times, free, x0, z0, h, sx, sz, gx, gz, speeds, ph, pk, hold, t0, step,
              edges):
    """Time-dependent Dijkstra (cost: time or energy, time carried along) from the point s to
    the point g over the node lattice, directed by A*'s consistent estimate of the cost to g
    (Dijkstra's route and cost; fewer nodes settled).

    Returns (cost (ny*nx,), arrival time (ny*nx,), parent (ny*nx,) node or -1 (= from s),
    goal_parent node (-1: s itself, -2: unreachable), goal cost, goal time); the labels of
    the nodes the search reached (inf, inf, -3 elsewhere)."""
    ny, nx = free.shape
    nn = ny * nx
    cost = np.full(nn, np.inf)
    tarr = np.full(nn, np.inf)
    parent = np.full(nn, -3, np.int64)
    done = np.zeros(nn, np.uint8)
    # lower bounds of the edges' costs: an edge whose bound cannot improve its end node's
    # cost is not integrated (the relaxation would not take it: the same search, bit for bit)
    reach = 0
    elen = np.empty(edges.shape[0])
    for k in range(edges.shape[0]):
        di = float(edges[k, 0])
        dj = float(edges[k, 1])
        elen[k] = h * math.sqrt(di * di + dj * dj)
        reach = max(reach, abs(edges[k, 0]), abs(edges[k, 1]))
    cloc = _local_cmax(cur, reach)
    rnode = np.empty(nn)
    cglob = 0.0
    for j in range(ny):
        for i in range(nx):
            rnode[j * nx + i] = _cost_rate(cloc[j, i], speeds, ph, pk)
            if not cloc[j, i] <= cglob:
                cglob = cloc[j, i]
    # the heap never outgrows this: a node is pushed at most once from the start (the
    # attached nodes lie in a 7 x 7 box) and once per edge from each settled node
    cap = nn * edges.shape[0] + 64
    hc = np.empty(cap)
    hn = np.empty(cap, np.int64)
    # A*'s estimate of each node's cost to g: its straight distance at the least cost per
    # metre anywhere on the lattice (no current there is faster than cloc's largest). No
    # edge costs less than its length at that rate, so the estimate is consistent: every
    # node a cheaper route to g can use is settled with Dijkstra's label (its least cost
    # and that route's time; an exact tie of two costs may go to the other parent), and the
    # nodes that cannot lead to g cheaper than the best so far are never expanded
    hb = np.empty(nn)
    grate = _cost_rate(cglob, speeds, ph, pk)
    for j in range(ny):
        for i in range(nx):
            dx = x0 + i * h - gx
            dz = z0 + j * h - gz
            hb[j * nx + i] = grate * math.sqrt(dx * dx + dz * dz)
    gp, bc, bt = _search(cur, times, free, x0, z0, h, sx, sz, gx, gz, speeds, ph, pk, hold,
                         t0, step, edges, elen, rnode, hb, cost, tarr, parent, done, hc,
                         hn, np.empty(0, np.int64))
    return cost, tarr, parent, gp, bc, bt


@hot_kernel   # no reference counting: its helpers get 4-5 arrays on every relaxation
def _search(cur, times, free, x0, z0, h, sx, sz, gx, gz, speeds, ph, pk, hold, t0, step,
            edges, elen, rnode, hb, cost, tarr, parent, done, hc, hn, nos):
    """:func:`_dijkstra`'s search on its allocated arrays (``cost``, ``tarr``, ``parent``
    at their initial values, ``done`` zero, the heap ``hc``/``hn`` large enough for every
    push): returns the goal's parent node, cost and time."""
    ny, nx = free.shape
    r_att = 2.3 * h
    bt, bc = _segment(cur, times, free, x0, z0, h, sx, sz, gx, gz, speeds, ph, pk, hold, t0,
                      step, True, nos)
    goal_parent = -1 if math.isfinite(bc) else -2
    # binary min-heap on (cost, node), lazy deletion: the keys are distinct (a node is pushed
    # again only with a strictly smaller cost), so it pops in the order heapq did
    size = 0
    # the start attaches to the nodes around it
    i_lo = max(int(math.floor((sx - x0) / h - 2.3)), 0)
    i_hi = min(int(math.ceil((sx - x0) / h + 2.3)), nx - 1)
    j_lo = max(int(math.floor((sz - z0) / h - 2.3)), 0)
    j_hi = min(int(math.ceil((sz - z0) / h + 2.3)), ny - 1)
    for j in range(j_lo, j_hi + 1):
        for i in range(i_lo, i_hi + 1):
            px = x0 + i * h
            pz = z0 + j * h
            if (px - sx) ** 2 + (pz - sz) ** 2 > r_att * r_att or not free[j, i] > 0.0:
                continue
            ta, ca = _segment(cur, times, free, x0, z0, h, sx, sz, px, pz, speeds, ph, pk,
                              hold, t0, step, True, nos)
            n = j * nx + i
            if ca < cost[n]:
                cost[n] = ca
                tarr[n] = ta
                parent[n] = -1
                size = _heap_push(hc, hn, size, ca + hb[n], n)
    while size > 0:
        f = hc[0]
        n = hn[0]
        size = _heap_pop(hc, hn, size)
        if done[n] == 1:
            continue
        if f >= bc:
            break
        c = cost[n]
        done[n] = 1
        i = n % nx
        j = n // nx
        px = x0 + i * h
        pz = z0 + j * h
        t = tarr[n]
        if (px - gx) ** 2 + (pz - gz) ** 2 <= r_att * r_att:
            tg, cg = _segment(cur, times, free, x0, z0, h, px, pz, gx, gz, speeds, ph, pk,
                              hold, t, step, False, nos)
            if c + cg < bc:
                bc = c + cg
                bt = tg
                goal_parent = n
        rate = rnode[n]
        for k in range(edges.shape[0]):
            ii = i + edges[k, 0]
            jj = j + edges[k, 1]
            if ii < 0 or jj < 0 or ii >= nx or jj >= ny:
                continue
            m = jj * nx + ii
            if done[m] == 1 or not free[jj, ii] > 0.0:
                continue
            # the edge's lower bound: it cannot improve m, or no route through m can beat
            # the best to g so far (m would never be expanded): not integrated
            lb = c + rate * elen[k]
            if lb >= cost[m] or lb + hb[m] >= bc:
                continue
            tm, cm = _segment(cur, times, free, x0, z0, h, px, pz, x0 + ii * h, z0 + jj * h,
                              speeds, ph, pk, hold, t, step, False, nos)
            if c + cm < cost[m]:
                cost[m] = c + cm
                tarr[m] = tm
                parent[m] = n
                size = _heap_push(hc, hn, size, c + cm + hb[m], m)
    return goal_parent, bc, bt


@njit(cache=True)
def _pull(cur, times, free, x0, z0, h, path, cum, tarr, speeds, ph, pk, hold, step):
    """String pulling: from each kept vertex jump to the farthest later vertex whose direct
    segment is passable and costs no more than the path between them (``cum``: the path's
    cumulative cost, ``tarr`` its times). Returns the kept vertex indices."""
    n = path.shape[0]
    keep = np.empty(n, np.int64)
    nos = np.empty(0, np.int64)
    keep[0] = 0
    m = 1
    a = 0
    ta = tarr[0]
    ca = cum[0]
    while a < n - 1:
        nxt = a + 1
        tn, cn_ = _segment(cur, times, free, x0, z0, h, path[a, 0], path[a, 1],
                           path[a + 1, 0], path[a + 1, 1], speeds, ph, pk, hold, ta, step,
                           False, nos)
        cn_ = ca + cn_
        for b in range(n - 1, a + 1, -1):
            tb, cb = _segment(cur, times, free, x0, z0, h, path[a, 0], path[a, 1], path[b, 0],
                              path[b, 1], speeds, ph, pk, hold, ta, step, False, nos)
            if ca + cb <= cum[b]:
                nxt = b
                tn = tb
                cn_ = ca + cb
                break
        keep[m] = nxt
        m += 1
        a = nxt
        ta = tn
        ca = cn_
    return keep[:m]


@njit(cache=True)
def _schedule(cur, times, free, x0, z0, h, path, speeds, ph, pk, hold, t0, step, out_xy,
              out_s, out_t):
    """Fly the polyline ``path``: every segment split into ``_n_pieces(L, step)`` pieces,
    each at its best speed. Writes the pieces' end points (out_xy[1:]), speed indices
    (out_s) and arrival times (out_t); returns (number of vertices, cost) (cost inf from the
    first impassable piece on)."""
    out_xy[0, 0] = path[0, 0]
    out_xy[0, 1] = path[0, 1]
    out_t[0] = t0
    t = t0
    cost = 0.0
    m = 1
    idx = np.empty(out_s.shape[0], np.int64)
    for k in range(1, path.shape[0]):
        ax = path[k - 1, 0]
        az = path[k - 1, 1]
        bx = path[k, 0]
        bz = path[k, 1]
        L = math.sqrt((bx - ax) ** 2 + (bz - az) ** 2)
        if L <= 0.0:
            continue
        n = _n_pieces(L, step)
        t1, c = _segment(cur, times, free, x0, z0, h, ax, az, bx, bz, speeds, ph, pk, hold,
                         t, step, k == 1, idx)
        if not math.isfinite(c):
            cost = math.inf
        for p in range(n):
            out_xy[m, 0] = ax + (bx - ax) * (p + 1) / n
            out_xy[m, 1] = az + (bz - az) * (p + 1) / n
            out_s[m - 1] = idx[p] if math.isfinite(c) else -1
            m += 1
        # times of the pieces: re-integrate (the segment only returns its end)
        if math.isfinite(c):
            tt = t
            ux = (bx - ax) / L
            uz = (bz - az) / L
            for p in range(n):
                s0 = L * p / n
                s1 = L * (p + 1) / n
                sm = 0.5 * (s0 + s1)
                ce, cn = _current(cur, times, x0, z0, h, ax + sm * ux, az + sm * uz, tt)
                g = ground_speed(ce, cn, ux, uz, speeds[idx[p]])
                tt += (s1 - s0) / g
                out_t[m - n + p] = tt
            t = t1
            cost += c
        else:
            for p in range(n):
                out_t[m - n + p] = math.inf
            t = math.inf
    return m, cost


@njit(cache=True)
def _map_forecast(cur, fc, e, out):
    for t in range(cur.shape[0]):
        for j in range(cur.shape[1]):
            for i in range(cur.shape[2]):
                fe, fn = forecast(fc, e, cur[t, j, i, 0], cur[t, j, i, 1])
                out[t, j, i, 0] = fe
                out[t, j, i, 1] = fn
    return out


# ------------------------------------------------------------------------------ planning

class Route(NamedTuple):
    """A planned route: ``path`` (n, 2) vertices (x east, z north) m from start to goal,
    ``speed`` (n - 1,) the through-water speed of every segment m/s, ``t`` (n,) planned
    arrival times s, ``cost`` the planned time (s) or energy (J) from start to goal, ``ok``
    False when no passable route was found (then the straight line, ``speed`` the slowest
    speed, ``t[1:]`` and ``cost`` inf)."""
    path: np.ndarray
    speed: np.ndarray
    t: np.ndarray
    cost: float
    ok: bool


def _arrays(cur, times, free):
    cur = np.ascontiguousarray(cur, dtype=np.float64)
    times = np.ascontiguousarray(times, dtype=np.float64).reshape(-1)
    free = np.ascontiguousarray(free, dtype=np.float64)
    if cur.ndim != 4 or cur.shape[3] != 2 or cur.shape[1:3] != free.shape \
            or cur.shape[0] != times.shape[0]:
        raise ValueError(f"routing: cur {cur.shape} must be (nt, ny, nx, 2) with free "
                         f"{free.shape} (ny, nx) and times {times.shape} (nt,)")
    return cur, times, free


def _speeds_power(speeds, power):
    sp = np.ascontiguousarray(np.atleast_1d(np.asarray(speeds, dtype=np.float64)))
    if sp.size == 0 or not np.all(sp > 0):
        raise ValueError(f"routing: speeds must be > 0, got {speeds!r}")
    if power is None:
        return sp, 0.0, 0.0
    ph, pk = (float(v) for v in power)
    if not (ph >= 0 and pk >= 0 and ph + pk > 0):
        raise ValueError(f"routing: power (hotel_w, k) must be >= 0, got {power!r}")
    return sp, ph, pk


def schedule(cur, times, free, x0: float, z0: float, h: float, path, speeds, t0: float, *,
             power=None, hold: float = 0.0, piece: float | None = None) -> Route:
    """Fly a fixed polyline: the best speed schedule along it.

    Every segment is split into equal pieces of at most ``piece`` m, each flown at its best
    speed of ``speeds`` (the fastest when ``power`` is None: cost = time; else the least
    energy) with the current where and when the vehicle gets there.

    Parameters
    ----------
    cur : (nt, ny, nx, 2) array_like
        The current (east, north) the planner knows at the lattice nodes, m s-1.
    times : (nt,) array_like
        Times of ``cur``, s, ascending.
    free : (ny, nx) array_like
        Passability margin (> 0: passable; :func:`plan_route`).
    x0, z0 : float
        World (x, z) of node (0, 0), m.
    h : float
        Node spacing, m.
    path : (n, 2) array_like
        The polyline's vertices (x, z), m.
    speeds : float or array_like
        Through-water speeds the vehicle may fly, m s-1.
    t0 : float
        Departure time, s.
    power : (hotel_w, k), optional
        None: cost = time; given: cost = energy, ``P(u) = hotel_w + k u^3`` W.
    hold : float
        Cross-current headroom a track needs, m s-1 (:func:`plan_route`).
    piece : float, optional
        Longest piece flown at one speed, m (default ``PIECE * h``).

    Returns
    -------
    Route
        One vertex per piece end (collinear pieces at the same speed merged); ``ok`` False and
        ``cost`` inf when a piece is impassable.

    Raises
    ------
    ValueError
        Inconsistent array shapes, a speed <= 0 or a negative power coefficient.
    """
    cur, times, free = _arrays(cur, times, free)
    sp, ph, pk = _speeds_power(speeds, power)
    p = np.ascontiguousarray(np.asarray(path, dtype=np.float64).reshape(-1, 2))
    step = float(piece) if piece is not None else PIECE * float(h)
    L = np.hypot(*np.diff(p, axis=0).T)
    n_max = 1 + int(sum(math.ceil(x / step) + 1 for x in L))   # an upper bound
    xy = np.empty((n_max, 2))
    si = np.empty(max(n_max - 1, 1), np.int64)
    tt = np.empty(n_max)
    m, cost = _schedule(cur, times, free, float(x0), float(z0), float(h), p, sp, ph, pk,
                        float(hold), float(t0), step, xy, si, tt)
    ok = bool(math.isfinite(cost))
    spd = np.where(si[:m - 1] >= 0, sp[np.maximum(si[:m - 1], 0)], sp.min())
    return _merge(Route(xy[:m].copy(), spd, tt[:m].copy(), float(cost), ok))


def _merge(r: Route) -> Route:
    """Drop the interior vertices between collinear pieces flown at the same speed."""
    n = r.path.shape[0]
    if n <= 2:
        return r
    keep = [0]
    for k in range(1, n - 1):
        a, b, c = r.path[keep[-1]], r.path[k], r.path[k + 1]
        d1, d2 = b - a, c - b
        cross = d1[0] * d2[1] - d1[1] * d2[0]
        same_dir = abs(cross) <= 1e-9 * (np.hypot(*d1) * np.hypot(*d2) + 1e-300) \
            and d1[0] * d2[0] + d1[1] * d2[1] > 0
        if not (same_dir and r.speed[k - 1] == r.speed[k]):
            keep.append(k)
    keep.append(n - 1)
    keep = np.array(keep)
    return Route(r.path[keep], r.speed[keep[:-1]], r.t[keep], r.cost, r.ok)


def plan_route(cur, times, free, x0: float, z0: float, h: float, start, goal, speeds,
               t0: float, *, power=None, hold: float = 0.0, piece: float | None = None
               ) -> Route:
    """The best route from ``start`` to ``goal`` leaving at ``t0``.

    Parameters
    ----------
    cur : (nt, ny, nx, 2) float64
        The current (east, north) m/s the planner knows at node ``(j, i)``, world
        ``(x0 + i h, z0 + j h)``, at ``times`` (nt,) s ascending.
    times : (nt,) float64
        Times of ``cur``, s, ascending (sampled linearly, clamped outside).
    free : (ny, nx) float64
        Passability margin: the vehicle may be where its bilinear interpolation is > 0
        (land, too shallow water and anything else forbidden <= 0). Outside the lattice is
        impassable.
    x0, z0 : float
        World (x, z) of node (0, 0), m.
    h : float
        Node spacing, m (> 0).
    start, goal : (2,) array_like
        Start and goal (x, z), m.
    speeds : float or array
        Through-water speeds the vehicle may fly, m/s (one: the fixed-speed problem).
    t0 : float
        Departure time, s.
    power : (hotel_w, k), optional
        None: the time-optimal route (each piece at the fastest feasible speed). Given: the
        least-energy route and speed schedule, ``P(u) = hotel_w + k u^3`` W.
    hold : float
        Cross-current headroom a track needs: a speed ``u`` is feasible on a piece only if
        ``u - |c_perp| >= hold`` m/s (and the ground speed exceeds ``G_MIN``).
    piece : float
        Longest piece flown at one speed and integrated with one current sample, m
        (default ``PIECE * h``).

    Returns
    -------
    Route
        Its ``path`` is the string-pulled lattice path re-scheduled piece by piece
        (:func:`schedule`); deterministic (bit for bit) on every CPU. No passable route:
        ``ok`` False (see :class:`Route`).

    Raises
    ------
    ValueError
        Inconsistent array shapes, ``h <= 0``, a speed <= 0 or a negative power coefficient.
    """
    cur, times, free = _arrays(cur, times, free)
    sp, ph, pk = _speeds_power(speeds, power)
    if not h > 0:
        raise ValueError("plan_route: h must be > 0")
    step = float(piece) if piece is not None else PIECE * float(h)
    sx, sz = (float(v) for v in start)
    gx, gz = (float(v) for v in goal)
    cost, tarr, parent, gp, bc, bt = _dijkstra(cur, times, free, float(x0), float(z0),
                                               float(h), sx, sz, gx, gz, sp, ph, pk,
                                               float(hold), float(t0), step, EDGES)
    if gp == -2:
        return Route(np.array([[sx, sz], [gx, gz]]), sp.min(keepdims=True),
                     np.array([float(t0), math.inf]), math.inf, False)
    nodes = []
    n = gp
    while n >= 0:
        nodes.append(n)
        n = parent[n]
    nodes.reverse()
    nx = free.shape[1]
    pts = [(sx, sz)] + [(x0 + (m % nx) * h, z0 + (m // nx) * h) for m in nodes] + [(gx, gz)]
    path = np.array(pts, dtype=np.float64)
    idx = np.array(nodes, dtype=np.int64)
    cum = np.concatenate([[0.0], cost[idx], [bc]])
    tt = np.concatenate([[float(t0)], tarr[idx], [bt]])
    keep = _pull(cur, times, free, float(x0), float(z0), float(h), path, cum, tt, sp, ph, pk,
                 float(hold), step)
    return schedule(cur, times, free, x0, z0, h, path[keep], sp, t0, power=power, hold=hold,
                    piece=step)


def route_cost(cur, times, free, x0: float, z0: float, h: float, path, speeds, t0: float, *,
               power=None, hold: float = 0.0, piece: float | None = None) -> float:
    """The planned cost of flying a fixed polyline (:func:`schedule`), e.g. the straight line.

    Parameters
    ----------
    cur : (nt, ny, nx, 2) array_like
        The current (east, north) the planner knows at the lattice nodes, m s-1.
    times : (nt,) array_like
        Times of ``cur``, s, ascending.
    free : (ny, nx) array_like
        Passability margin (> 0: passable; :func:`plan_route`).
    x0, z0 : float
        World (x, z) of node (0, 0), m.
    h : float
        Node spacing, m.
    path : (n, 2) array_like
        The polyline's vertices (x, z), m.
    speeds : float or array_like
        Through-water speeds the vehicle may fly, m s-1.
    t0 : float
        Departure time, s.
    power : (hotel_w, k), optional
        None: cost = time; given: cost = energy, ``P(u) = hotel_w + k u^3`` W.
    hold : float
        Cross-current headroom a track needs, m s-1 (:func:`plan_route`).
    piece : float, optional
        Longest piece flown at one speed, m (default ``PIECE * h``).

    Returns
    -------
    float
        Time (s, ``power`` None) or energy (J); inf when impassable.
    """
    return schedule(cur, times, free, x0, z0, h, path, speeds, t0, power=power, hold=hold,
                    piece=piece).cost


# ------------------------------------------------------------------------------ the field

class Lattice(NamedTuple):
    """A planning lattice over a window of the grid: node ``(j, i)`` is world
    ``(x0 + i h, z0 + j h)``."""
    x0: float
    z0: float
    h: float
    nx: int
    ny: int


def lattice(grid, points, pad: float, h: float) -> Lattice:
    """The planning lattice covering some points, clipped to the grid's extent.

    Parameters
    ----------
    grid : Grid
        The grid export.
    points : (n, 2) array_like
        Points (x, z), m.
    pad : float
        Margin around the points' bounding box, m.
    h : float
        Node spacing, m.

    Returns
    -------
    Lattice
        At least 2 x 2 nodes.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    xl = max(float(p[:, 0].min()) - pad, grid.x0)
    xh = min(float(p[:, 0].max()) + pad, grid.x_max)
    zl = max(float(p[:, 1].min()) - pad, grid.z0)
    zh = min(float(p[:, 1].max()) + pad, grid.z_max)
    nx = max(2, int(math.floor((xh - xl) / h)) + 1)
    ny = max(2, int(math.floor((zh - zl) / h)) + 1)
    return Lattice(xl, zl, float(h), nx, ny)


def field_times(grid, t0: float, duration: float) -> np.ndarray:
    """The grid's own time axis over an episode window: the planner's ``times``.

    On it the product's currents are linear in time.

    Parameters
    ----------
    grid : Grid
        The grid export.
    t0 : float
        Window start, s since the grid's ``time0``.
    duration : float
        Window length, s.

    Returns
    -------
    (nt,) float64
        The grid times in ``[t0, t0 + duration]`` plus the bracketing ones (the single time of
        a one-time grid).
    """
    ts = np.asarray(grid.time_s, dtype=np.float64)
    lo, hi = _time_window(ts, t0, duration)
    return ts[lo:hi + 1].copy()


def field_from_grid(grid, lat: Lattice, depth: float, times, clearance: float,
                    land_threshold: float = 0.5, land_margin: float = 0.1):
    """The true field on a planning lattice.

    Parameters
    ----------
    grid : Grid
        The grid export.
    lat : Lattice
        The planning lattice.
    depth : float
        Depth of the plan, m (positive down).
    times : (nt,) array_like
        Sample times, s since the grid's ``time0`` (:func:`field_times`).
    clearance : float
        Seafloor clearance below ``depth``, m.
    land_threshold : float
        Land-mask threshold.
    land_margin : float
        Margin below ``land_threshold`` that still counts as land.

    Returns
    -------
    cur : (nt, ny, nx, 2) float64
        :func:`oneocean.engine.grid.sample_currents` at every node at ``depth`` and every time
        of ``times``, m s-1.
    free : (ny, nx) float64
        The smaller of the water depth below ``depth + clearance`` (m) and
        ``(land_threshold - land_margin - land) * h`` (land and shallows <= 0).
    """
    times = np.ascontiguousarray(times, dtype=np.float64).reshape(-1)
    cur = np.empty((times.size, lat.ny, lat.nx, 2))
    free = np.empty((lat.ny, lat.nx))
    _fill_field(grid, float(lat.x0), float(lat.z0), float(lat.h), float(depth),
                _time_places(grid, times), float(clearance), float(land_threshold),
                float(land_margin), cur, free)
    return cur, free


@njit(cache=True)
def _time_places(grid, times):
    """:func:`_fill_field`'s ``tloc`` (nt, 5): ``(t0, t1, wt)`` of each of ``times`` on the
    grid's axis (:func:`~oneocean.engine.grid.locate_time`) and its synthetic tide
    ``(te, tn)``."""
    tloc = np.empty((times.shape[0], 5))
    for n in range(times.shape[0]):
        t0, t1, wt = locate_time(grid, times[n])
        te, tn = synthetic_tide(grid, times[n])
        tloc[n, 0] = t0
        tloc[n, 1] = t1
        tloc[n, 2] = wt
        tloc[n, 3] = te
        tloc[n, 4] = tn
    return tloc


@hot_kernel   # no reference counting: the grid's arrays are read at every node
def _fill_field(grid, x0, z0, h, depth, tloc, clearance, land_threshold, land_margin, cur,
                free):
    """:func:`field_from_grid` into ``cur`` (nt, ny, nx, 2) and ``free`` (ny, nx): node
    ``(j, i)`` at ``(x0 + i h, z0 + j h)`` at the times located in ``tloc``
    (:func:`_time_places`), every value as the engine's vectorised samplers give it
    (``sample_currents``, ``sample_elevation_points``, ``np.minimum``). Each node is located
    once and each of its time slabs read once (the next time's interval starts where this
    one's ends): the same blends as ``sample_current``, bit for bit."""
    ny, nx = free.shape
    nt = tloc.shape[0]
    for j in range(ny):
        z = z0 + j * h
        for i in range(nx):
            ci, cj, k0, k1, wk, a00, a10, a01, a11 = point_cell(grid, x0 + i * h, depth, z)
            pi = -1                     # the time index of the slab (pu, pv, put, pvt)
            pu = pv = put = pvt = 0.0
            for n in range(nt):
                t0 = int(tloc[n, 0])
                t1 = int(tloc[n, 1])
                wt = tloc[n, 2]
                if t0 == pi:
                    u0, v0, ut0, vt0 = pu, pv, put, pvt
                else:
                    u0, v0, ut0, vt0 = time_slab(grid, t0, ci, cj, k0, k1, wk, a00, a10,
                                                 a01, a11)
                if t1 == t0:
                    u1, v1, ut1, vt1 = u0, v0, ut0, vt0
                elif t1 == pi:
                    u1, v1, ut1, vt1 = pu, pv, put, pvt
                else:
                    u1, v1, ut1, vt1 = time_slab(grid, t1, ci, cj, k0, k1, wk, a00, a10,
                                                 a01, a11)
                pi = t1
                pu, pv, put, pvt = u1, v1, ut1, vt1
                cur[n, j, i, 0] = current_from_parts(grid, wt, u0, u1, ut0, ut1) + tloc[n, 3]
                cur[n, j, i, 1] = current_from_parts(grid, wt, v0, v1, vt0, vt1) + tloc[n, 4]
    dc = depth + clearance
    lm = land_threshold - land_margin
    for j in range(ny):
        z = z0 + j * h
        for i in range(nx):
            x = x0 + i * h
            a = -sample_elevation(grid, x, z) - dc
            b = (lm - sample_land(grid, x, z)) * h
            free[j, i] = a if (a <= b or a != a) else b


@njit(cache=True)
def _land_points(grid, xz, out):
    for n in range(xz.shape[0]):
        out[n] = sample_land(grid, xz[n, 0], xz[n, 1])
    return out


def forecast_field(cur, fc, e: int) -> np.ndarray:
    """A field as a vehicle carrying the forecast sees it: what it plans on.

    Parameters
    ----------
    cur : (nt, ny, nx, 2) array_like
        The true field, m s-1.
    fc : (E, 5) array_like
        Forecast-error models (``LoopState.fc``).
    e : int
        Episode index.

    Returns
    -------
    (nt, ny, nx, 2) float64
        ``cur`` mapped through episode ``e``'s forecast-error model
        (:func:`oneocean.sensing.kernels.forecast` at every node and time), m s-1.
    """
    cur = np.ascontiguousarray(cur, dtype=np.float64)
    return _map_forecast(cur, np.ascontiguousarray(fc, dtype=np.float64), int(e),
                         np.empty_like(cur))


# ------------------------------------------------------------------------------ missions

#: Slowest through-water speed a transit mission programs, m/s (fins keep authority above
#: it), and the step of the programmed speeds up to the vehicle's speed limit.
SPEED_MIN = 0.75
SPEED_STEP = 0.25
#: Cross-current headroom a track keeps, m/s: a leg is flown at least this much faster than
#: the current across it (the plan's constraint and the steering's rule alike).
HOLD_MS = 0.1
#: Slowest ground speed a vehicle accepts along its track, m/s (the steering speeds up to
#: keep it: it is never swept backwards while it has speed in hand); the plans' G_MIN.
G_MIN_MS = G_MIN
#: Longest stretch flown at one programmed speed, m.
PIECE_M = 100.0


def mission_speeds(v_max: float) -> np.ndarray:
    """The speeds a mission may program.

    Parameters
    ----------
    v_max : float
        The vehicle's speed limit, m s-1.

    Returns
    -------
    float64 ndarray
        ``SPEED_MIN`` .. ``v_max`` in ``SPEED_STEP`` steps (and ``v_max``), m s-1; only
        ``v_max`` when it is at most ``SPEED_MIN``.
    """
    v = float(v_max)
    if v <= SPEED_MIN:
        return np.array([v])
    s = np.arange(SPEED_MIN, v + 1e-9, SPEED_STEP)
    return s if abs(s[-1] - v) <= 1e-9 else np.append(s, v)


def cruise_speed(v_max: float, power: PowerModel | None) -> float:
    """The programmed speed of a vehicle flying one speed.

    Parameters
    ----------
    v_max : float
        The vehicle's speed limit, m s-1.
    power : PowerModel or None
        Its power model.

    Returns
    -------
    float
        The mission speed (:func:`mission_speeds`) nearest its maximum-range speed
        (:attr:`PowerModel.range_speed`); ``v_max`` without a power model, m s-1.
    """
    s = mission_speeds(v_max)
    if power is None:
        return float(s[-1])
    return float(s[int(np.argmin(np.abs(s - power.range_speed)))])


def lattice_spacing(length: float) -> float:
    """Node spacing of the planning lattice for a route.

    Parameters
    ----------
    length : float
        Route length, m.

    Returns
    -------
    float
        ``length / 40`` clipped to 50-200 m (the product's own spacing is 100-250 m).
    """
    return float(min(max(float(length) / 40.0, 50.0), 200.0))


class MissionField(NamedTuple):
    """The current field a plan is made on: a planning lattice at one depth over an episode's
    window (:func:`mission_field`), the truth or a forecast of it."""
    cur: np.ndarray     # (nt, ny, nx, 2) float64 current at every node and time (e, n), m s-1
    times: np.ndarray   # (nt,) float64 its times, s since the grid's time0
    free: np.ndarray    # (ny, nx) float64 passability (> 0: water at the depth, m)
    x0: float           # lattice origin east, m
    z0: float           # lattice origin north, m
    h: float            # node spacing, m


def mission_field(grid, points, depth: float, t0: float, duration: float, *,
                  fixed: bool = False, fc=None, e: int = 0, clearance: float = 5.0,
                  land_threshold: float = 0.5) -> MissionField:
    """The field a mission through ``points`` is planned on: the truth sampled on a lattice
    around the points (:func:`lattice`, :func:`field_from_grid` over ``[t0, t0 + duration]``),
    or, given ``fc``, episode ``e``'s forecast of it (:func:`forecast_field`). A task's
    briefing carries it (the forecast for every non-oracle method, the truth for the oracle).

    Parameters
    ----------
    grid : Grid
        The grid export.
    points : (n, 2) array_like
        (x, z) m: the start and goal of a transit (``fixed=False``), or a route's vertices
        (``fixed=True``: a narrower margin, the route is flown as given).
    depth : float
        Depth of the plan, m (positive down).
    t0, duration : float
        Departure time (s since the grid's ``time0``) and length of the window, s.
    fixed : bool
        Whether the route is fixed (see ``points``).
    fc : (E, 5) array_like, optional
        Forecast-error models (``LoopState.fc``); None: the truth.
    e : int
        Episode index into ``fc``.
    clearance : float
        Seafloor clearance below ``depth``, m.
    land_threshold : float
        Land-mask threshold.

    Returns
    -------
    MissionField
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    length = float(np.hypot(*np.diff(pts, axis=0).T).sum())
    h = lattice_spacing(length)
    lat = lattice(grid, pts, (200.0 if fixed else 0.25 * length + 300.0), h)
    times = field_times(grid, t0, duration)
    cur, free = field_from_grid(grid, lat, depth, times, clearance, land_threshold)
    if fc is not None:
        cur = forecast_field(cur, fc, e)
    return MissionField(cur, times, free, lat.x0, lat.z0, lat.h)


def plan_on_field(f: MissionField, points, t0: float, v_max: float,
                  power: PowerModel | None, *, fixed: bool = False) -> Route:
    """A vehicle's plan through the field ``f`` (:func:`mission_field`).

    Speeds: :func:`mission_speeds`; cross-current headroom ``HOLD_MS``; pieces of at most
    ``PIECE_M``.

    Parameters
    ----------
    f : MissionField
        The field the vehicle knows.
    points : (n, 2) array_like
        (x, z) m, as for :func:`mission_field`.
    t0 : float
        Departure time, s since the grid's ``time0``.
    v_max : float
        The vehicle's speed limit, m s-1.
    power : PowerModel or None
        Its power model (None: cost = time).
    fixed : bool
        False: the least-energy route and speed schedule (the fastest route at ``v_max``
        without a power model); True: the speed schedule along the fixed route.

    Returns
    -------
    Route
        The plan; ``cost`` in J with a power model, else s.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    speeds = mission_speeds(v_max)
    pw = None if power is None else (power.hotel_w, power.k)
    args = (f.cur, f.times, f.free, f.x0, f.z0, f.h)
    if fixed:
        return schedule(*args, pts, speeds, t0, power=pw, hold=HOLD_MS, piece=PIECE_M)
    return plan_route(*args, pts[0], pts[-1], speeds, t0, power=pw, hold=HOLD_MS,
                      piece=PIECE_M)


def plan_mission(grid, points, depth: float, t0: float, duration: float, v_max: float,
                 power: PowerModel | None, *, fixed: bool = False, fc=None, e: int = 0,
                 clearance: float = 5.0, land_threshold: float = 0.5) -> Route:
    """A vehicle's plan through the field of ``grid`` at one depth: :func:`plan_on_field` on
    :func:`mission_field`.

    Parameters
    ----------
    grid, points, depth, t0, duration, fixed, fc, e, clearance, land_threshold
        As for :func:`mission_field`.
    v_max, power
        As for :func:`plan_on_field`.

    Returns
    -------
    Route
        The plan; ``cost`` in J with a power model, else s.
    """
    f = mission_field(grid, points, depth, t0, duration, fixed=fixed, fc=fc, e=e,
                      clearance=clearance, land_threshold=land_threshold)
    return plan_on_field(f, points, t0, v_max, power, fixed=fixed)


#: A briefing's packed mission fields (:func:`pack_fields`): E-leading arrays, each
#: episode's field in the leading corner of the padded axes. name -> (shape, unit, meaning).
FIELD_DOCS = {
    "fc_cur": ("(E, nt, ny, nx, 2)", "m s-1", "the forecast current (east, north) at the "
               "mission's depth on a planning lattice over the episode's window, at the tier's "
               "forecast lead (the truth for the oracle): node (j, i) is world "
               "(fc_x0 + i fc_h, fc_z0 + j fc_h), time n is fc_times[n]"),
    "fc_times": ("(E, nt)", "s", "the field's times, since the product's time origin"),
    "fc_free": ("(E, ny, nx)", "m", "passability at the mission's depth: water below it minus "
                "the clearance (<= 0: land or too shallow), from the chart"),
    "fc_x0": ("(E,)", "m", "the lattice's origin east"),
    "fc_z0": ("(E,)", "m", "the lattice's origin north"),
    "fc_h": ("(E,)", "m", "the lattice's spacing"),
    "fc_shape": ("(E, 3)", "", "(nt, ny, nx) of each episode's field in the padded arrays "
                 "(zeros: none, the mission lies off the product)"),
}
FIELD_KEYS = tuple(FIELD_DOCS)
#: Vertex capacity of a stored plan (:func:`write_plan`).
MAX_VERTICES = 256


def pack_fields(fields) -> dict:
    """Every episode's :class:`MissionField` in padded E-leading arrays (a briefing's part).

    Parameters
    ----------
    fields : sequence of MissionField or None
        One per episode; None: no field (the mission's points lie off the grid).

    Returns
    -------
    dict
        :data:`FIELD_KEYS`: ``fc_cur`` (E, nt, ny, nx, 2) and ``fc_times`` (E, nt) float64,
        ``fc_free`` (E, ny, nx) float64, ``fc_x0`` / ``fc_z0`` / ``fc_h`` (E,) float64 (m), and
        ``fc_shape`` (E, 3) int64 ``(nt, ny, nx)`` of each episode's field (zeros: none).
    """
    n = len(fields)
    dims = np.array([f.cur.shape[:3] if f is not None else (0, 0, 0) for f in fields],
                    dtype=np.int64).reshape(n, 3)
    top = dims.max(axis=0) if n else np.zeros(3, np.int64)
    out = {"fc_cur": np.zeros((n, max(top[0], 1), max(top[1], 1), max(top[2], 1), 2)),
           "fc_times": np.zeros((n, max(top[0], 1))),
           "fc_free": np.zeros((n, max(top[1], 1), max(top[2], 1))),
           "fc_x0": np.zeros(n), "fc_z0": np.zeros(n), "fc_h": np.zeros(n), "fc_shape": dims}
    for e, f in enumerate(fields):
        if f is None:
            continue
        nt, ny, nx = dims[e]
        out["fc_cur"][e, :nt, :ny, :nx] = f.cur
        out["fc_times"][e, :nt] = f.times
        out["fc_free"][e, :ny, :nx] = f.free
        out["fc_x0"][e], out["fc_z0"][e], out["fc_h"][e] = f.x0, f.z0, f.h
    return out


def unpack_field(B, e: int) -> MissionField | None:
    """Episode ``e``'s :class:`MissionField` from a briefing that carries packed fields.

    Parameters
    ----------
    B : NamedTuple
        A briefing with the :data:`FIELD_KEYS` (:func:`pack_fields`).
    e : int
        Episode.

    Returns
    -------
    MissionField or None
        None where the episode has no field.
    """
    nt, ny, nx = (int(v) for v in B.fc_shape[e])
    if nt == 0:
        return None
    return MissionField(np.ascontiguousarray(B.fc_cur[e, :nt, :ny, :nx]),
                        np.ascontiguousarray(B.fc_times[e, :nt]),
                        np.ascontiguousarray(B.fc_free[e, :ny, :nx]),
                        float(B.fc_x0[e]), float(B.fc_z0[e]), float(B.fc_h[e]))


# ------------------------------------------------------------------------------ batched costs

@njit(cache=True)
def _path_cost(cur, times, free, x0, z0, h, path, speeds, ph, pk, hold, t0, step):
    """The cost of :func:`schedule` on ``path`` (the sum of its segments' costs, inf from
    the first impassable one), without the route."""
    nos = np.empty(0, np.int64)
    t = t0
    cost = 0.0
    for k in range(1, path.shape[0]):
        ax = path[k - 1, 0]
        az = path[k - 1, 1]
        bx = path[k, 0]
        bz = path[k, 1]
        L = math.sqrt((bx - ax) ** 2 + (bz - az) ** 2)
        if L <= 0.0:
            continue
        t1, c = _segment(cur, times, free, x0, z0, h, ax, az, bx, bz, speeds, ph, pk, hold,
                         t, step, k == 1, nos)
        if not math.isfinite(c):
            return math.inf
        t = t1
        cost += c
    return cost


@njit(cache=True)
def _route_cost(cur, times, free, x0, z0, h, sx, sz, gx, gz, speeds, ph, pk, hold, t0, step,
                edges):
    """The cost of :func:`plan_route` (Dijkstra, string pulling, the schedule of the pulled
    path), without the route."""
    cost, tarr, parent, gp, bc, bt = _dijkstra(cur, times, free, x0, z0, h, sx, sz, gx, gz,
                                               speeds, ph, pk, hold, t0, step, edges)
    if gp == -2:
        return math.inf
    nx = free.shape[1]
    cnt = 0
    n = gp
    while n >= 0:
        cnt += 1
        n = parent[n]
    path = np.empty((cnt + 2, 2))
    cum = np.empty(cnt + 2)
    tt = np.empty(cnt + 2)
    path[0, 0] = sx
    path[0, 1] = sz
    cum[0] = 0.0
    tt[0] = t0
    n = gp
    k = cnt
    while n >= 0:
        path[k, 0] = x0 + (n % nx) * h
        path[k, 1] = z0 + (n // nx) * h
        cum[k] = cost[n]
        tt[k] = tarr[n]
        k -= 1
        n = parent[n]
    path[cnt + 1, 0] = gx
    path[cnt + 1, 1] = gz
    cum[cnt + 1] = bc
    tt[cnt + 1] = bt
    keep = _pull(cur, times, free, x0, z0, h, path, cum, tt, speeds, ph, pk, hold, step)
    return _path_cost(cur, times, free, x0, z0, h, path[keep], speeds, ph, pk, hold, t0, step)


@njit(cache=True, nogil=True)
def _mission_costs(grid, ts, pts, npts, depth, t0, lat_f, lat_n, t_lo, t_hi, speeds, ph, pk,
                   hold, step, clearance, land_threshold, land_margin, fixed, edges, out, lo,
                   hi):
    for e in range(lo, hi):
        if npts[e] < 2:
            continue
        times = ts[t_lo[e]:t_hi[e] + 1].copy()
        nx = lat_n[e, 0]
        ny = lat_n[e, 1]
        x0 = lat_f[e, 0]
        z0 = lat_f[e, 1]
        h = lat_f[e, 2]
        cur = np.empty((times.shape[0], ny, nx, 2))
        free = np.empty((ny, nx))
        _fill_field(grid, x0, z0, h, depth[e], _time_places(grid, times), clearance,
                    land_threshold, land_margin, cur, free)
        m = npts[e]
        if fixed:
            out[e] = _path_cost(cur, times, free, x0, z0, h, pts[e, :m], speeds, ph, pk, hold,
                                t0[e], step)
        else:
            out[e] = _route_cost(cur, times, free, x0, z0, h, pts[e, 0, 0], pts[e, 0, 1],
                                 pts[e, m - 1, 0], pts[e, m - 1, 1], speeds, ph, pk, hold,
                                 t0[e], step, edges)


def _time_window(ts: np.ndarray, t0: float, duration: float) -> tuple[int, int]:
    """The index range ``lo .. hi`` of :func:`field_times` in the time axis ``ts``."""
    if ts.size == 1:
        return 0, 0
    lo = max(int(np.searchsorted(ts, t0, side="right")) - 1, 0)
    hi = min(int(np.searchsorted(ts, t0 + duration, side="left")), ts.size - 1)
    return lo, hi


def mission_costs(grid, routes, depths, t0s, duration: float, v_max: float,
                  power: PowerModel | None, *, fixed: bool = False, clearance: float = 5.0,
                  land_threshold: float = 0.5) -> np.ndarray:
    """The cost of :func:`plan_mission` for every episode, in one compiled call.

    ``plan_mission(grid, routes[e], depths[e], t0s[e], duration, v_max, power,
    fixed=fixed).cost`` of every episode ``e``, the same bits, with the episodes on
    :func:`oneocean.engine.dispatch.over_range`'s threads instead of one plan each.

    Parameters
    ----------
    grid : Grid
        The grid export.
    routes : (E, n, 2) array_like or sequence of (n_e, 2) arrays
        (x, z) m: the start and goal of a transit (``fixed=False``: the least-energy route's
        cost), or the fixed route's vertices (``fixed=True``: its best speed schedule's cost).
    depths : (E,) array_like
        Depth of each plan, m.
    t0s : (E,) array_like
        Departure times, s since the grid's ``time0``.
    duration : float
        Length of the field window, s.
    v_max : float
        The vehicle's speed limit, m s-1.
    power : PowerModel or None
        Its power model (None: cost = time).
    fixed : bool
        See ``routes``.
    clearance : float
        Seafloor clearance below the depth, m.
    land_threshold : float
        Land-mask threshold.

    Returns
    -------
    (E,) float64
        Costs, J (s without a power model); inf where a route has a point off the grid
        (:func:`within_grid`) or no passable route exists.
    """
    from ..engine.dispatch import over_range

    routes = [np.asarray(r, dtype=np.float64).reshape(-1, 2) for r in routes]
    n_ep = len(routes)
    n_max = max([r.shape[0] for r in routes], default=2)
    pts = np.zeros((n_ep, n_max, 2))
    npts = np.zeros(n_ep, np.int64)          # 0: not planned (inf)
    lat_f = np.ones((n_ep, 3))
    lat_n = np.full((n_ep, 2), 2, np.int64)
    t_lo = np.zeros(n_ep, np.int64)
    t_hi = np.zeros(n_ep, np.int64)
    depth = np.ascontiguousarray(depths, dtype=np.float64).reshape(-1)
    t0 = np.ascontiguousarray(t0s, dtype=np.float64).reshape(-1)
    ts = np.ascontiguousarray(grid.time_s, dtype=np.float64)
    for e, r in enumerate(routes):
        if not within_grid(grid, r):
            continue
        length = float(np.hypot(*np.diff(r, axis=0).T).sum())
        h = lattice_spacing(length)
        lat = lattice(grid, r, (200.0 if fixed else 0.25 * length + 300.0), h)
        lat_f[e] = lat.x0, lat.z0, lat.h
        lat_n[e] = lat.nx, lat.ny
        t_lo[e], t_hi[e] = _time_window(ts, float(t0[e]), float(duration))
        pts[e, :r.shape[0]] = r
        npts[e] = r.shape[0]
    out = np.full(n_ep, math.inf)
    speeds = np.ascontiguousarray(mission_speeds(v_max), dtype=np.float64)
    ph, pk = (0.0, 0.0) if power is None else (float(power.hotel_w), float(power.k))
    over_range(_mission_costs, 0, n_ep, grid, ts, pts, npts, depth, t0, lat_f, lat_n, t_lo,
               t_hi, speeds, ph, pk, float(HOLD_MS), float(PIECE_M), float(clearance),
               float(land_threshold), 0.1, bool(fixed), EDGES, out)
    return out


def within_grid(grid, points) -> bool:
    """Whether every point lies inside the grid's horizontal extent.

    Parameters
    ----------
    grid : Grid
        The grid export.
    points : (n, 2) array_like
        Points (x, z), m.

    Returns
    -------
    bool
        True if all points are inside (edges included).
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    return bool(np.all((p[:, 0] >= grid.x0) & (p[:, 0] <= grid.x_max)
                       & (p[:, 1] >= grid.z0) & (p[:, 1] <= grid.z_max)))


# ------------------------------------------------------------------------------ following

@hot_kernel
def follow_path(wps, wspd, wcount, widx, e, px, pz, look, capture, commit):
    """Line-of-sight following of episode ``e``'s planned polyline.

    The active segment ``widx[e]`` advances while the vehicle is within ``capture`` m of its
    end or its along-track position is within ``capture`` of the end (stored when
    ``commit``). The carrot is ``look`` m beyond the vehicle's projection on the active
    segment, along the polyline across straight vertices (where only the programmed speed
    changes) but never past a corner: a corner vertex (a waypoint, a turn of the route) is
    steered at until it is captured, so the vehicle visits it, and the carrot cannot pull it to
    a point whose projection never reaches the segment's end.

    Parameters
    ----------
    wps : (E, n_max, 2) float64
        Plan vertices (x, z), m (plan tokens, :func:`write_plan`).
    wspd : (E, n_max) float64
        Programmed through-water speed of each segment, m s-1.
    wcount : (E,) int64
        Vertices of each plan.
    widx : (E,) int64
        Active segment of each plan.
    e : int
        Episode index.
    px, pz : float
        Vehicle position (x, z), m.
    look : float
        Carrot lookahead, m.
    capture : float
        Capture radius of a segment's end, m.
    commit : int
        Non-zero: store the advanced segment in ``widx[e]``.

    Returns
    -------
    cx, cz : float
        The carrot, m.
    u : float
        The active segment's programmed speed, m s-1.
    """
    n = wcount[e]
    w = widx[e]
    while w < n - 2:
        ax_ = wps[e, w, 0]
        az_ = wps[e, w, 1]
        bx_ = wps[e, w + 1, 0]
        bz_ = wps[e, w + 1, 1]
        dx = bx_ - ax_
        dz = bz_ - az_
        L = math.sqrt(dx * dx + dz * dz)
        if (L > 1e-9 and ((px - ax_) * dx + (pz - az_) * dz) / L < L - capture
                and (px - bx_) ** 2 + (pz - bz_) ** 2 > capture * capture):
            break
        w += 1
    if commit != 0:
        widx[e] = w
    ax_ = wps[e, w, 0]
    az_ = wps[e, w, 1]
    dx = wps[e, w + 1, 0] - ax_
    dz = wps[e, w + 1, 1] - az_
    L = math.sqrt(dx * dx + dz * dz)
    along = 0.0
    if L > 1e-9:
        along = ((px - ax_) * dx + (pz - az_) * dz) / L
        if along < 0.0:
            along = 0.0
    rem = along + look
    k = w
    cx = wps[e, n - 1, 0]
    cz = wps[e, n - 1, 1]
    while k < n - 1:
        ax_ = wps[e, k, 0]
        az_ = wps[e, k, 1]
        dx = wps[e, k + 1, 0] - ax_
        dz = wps[e, k + 1, 1] - az_
        L = math.sqrt(dx * dx + dz * dz)
        if rem <= L:
            f = rem / L
            cx = ax_ + f * dx
            cz = az_ + f * dz
            break
        cx = wps[e, k + 1, 0]
        cz = wps[e, k + 1, 1]
        if k + 2 <= n - 1:   # spill over the vertex only where the polyline runs straight on
            ex = wps[e, k + 2, 0] - cx
            ez = wps[e, k + 2, 1] - cz
            M = math.sqrt(ex * ex + ez * ez)
            if abs(dx * ez - dz * ex) > 1e-6 * L * M or dx * ex + dz * ez <= 0.0:
                break
        rem -= L
        k += 1
    return cx, cz, wspd[e, w]


@hot_kernel
def hold_speed(u, dx, dz, ce, cn, v_max):
    """The through-water speed to fly toward a direction in a current.

    The programmed ``u``, raised (up to ``v_max``) so the cross current leaves ``HOLD_MS`` to
    spare and the ground speed along the track stays >= ``G_MIN_MS``.

    Parameters
    ----------
    u : float
        Programmed speed, m s-1.
    dx, dz : float
        Direction of travel (x, z), any length, m.
    ce, cn : float
        Current (east, north), m s-1.
    v_max : float
        The vehicle's speed limit, m s-1.

    Returns
    -------
    float
        Speed through the water, m s-1 (``u`` for a zero direction).
    """
    d = math.sqrt(dx * dx + dz * dz)
    if d <= 1e-9:
        return u
    ux = dx / d
    uz = dz / d
    c_par = ce * ux + cn * uz
    qx = ce - c_par * ux
    qz = cn - c_par * uz
    q2 = qx * qx + qz * qz
    need = math.sqrt(q2) + HOLD_MS
    if c_par < G_MIN_MS:
        n2 = math.sqrt(q2 + (G_MIN_MS - c_par) * (G_MIN_MS - c_par))
        if n2 > need:
            need = n2
    if need > u:
        u = need if need < v_max else v_max
    return u


def write_plan(route: Route, wps, wspd, wcount, widx, e: int) -> None:
    """Store a route as episode ``e``'s plan tokens (:func:`follow_path`).

    Parameters
    ----------
    route : Route
        The plan.
    wps : (E, n_max, 2) float64
        Plan vertices, written in place.
    wspd : (E, n_max) float64
        Programmed segment speeds, written in place.
    wcount : (E,) int64
        Vertex counts, written in place.
    widx : (E,) int64
        Active segments, reset to 0.
    e : int
        Episode index.

    Raises
    ------
    RuntimeError
        If the route has more vertices than ``wps`` holds.
    """
    n = route.path.shape[0]
    if n > wps.shape[1]:
        raise RuntimeError(f"plan of episode {e}: {n} vertices, the plan-token array holds "
                           f"{wps.shape[1]}")
    wps[e] = 0.0
    wps[e, :n] = route.path
    wspd[e] = 0.0
    wspd[e, :n - 1] = route.speed
    wcount[e] = n
    widx[e] = 0
