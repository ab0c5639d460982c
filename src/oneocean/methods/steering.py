"""Steering laws: how a method turns a target point or a desired ground velocity into a
velocity request through the water under the current it knows (:func:`seek_max`,
:func:`steer`). Inlined into the fused policies; imports nothing from
:mod:`oneocean.tasks`.
"""

from __future__ import annotations

import math

from ..engine._jit import hot_kernel


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
