"""G2G heuristic and oracle: best-effort transit to the goal with current feed-forward.

Both spend the vehicle's full speed budget ``v_max`` through the water (no method is
throttled), compensating the sensed current by crabbing: the cross-track current is fed forward
first and the rest of the budget goes along the goal bearing, with P-control (``KP``) of the
approach (:func:`~oneocean.tasks.common.seek_max`). ``heuristic``: the NOISY local probe.
``oracle``: the exact current. They differ in information only.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from ...engine._jit import hot_kernel
from ...tasks.common import seek_max
from ...tasks.loop import noop_plan as plan  # noqa: F401  (no team-level decision)
from . import SENSING  # noqa: F401

#: Proportional gain of the approach (ground speed = min(KP * distance, cruise)), s-1.
KP = 0.5


class G2GPolicy(NamedTuple):
    budget: float   # speed budget through the water, m s-1
    kp: float       # approach gain, s-1


def params(method: str, tier: dict, vehicle) -> G2GPolicy:
    v_max = float(vehicle.v_max)
    return G2GPolicy(v_max, KP)


@hot_kernel(inline="always")
def act(grid, P, W, M, state, e, k, i, t, pe, pn):
    s = state[e, i]
    g = W.goal[e]
    ax, ay, az = seek_max(s[0], s[1], s[2], g[0], g[1], g[2], M.budget, M.kp, pe, pn)
    return ax, ay, az, math.nan
