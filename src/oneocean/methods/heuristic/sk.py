"""SK heuristic and oracle: dynamic positioning on the station with current feed-forward.

``heuristic``: P-control (``KP``) to the station plus feed-forward of the NOISY probed current
with the cruise throttle cap ``|a| <= CRUISE_FRAC * v_max``
(:func:`~oneocean.tasks.common.seek_max`), heading commanded to the station heading. It cannot
hold against a current above its cruise speed, and the probe noise shakes it. ``oracle``: the
same controller with the exact current and the full ``v_max``.
"""

from __future__ import annotations

from typing import NamedTuple

from ...engine._jit import hot_kernel
from ...tasks.common import CRUISE_FRAC, seek_max
from ...tasks.loop import noop_plan as plan  # noqa: F401  (no team-level decision)
from . import SENSING  # noqa: F401

#: Proportional position gain, s-1 (ground-speed request = KP * error, plus feed-forward).
KP = 0.4


class SKPolicy(NamedTuple):
    budget: float   # speed budget through the water, m s-1
    kp: float       # position gain, s-1


def params(method: str, tier: dict, vehicle) -> SKPolicy:
    v_max = float(vehicle.v_max)
    return SKPolicy(CRUISE_FRAC * v_max if method == "heuristic" else v_max, KP)


@hot_kernel(inline="always")
def act(grid, P, W, M, state, e, k, i, t, pe, pn):
    s = state[e, i]
    g = W.station[e]
    ax, ay, az = seek_max(s[0], s[1], s[2], g[0], g[1], g[2], M.budget, M.kp, pe, pn)
    return ax, ay, az, W.heading[e]
