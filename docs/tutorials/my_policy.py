"""Example policies for the tutorials: what a method can do with the public view alone.

A policy gets the task's briefing at the start (``reset(briefing)``) and every agent's
observation each step (``act(observation)``, ``observation.agents`` (E, N, D): the fields of
``oneocean.tasks.common.OBS_FIELDS``, then the task's own), and returns the desired velocity
through the water (E, N, 3), world frame (x east, y down, z north), m/s (docs/policy.md).

``CueFollower`` seeks the task's cue -- the point the task's mission computer gives every
method: the goal, the station, the route ahead, the next survey line, the slot -- at a speed
from the briefing (the vehicle's most economical speed where it has a power model), slowing
in the last metres, cancelling the current it knows, and keeps clear of its nearest
teammates. One class for the three task families (navigation, sensing, coordination); the
families differ only in its defaults (``for_task``).

``act`` is the plainest form, a function of the agents' array alone: head for the cue at a
fixed speed and cancel the known current.
"""

import numpy as np

SPEED = 1.25     # m/s through the water (the REMUS 100's most economical speed)

# observation columns (oneocean.tasks.common.OBS_FIELDS)
CUE, CURRENT, MATES = slice(0, 3), slice(3, 5), slice(8, 14)


def act(obs):
    """Head for the cue at ``SPEED``, cancelling the estimated current."""
    goal = obs[..., CUE]
    dist = np.linalg.norm(goal, axis=-1, keepdims=True)
    v = SPEED * goal / np.maximum(dist, 1.0)    # slow down inside the last metre
    v[..., 0] -= obs[..., 3]                    # cancel the estimated eastward current
    v[..., 2] -= obs[..., 4]                    # and the northward one
    return v


class CueFollower:
    """Seek the task's cue, cancel the known current, keep clear of teammates.

    Parameters
    ----------
    gain : float
        Approach gain, s-1: the speed toward the cue is at most ``gain x distance``.
    separation : float
        Keep this far from the nearest teammates, m (0: do not).
    """

    def __init__(self, gain: float = 0.5, separation: float = 0.0):
        self.gain, self.separation = float(gain), float(separation)

    def reset(self, briefing):
        """The cruise speed from the briefing: where the mission allocates energy, the power
        model's most economical speed ``(hotel_w / 2 pk)^(1/3)`` (the least energy per metre
        in still water), else 90 % of the speed limit."""
        v_max = float(briefing.v_max)
        if np.isfinite(briefing.energy_allocation).any() and briefing.pk > 0.0:
            self.speed = min(v_max, (briefing.hotel_w / (2.0 * briefing.pk)) ** (1.0 / 3.0))
        else:
            self.speed = 0.9 * v_max
        self.v_max = v_max

    def act(self, observation):
        o = np.nan_to_num(observation.agents)
        cue = o[..., CUE]
        dist = np.linalg.norm(cue, axis=-1, keepdims=True)
        speed = np.minimum(self.speed, self.gain * dist)
        v = speed * cue / np.maximum(dist, 1e-9)
        if self.separation > 0.0:                   # push away from teammates too close
            mates = o[..., MATES].reshape(o.shape[:-1] + (3, 2))
            d = np.linalg.norm(mates, axis=-1, keepdims=True)
            near = (d > 1e-9) & (d < self.separation)
            push = np.where(near, -mates / np.maximum(d, 1e-9) * (self.separation - d), 0.0)
            push = self.gain * push.sum(axis=-2)
            v[..., 0] += push[..., 0]
            v[..., 2] += push[..., 1]
        v[..., 0] -= o[..., 3]                      # cancel the known current
        v[..., 2] -= o[..., 4]
        return v


def for_task(family: str) -> CueFollower:
    """The example controller of a task family (``oneocean.registry.task_spec(t).family``):
    the coordination tasks close their cue offset more gently (a slot cue leads the slot)
    and keep 4 m from their teammates."""
    if family == "coordination":
        return CueFollower(gain=0.3, separation=4.0)
    return CueFollower()
