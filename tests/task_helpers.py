"""Assertions shared by the task-module tests (tests/test_task_*.py)."""

from __future__ import annotations

import numba


def assert_tier_table_monotone(table: dict) -> None:
    """Tiers 1, 2, 3; every parameter declared in ``harder`` (``up`` or ``down``) and
    monotone T1 -> T2 -> T3 in its declared direction; every tier sets exactly those."""
    tiers = table["tiers"]
    assert sorted(tiers) == [1, 2, 3]
    for key, way in table["harder"].items():
        assert way in ("up", "down")
        vals = [float(tiers[t][key]) for t in (1, 2, 3)]
        sign = 1.0 if way == "up" else -1.0
        assert all(sign * (b - a) >= 0 for a, b in zip(vals, vals[1:])), (key, vals)
    for t in (1, 2, 3):
        assert set(tiers[t]) == set(table["harder"]), t


def on_one_thread(fn, *args, **kwargs):
    """``fn(*args, **kwargs)`` with numba limited to one thread (restored afterwards)."""
    prev = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        return fn(*args, **kwargs)
    finally:
        numba.set_num_threads(prev)
