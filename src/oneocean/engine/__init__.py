"""Core backend engine: grid sampling, vehicle dynamics, constraints and batched rollouts.

See ``docs/contracts.md`` §5 for the API the task layer consumes.
"""

from . import status
from .constraints import (DEFAULT_CLEARANCE_M, DEFAULT_LAND_THRESHOLD, DEFAULT_R_COLL_M,
                          check_move, check_points, feasibility, is_feasible,
                          min_pairwise_distance, spawn_positions)
from .controllers import (GOAL, MLP, OPEN_LOOP, PLAN, Controller, compute_command,
                          drift_controller, goal_controller, mlp_controller,
                          open_loop_controller, pack_mlp, plan_controller)
from .dynamics import (CMD_DIM, DOF3, DOF4, DOF6, KINEMATIC, PARAM_DIM, STATE_DIM, Vehicle,
                       clip_action, load_vehicle, make_cmd, model_id, new_state, step_agent)
from .grid import (Grid, grid_metadata, load_grid, make_test_grid, sample_current,
                   sample_current_at, sample_current_data, synthetic_tide, locate_time,
                   sample_currents, sample_elevation, sample_land, uniform_grid, with_forcing)
from .recording import episode_metrics, write_metrics, write_trajectories
from .rng import episode_rng, hash64, normal, uniform01
from .rollout import Batch, init_batch, run

__all__ = [
    "status", "Grid", "load_grid", "make_test_grid", "uniform_grid", "with_forcing",
    "grid_metadata", "sample_current", "sample_current_data", "sample_current_at",
    "locate_time", "synthetic_tide",
    "sample_currents", "sample_elevation", "sample_land",
    "check_move", "is_feasible", "check_points", "feasibility", "min_pairwise_distance",
    "spawn_positions", "DEFAULT_CLEARANCE_M", "DEFAULT_LAND_THRESHOLD", "DEFAULT_R_COLL_M",
    "KINEMATIC", "DOF3", "DOF4", "DOF6", "STATE_DIM", "CMD_DIM", "PARAM_DIM", "Vehicle",
    "load_vehicle", "model_id", "new_state", "make_cmd", "step_agent", "clip_action",
    "Controller", "GOAL", "MLP", "PLAN", "OPEN_LOOP", "goal_controller", "drift_controller",
    "plan_controller", "open_loop_controller", "mlp_controller", "pack_mlp", "compute_command",
    "Batch", "init_batch", "run", "episode_metrics", "write_metrics", "write_trajectories",
    "episode_rng", "hash64", "uniform01", "normal",
]

from . import _jit as _jit_mod  # noqa: E402
from .rollout import _rollout_kernel as _any_kernel  # noqa: E402

_jit_mod.ensure_fresh_cache(_any_kernel, ("grid.", "constraints.", "dynamics.", "controllers.",
                                          "rng.", "rollout.", "reference."))
