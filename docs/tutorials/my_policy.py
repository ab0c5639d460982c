"""A tiny policy for the tutorials: head for the goal cue at a fixed speed through the water,
cancelling the current the vehicle believes it is in.

A policy maps a batch of observations ``obs`` (E, N, 14) to actions (E, N, 3): the desired
velocity through the water, world frame (x east, y down, z north), m s-1. The observation
fields are ``oneocean.tasks.common.OBS_FIELDS``: the goal cue (dx, dy, dz) in m, then the
current estimate (east, north) in m s-1, ...
"""

import numpy as np

SPEED = 1.5     # m/s through the water (the REMUS 100's limit is 2.5)


def act(obs):
    goal = obs[..., 0:3]
    dist = np.linalg.norm(goal, axis=-1, keepdims=True)
    v = SPEED * goal / np.maximum(dist, 1.0)    # slow down inside the last metre
    v[..., 0] -= obs[..., 3]                    # cancel the estimated eastward current
    v[..., 2] -= obs[..., 4]                    # and the northward one
    return v
