"""The kernels' compiled entry points (``fast_entry``): found once per argument types, and
always the version numba itself would dispatch to."""

from __future__ import annotations

from collections import namedtuple
from itertools import combinations

import numpy as np
import pytest
from numba import njit
from numba.core.typing.typeof import Purpose, typeof

from oneocean.engine.dispatch import _FAST, _Unkeyed, _type_key, fast_entry

Pair = namedtuple("Pair", "a b")
Other = namedtuple("Other", "a b")


def _values():
    """Arguments of every kind the loop passes, and their near misses."""
    a = np.zeros((3, 4))
    ro = a.copy()
    ro.flags.writeable = False
    return [
        a, np.zeros((3, 4), order="F"), a[:, ::2], ro, np.zeros(4), np.zeros((1, 4)),
        np.zeros(4, dtype=np.int64), np.zeros(4, dtype=np.uint8), np.zeros(4, dtype=np.float32),
        np.zeros((0, 3)),
        1, 2**40, 2**63, -5, True, False, 1.5, np.float64(1.5), np.int64(3), np.bool_(True),
        None, (1, 2), (1, 2.0), (1.0, 2.0), Pair(1, 2), Other(1, 2), Pair(a, 1.0),
        Pair(a[:, ::2], 1.0), ((1, 2), (a, ro)),
    ]


def test_equal_keys_mean_equal_numba_types():
    vals = _values()
    keys = [_type_key(v) for v in vals]
    types = [typeof(v, Purpose.argument) for v in vals]
    for (k1, t1), (k2, t2) in combinations(zip(keys, types), 2):
        if k1 == k2:
            assert t1 == t2
        if t1 != t2:
            assert k1 != k2
    # the near misses are told apart (layout, writeability, ndim, dtype, tuple class)
    assert len(set(keys[:9])) == 9
    assert keys[-5] != keys[-4] and keys[-3] != keys[-2]


def test_values_of_other_kinds_are_not_keyed():
    with pytest.raises(_Unkeyed):
        _type_key("text")
    with pytest.raises(_Unkeyed):
        _type_key((1, [2]))
    with pytest.raises(_Unkeyed):
        _type_key(np.ma.zeros(3))


@njit(cache=False)
def _add(x, p):
    return x.sum() + p.a + p.b


def test_the_entry_is_numbas_own_and_reused_per_argument_types():
    x = np.arange(6.0)
    p = Pair(1.0, 2)
    _add(x, p)
    _add(x[::2], p)
    _FAST.clear()
    e1 = fast_entry(_add, (x, p))
    sig = tuple(_add.typeof_pyval(v) for v in (x, p))
    assert e1 is _add.overloads[sig].entry_point
    assert e1(x, p) == 18.0
    # the same types (other values): the kept entry; other types: their own version
    assert fast_entry(_add, (np.ones(3), Pair(0.5, 7))) is e1
    e2 = fast_entry(_add, (x[::2], p))
    assert e2 is not e1 and e2(x[::2], p) == 9.0
    assert len(_FAST) == 2


def test_types_without_a_compiled_version_give_the_dispatcher_and_are_not_kept():
    _FAST.clear()
    assert fast_entry(_add, (np.zeros(3, dtype=np.int32), Pair(1, 1))) is _add
    assert not _FAST


@pytest.mark.parametrize("task", ["G2G", "PI", "SPC"])
def test_a_cells_batches_run_numbas_own_entries(task):
    """Every batch after the first takes its entry points from the cache: they are the ones
    numba resolves for that batch's arguments."""
    from oneocean.envs import OceanVectorEnv

    env = OceanVectorEnv(task, 1, None, num_envs=2, pool=1)
    for seed in (0, 1):
        env.reset(seed=seed)
        b = env._pools[-1].batch
        args = (b._args(), b._no_io, 0, 0, 1)
        sig = tuple(b.kern._kernel.typeof_pyval(a) for a in args)
        assert b._entries["run"] is b.kern._kernel.overloads[sig].entry_point
    env.close()
