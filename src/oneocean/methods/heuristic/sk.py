"""SK heuristic and oracle: dynamic positioning on the station with current feed-forward.

A policy of the public view only (:class:`oneocean.tasks.loop.Ctx`): the briefing
(:class:`oneocean.tasks.sk.SKBriefing`: the station and its heading) and each step's
observation (the navigation estimate, depth, the current estimate).

Both: P-control (``KP``) to the station plus feed-forward of the observed current within the
vehicle's full speed budget ``|a| <= v_max`` (:func:`~oneocean.methods.steering.seek_max`),
heading commanded to the briefing's station heading. They differ in information only:
``heuristic`` feeds forward its current estimate and steers by its navigation estimate
(:mod:`oneocean.sensing`); ``oracle`` the true current and position. Neither can hold against
a current above ``v_max``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ...engine._jit import hot_kernel
from ...tasks.common import O_CE, O_CN, O_DEPTH, O_X, O_Z
from ...tasks.loop import noop_plan as plan  # noqa: F401  (no team-level decision
from ..steering import seek_max
from . import SENSING  # noqa: F401

#: Proportional position gain, s-1 (ground-speed request = KP * error, plus feed-forward).
KP = 0.4


class SKPolicy(NamedTuple):
    """Parameters ``M`` of the SK policy (the same for heuristic and oracle).

    Attributes
    ----------
    budget : float
        Speed budget through the water, m s-1 (the vehicle's ``v_max``).
    kp : float
        Position gain, s-1 (:data:`KP`).
    """
    budget: float   # speed budget through the water, m s-1
    kp: float       # position gain, s-1


class SKMemory(NamedTuple):
    """The method's memory ``H``: none (a stateless controller; one placeholder array)."""
    unused: np.ndarray      # (E,) float64


def params(method: str, B) -> SKPolicy:
    """The policy's params: the same for every method (they differ in information only).

    Returns
    -------
    SKPolicy
        Budget ``v_max`` and :data:`KP`.
    """
    return SKPolicy(float(B.v_max), KP)


def memory(B, M: SKPolicy) -> SKMemory:
    """A fresh memory (nothing to remember).

    Returns
    -------
    SKMemory
    """
    return SKMemory(np.zeros(B.t0.shape[0]))


@hot_kernel
def act(C, e, k, i):
    """Agent ``i``'s action: P-control to the station plus current feed-forward, station
    heading. Policy hook (:mod:`oneocean.tasks.loop`).

    Returns
    -------
    ax, ay, az : float
        Desired velocity relative to the water, world frame (x east, y down, z north), m s-1
        (:func:`~oneocean.methods.steering.seek_max`, ``|a| <= M.budget``).
    psi : float
        Commanded heading, rad: the briefing's station heading.
    """
    M = C.M
    o = C.O[e, i]
    g = C.B.station[e]
    ax, ay, az = seek_max(o[O_X], o[O_DEPTH], o[O_Z], g[0], g[1], g[2], M.budget, M.kp,
                          o[O_CE], o[O_CN])
    return ax, ay, az, C.B.heading[e]
