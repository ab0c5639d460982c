"""Execution backends of a rollout: the core (numba) and the MuJoCo scene backend."""
