"""The fused step's arguments read from their :class:`~oneocean.tasks.loop.StepArgs` without
counting references (``step_fields``): the same arrays and values as numba's own field
reads, the same steps, and no reference left behind."""

from __future__ import annotations

import gc
import sys
import weakref
from collections import namedtuple

import numpy as np
import pytest
from numba import njit

from oneocean.engine._jit import hot_kernel
from oneocean.envs import OceanVectorEnv
from oneocean.engine.dispatch import fast_entry
from oneocean.tasks.loop import BORROWED_FIELDS, STEP_FIELDS, Batch, StepArgs, step_fields

Inner = namedtuple("Inner", "u n")


def _toy_args():
    """A StepArgs of small arrays, scalars and tuples, each field told apart by its values."""
    vals = [Inner(np.arange(3.0) + 10 * f, f) if f % 3 == 0 else np.full(2, float(f))
            for f in range(len(STEP_FIELDS))]
    return vals, StepArgs(*vals)


@hot_kernel
def _read_borrowed(A, out):
    """Write a value of some fields into ``out`` and add 1 to the first element of two
    array fields (through the borrowed arrays)."""
    f = step_fields(A)
    out[0] = f[0].u[1] + f[0].n
    out[1] = f[1][0]
    f[1][0] += 1.0
    out[2] = f[13][0]
    f[13][0] += 1.0
    out[3] = f[6].u[2] + f[6].n
    out[4] = f[11][1]


@njit
def _read(A, out):
    """:func:`_read_borrowed` as a kernel module calls it (from a function that counts its
    reference to ``A``)."""
    _read_borrowed(A, out)


def test_the_fields_are_the_structs_own_arrays_and_values():
    assert BORROWED_FIELDS, "this numba's MemInfo layout was not found: fields by getattr"
    vals, A = _toy_args()
    out = np.zeros(5)
    _read(A, out)
    np.testing.assert_array_equal(out, [1.0, 1.0, 13.0, 68.0, 11.0])
    # the writes went to the arrays the caller gave (shared, not copied)
    assert vals[1][0] == 2.0 and vals[13][0] == 14.0 and vals[1][1] == 1.0


def test_no_reference_is_left_behind():
    vals = _toy_args()[0]
    arrays = (vals[1], vals[13], vals[0].u)
    before = [sys.getrefcount(v) for v in arrays]
    A = StepArgs(*vals)
    out = np.zeros(5)
    for _ in range(2000):
        _read(A, out)
    assert vals[1][0] == 1.0 + 2000.0 and out[1] == 2000.0
    del A
    gc.collect()
    # the struct gave back every array it held: none is held by a reference a read kept
    assert [sys.getrefcount(v) for v in arrays] == before


def _getattr_step(kern):
    """A kernel module's ``_step_boxed`` written with numba's own field reads (each
    array's reference counted), the baseline of the borrowed one."""
    inner = kern._kernel

    @njit(nogil=True)
    def boxed(A, io, k_stop, e_lo, e_hi):
        inner(Batch(A.grid, A.vp, A.LP, A.P, A.W, A.C, A.LS, A.t0, A.state, A.cmd, A.ext,
                    A.rec_o, A.rec_a, A.res), io, k_stop, e_lo, e_hi)

    return boxed


@pytest.mark.parametrize("task", ["G2G", "FT"])
def test_steps_equal_numbas_own_field_reads_bit_for_bit(task):
    envs = [OceanVectorEnv(task, 2, None, num_envs=3, autoreset_mode="disabled")
            for _ in range(2)]
    for env in envs:
        env.reset(seed=11)
    a0 = np.zeros(envs[0].action_space.shape)
    envs[0].step(a0)                         # builds the batch's step entry
    envs[1].step(a0)
    batch = envs[1]._pools[0].batch
    _, args = batch._entries["step"]
    boxed = _getattr_step(batch.kern)
    boxed(*args, batch._no_io, -1, 0, 0)    # compile on these types
    batch._entries["step"] = (fast_entry(boxed, args + (batch._no_io, -1, 0, 1)), args)
    rng = np.random.default_rng(5)
    for _ in range(150):
        a = rng.uniform(-1.0, 1.0, a0.shape) * envs[0].v_max
        got = [env.step(a) for env in envs]
        for x, y in zip(got[0][:4], got[1][:4]):
            np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    b0 = envs[0]._pools[0].batch
    for name in ("state", "res", "ext"):
        assert getattr(b0, name).tobytes() == getattr(batch, name).tobytes()
    assert b0.LS.k.tobytes() == batch.LS.k.tobytes() and int(b0.LS.k.min()) >= 50


def test_a_stepped_batch_is_freed_with_its_env():
    env = OceanVectorEnv("G2G", 2, None, num_envs=2, autoreset_mode="next_step")
    env.reset(seed=2)
    for _ in range(20):
        env.step(np.zeros(env.action_space.shape))
    batch = env._pools[0].batch
    assert batch._entries.get("step") is not None          # stepped by _step_boxed
    gone = [weakref.ref(batch.state), weakref.ref(batch.LS.k), weakref.ref(batch.C.O)]
    del batch
    env.close()
    del env
    gc.collect()
    assert [w() for w in gone] == [None, None, None]
