"""The per-agent step every rollout takes: clip the action, advance the dynamics, enforce
feasibility.

:func:`advance_agent` is the engine's one entry point for moving an agent; the episode loop
(:func:`oneocean.tasks.loop.run_episode`) calls it for every agent and step, so clipping to
``v_max`` (eq. 1's a_t), the energy proxy ``||a||^2 dt`` (eq. 7), the dynamics and the
rejection of infeasible moves (eq. 3: position kept, velocity zeroed, status code returned)
are identical across tasks and methods.
"""

from __future__ import annotations

from . import dynamics as dyn
from . import status as st
from .constraints import check_move
from ._jit import hot_kernel


@hot_kernel(inline="always")
def advance_agent(grid, model, vp, s, cmd, ce, cn, v_max, dt, land_threshold, clearance):
    """Clip the command, advance one agent one step and enforce feasibility, in place.

    Parameters
    ----------
    grid : Grid
        The grid export (:class:`oneocean.engine.grid.Grid`).
    model : int
        Dynamics model id (:func:`oneocean.engine.dynamics.model_id`).
    vp : (PARAM_DIM,) float64
        Vehicle parameters (:func:`oneocean.engine.dynamics.vehicle_params`).
    s : (STATE_DIM,) float64
        Agent state (see :mod:`oneocean.engine.dynamics`), modified in place.
    cmd : (CMD_DIM,) float64
        ``[ax, ay, az, psi_cmd, thrust]``: desired velocity relative to the water (world m s-1);
        clipped here to ``v_max`` (the executed action a_t is written back into ``cmd``).
    ce, cn : float
        True current at the agent (east, north), m s-1, frozen over the step.
    v_max : float
        Speed limit of the action, m s-1.
    dt : float
        Step, s.
    land_threshold : float
        Rejection threshold on the sampled land mask, 0..1
        (:func:`~oneocean.engine.constraints.check_move`).
    clearance : float
        Required distance above the seafloor, m.

    Returns
    -------
    energy : float
        ``||a_t||^2 dt`` of the clipped action (m2 s-1), 0 when thrust is off.
    code : int
        Status of the move (``OK`` or the rejection reason, :mod:`oneocean.engine.status`); a
        rejected move keeps the position and zeroes the velocity.
    """
    ax, ay, az = dyn.clip_action(cmd[0], cmd[1], cmd[2], v_max)
    cmd[0] = ax
    cmd[1] = ay
    cmd[2] = az
    e = (ax * ax + ay * ay + az * az) * dt if cmd[4] != 0.0 else 0.0
    px = s[0]
    py = s[1]
    pz = s[2]
    dyn.step_agent(model, vp, s, cmd, ce, cn, dt)
    code = check_move(grid, s[0], s[1], s[2], land_threshold, clearance)
    if code != st.OK:
        s[0] = px
        s[1] = py
        s[2] = pz
        for c in range(dyn.U, dyn.W + 1):
            s[c] = 0.0
        for c in range(dyn.VX, dyn.VZ + 1):
            s[c] = 0.0
    return e, code
