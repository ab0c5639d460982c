"""SK heuristic and oracle: dynamic positioning on the station with current feed-forward.

Both: P-control (``KP``) to the station plus feed-forward of the sensed current within the
vehicle's full speed budget ``|a| <= v_max`` (:func:`~oneocean.tasks.common.seek_max`), heading
commanded to the station heading. They differ in information only: ``heuristic`` feeds forward
its current estimate and steers by its navigation estimate (:mod:`oneocean.sensing`);
``oracle`` the true current and position. Neither can hold against a current above ``v_max``.
"""

from __future__ import annotations

from typing import NamedTuple

from ...engine._jit import hot_kernel
from ...tasks.common import seek_max
from ...tasks.loop import noop_plan as plan  # noqa: F401  (no team-level decision)
from . import SENSING  # noqa: F401

#: Proportional position gain, s-1 (ground-speed request = KP * error, plus feed-forward).
KP = 0.4


class SKPolicy(NamedTuple):
    budget: float   # speed budget through the water, m s-1
    kp: float       # position gain, s-1


def params(method: str, tier: dict, vehicle) -> SKPolicy:
    return SKPolicy(float(vehicle.v_max), KP)


@hot_kernel(inline="always")
def act(grid, P, W, M, state, e, k, i, t, pe, pn):
    s = state[e, i]
    g = W.station[e]
    ax, ay, az = seek_max(s[0], s[1], s[2], g[0], g[1], g[2], M.budget, M.kp, pe, pn)
    return ax, ay, az, W.heading[e]
