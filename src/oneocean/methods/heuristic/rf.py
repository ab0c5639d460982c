"""RF heuristic and oracle: line-of-sight route following with current feed-forward.

Both aim at the point ``LOOKAHEAD_M`` ahead of the agent's projection on the active leg
(clamped to the waypoint; the env's leg frame ``W.leg``, updated before every step) with
:func:`~oneocean.tasks.common.seek_max` (cross-track current fed forward first, P-control
``KP`` toward the point), both with the full ``v_max``. ``heuristic``: NOISY probed current.
``oracle``: exact current.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from ...engine._jit import hot_kernel
from ...tasks.common import seek_max
from ...tasks.loop import noop_plan as plan  # noqa: F401  (no team-level decision)
from . import SENSING  # noqa: F401

#: Line-of-sight lookahead distance along the active leg, m.
LOOKAHEAD_M = 20.0
#: Proportional gain toward the lookahead point, s-1 (saturates: full speed on the route).
KP = 0.5


class RFPolicy(NamedTuple):
    budget: float   # speed budget through the water, m s-1
    kp: float       # gain toward the lookahead point, s-1
    look: float     # lookahead along the active leg, m


def params(method: str, tier: dict, vehicle) -> RFPolicy:
    v_max = float(vehicle.v_max)
    return RFPolicy(v_max, KP, LOOKAHEAD_M)


@hot_kernel(inline="always")
def act(grid, P, W, M, state, e, k, i, t, pe, pn):
    s = state[e, i]
    g = W.leg[e]                    # along-track, tangent (x, y, z), leg length
    a0 = W.route[e, W.wp[e] - 1]
    sl = min(max(g[0], 0.0) + M.look, g[4])
    lx = a0[0] + sl * g[1]
    ly = a0[1] + sl * g[2]
    lz = a0[2] + sl * g[3]
    ax, ay, az = seek_max(s[0], s[1], s[2], lx, ly, lz, M.budget, M.kp, pe, pn)
    return ax, ay, az, math.nan
