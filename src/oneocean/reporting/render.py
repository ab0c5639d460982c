"""A fast top-down picture of an episode for ``render_mode="rgb_array"`` (no plotting library).

:func:`topdown_rgb` rasterises the grid's nodes: water shaded by the surface current speed at
time ``t`` (dark blue = still, light cyan = the fastest current in view), land grey; every
agent a red square and its goal cue a green one. North is up.
"""

from __future__ import annotations

import numpy as np

LAND_RGB = np.array([150, 150, 150], dtype=np.float64)
STILL_RGB = np.array([10, 30, 90], dtype=np.float64)
FAST_RGB = np.array([120, 230, 255], dtype=np.float64)
AGENT_RGB = np.array([230, 40, 40], dtype=np.uint8)
GOAL_RGB = np.array([40, 220, 60], dtype=np.uint8)


def topdown_rgb(grid, positions, goal_offsets, t: float, size: int = 256) -> np.ndarray:
    """A top-down RGB view of ``grid`` at time ``t`` with the agents and their goal cues.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    positions : array_like
        (N, >=3) agent positions, world frame (x east, y down, z north), m; only columns 0
        (x) and 2 (z) are used, e.g. the agents' state rows.
    goal_offsets : array_like
        (N, 3) each agent's goal cue relative to it, m (NaN: none).
    t : float
        Time, s since the grid's ``time0_unix_s``; the currents are sampled at 0.5 m depth.
    size : int, default 256
        Target pixels along the longer side: each grid node is an integer
        ``max(1, size // max(nx, ny))`` pixels square.

    Returns
    -------
    numpy.ndarray
        (H, W, 3) uint8 image, north up.
    """
    from ..engine.grid import sample_currents

    nx, ny = int(grid.nx), int(grid.ny)
    xs = grid.x0 + grid.dx * np.arange(nx)
    zs = grid.z0 + grid.dz * np.arange(ny)
    X, Z = np.meshgrid(xs, zs)
    pts = np.column_stack([X.ravel(), np.full(X.size, 0.5), Z.ravel()])
    cur = sample_currents(grid, pts, np.full(X.size, float(t)))
    speed = np.hypot(cur[:, 0], cur[:, 1]).reshape(ny, nx)
    top = float(speed.max()) if speed.size and speed.max() > 0 else 1.0
    f = (speed / top)[..., None]
    img = STILL_RGB + f * (FAST_RGB - STILL_RGB)
    land = np.asarray(grid.land) >= 0.5
    img[land] = LAND_RGB
    img = img[::-1]                               # north up: row 0 is the northern edge
    scale = max(1, int(size // max(nx, ny)))
    img = np.repeat(np.repeat(img, scale, axis=0), scale, axis=1).astype(np.uint8)
    h, w = img.shape[:2]

    def mark(x, z, rgb):
        if not (np.isfinite(x) and np.isfinite(z)):
            return
        c = int(round((x - grid.x0) / grid.dx * scale))
        r = h - 1 - int(round((z - grid.z0) / grid.dz * scale))
        r0, r1 = max(0, r - 2), min(h, r + 3)
        c0, c1 = max(0, c - 2), min(w, c + 3)
        if r0 < r1 and c0 < c1:
            img[r0:r1, c0:c1] = rgb

    pos = np.asarray(positions, dtype=np.float64)
    goal = np.asarray(goal_offsets, dtype=np.float64)
    for i in range(pos.shape[0]):
        mark(pos[i, 0] + goal[i, 0], pos[i, 2] + goal[i, 2], GOAL_RGB)
    for i in range(pos.shape[0]):
        mark(pos[i, 0], pos[i, 2], AGENT_RGB)
    return img
