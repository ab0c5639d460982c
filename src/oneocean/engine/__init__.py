"""Core backend engine: grid sampling, vehicle dynamics, constraints and the per-agent step.

Every rollout runs on the one episode loop of the task layer (:mod:`oneocean.tasks.loop`),
which moves agents with :func:`advance_agent`. Analytic grids for tests and benchmarks are in
:mod:`oneocean.testing`. See ``docs/contracts.md`` §5 for the API the task layer consumes.
"""

from . import status
from .constraints import (DEFAULT_CLEARANCE_M, DEFAULT_LAND_THRESHOLD, DEFAULT_R_COLL_M,
                          check_move, check_points, feasibility, is_feasible,
                          min_pairwise_distance, spawn_positions)
from .dynamics import (CMD_DIM, DOF3, DOF4, DOF6, KINEMATIC, PARAM_DIM, STATE_DIM, Vehicle,
                       clip_action, load_vehicle, make_cmd, model_id, new_state, step_agent)
from .grid import (Grid, current_coverage, current_defined, grid_metadata, hold_levels,
                   load_grid, sample_current, sample_current_at, sample_current_data,
                   synthetic_tide, locate_time, sample_currents, sample_elevation, sample_land,
                   with_forcing)
from .recording import read_metrics_meta, write_metrics
from .rng import episode_rng, hash64, normal, uniform01
from .step import advance_agent

__all__ = [
    "status", "Grid", "load_grid", "with_forcing",
    "grid_metadata", "sample_current", "sample_current_data", "sample_current_at",
    "locate_time", "synthetic_tide", "current_defined", "current_coverage", "hold_levels",
    "sample_currents", "sample_elevation", "sample_land",
    "check_move", "is_feasible", "check_points", "feasibility", "min_pairwise_distance",
    "spawn_positions", "DEFAULT_CLEARANCE_M", "DEFAULT_LAND_THRESHOLD", "DEFAULT_R_COLL_M",
    "KINEMATIC", "DOF3", "DOF4", "DOF6", "STATE_DIM", "CMD_DIM", "PARAM_DIM", "Vehicle",
    "load_vehicle", "model_id", "new_state", "make_cmd", "step_agent", "clip_action",
    "advance_agent", "write_metrics", "read_metrics_meta",
    "episode_rng", "hash64", "uniform01", "normal",
]

from . import _jit as _jit_mod  # noqa: E402
from .constraints import check_points as _any_kernel  # noqa: E402

_jit_mod.ensure_fresh_cache(_any_kernel, ("grid.", "constraints.", "dynamics.", "step.", "rng.",
                                          "reference.", "streams."))
