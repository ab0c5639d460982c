"""The mission computer's waypoint geometry: the active waypoint of a route as the vehicle
knows it (:func:`nav_waypoint`), line-of-sight carrots on a leg (:func:`los_carrot`) and on a
lawnmower's waypoint list (:func:`waypoint_carrot`, its transit radius :data:`ARRIVE_M`), and a
point's projection on a depth profile's leg (:func:`profile_at`). The tasks build their cue
with it; the methods follow the same geometry from their navigation estimate.
"""

from __future__ import annotations

import math

from ..engine._jit import hot_kernel

#: Transit arrival radius of the lawnmower followers (:func:`waypoint_carrot`), m: wider than
#: the REMUS 100's 10 m turning diameter, so a torpedo never orbits its first waypoint.
ARRIVE_M = 12.0


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
