"""The shared-memo block copy installed in numba's inliner (oneocean.engine._jit): an IR copy
made the inliner's way is a full, independent copy whose blocks share ONE copied scope, and
inlined kernels give the same results as without it."""

import os
import subprocess
import sys
import textwrap

from numba.core import inline_closurecall as icc
from numba.core import ir
from numba.core.compiler import run_frontend

from oneocean.engine import _jit


def _callee(a, b):
    c = a + b
    if c > 0:
        d = c * 2.0
    else:
        d = -c
    for i in range(3):
        d += i
    return d


def _copy_like_the_inliner(the_ir):
    """numba's ``InlineWorker.inline_ir.copy_ir``: ``FunctionIR.copy``, then each block
    through the inliner module's ``copy.deepcopy``."""
    out = the_ir.copy()
    out.blocks = {label: icc.copy.deepcopy(block) for label, block in the_ir.blocks.items()}
    return out


def test_blocks_of_one_copy_share_one_new_scope_and_copies_are_independent():
    assert _jit.INLINE_MEMO_SHARED and isinstance(icc.copy, _jit._BlockMemoCopy)
    original = run_frontend(_callee)
    assert len(original.blocks) > 3
    scope0 = next(iter(original.blocks.values())).scope
    a, b = _copy_like_the_inliner(original), _copy_like_the_inliner(original)
    for cp in (a, b):
        scopes = {id(blk.scope) for blk in cp.blocks.values()}
        assert len(scopes) == 1 and id(scope0) not in scopes        # one new scope per copy
        for label, blk in cp.blocks.items():
            assert blk is not original.blocks[label]
            assert [str(s) for s in blk.body] == [str(s) for s in original.blocks[label].body]
    sa = next(iter(a.blocks.values())).scope
    sb = next(iter(b.blocks.values())).scope
    assert sa is not sb
    # the inliner renames into the copy's scope: neither the original nor the other copy sees it
    sa.redefine("oneocean_inlined_probe", loc=ir.Loc("t", 1))
    assert "oneocean_inlined_probe" in sa.localvars._con
    assert "oneocean_inlined_probe" not in sb.localvars._con
    assert "oneocean_inlined_probe" not in scope0.localvars._con


def test_inlined_kernel_results_equal_without_the_shared_memo(tmp_path):
    code = textwrap.dedent("""
        import numpy as np
        from oneocean.engine._jit import INLINE_MEMO_SHARED, hot_kernel

        @hot_kernel(inline="always", cache=False)
        def step(x, k):
            y = x
            for _ in range(k):
                y = 0.5 * y + np.sin(y) / 3.0
            return y

        @hot_kernel(cache=False)
        def run(xs, out):
            for i in range(xs.size):
                out[i] = step(xs[i], 7) + step(-xs[i], 3)

        xs = np.linspace(-3.0, 3.0, 101)
        out = np.empty_like(xs)
        run(xs, out)
        print(INLINE_MEMO_SHARED, out.tobytes().hex())
    """)
    res = {}
    for flag in ("1", "0"):
        env = {**os.environ, "ONEOCEAN_NUMBA_INLINE_MEMO": flag,
               "NUMBA_CACHE_DIR": str(tmp_path / flag)}
        res[flag] = subprocess.run([sys.executable, "-c", code], capture_output=True,
                                   text=True, env=env, check=True).stdout.split()
    assert res["1"][0] == "True" and res["0"][0] == "False"
    assert res["1"][1] == res["0"][1]
