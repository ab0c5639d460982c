"""Environment models used by the tasks: pollution fields and a fish school.

Every kernel is an ``@numba.njit(cache=True)`` pure function of arrays and scalars, callable
from a task's own jitted rollout loop; the Python helpers (``make_*``, ``*_params``,
``init_school``) run on the orchestration side.
"""

from . import fish, pollution
from .fish import (FISH_PARAM_NAMES, fish_params, fraction_inside_circle, init_school,
                   school_centroid, school_spread, step_school)
from .pollution import (KIND_REACTION, KIND_TRACER, OPEN_ALL, centroid, emit, faces_from_centers,
                        field_params, make_spill, make_work, probe, remove_in_radius, step_field,
                        total_mass)

__all__ = [
    "fish", "pollution",
    "FISH_PARAM_NAMES", "fish_params", "fraction_inside_circle", "init_school",
    "school_centroid", "school_spread", "step_school",
    "KIND_REACTION", "KIND_TRACER", "OPEN_ALL", "centroid", "emit", "faces_from_centers",
    "field_params", "make_spill", "make_work", "probe", "remove_in_radius", "step_field",
    "total_mass",
]
