"""JIT decorator for the engine's hot kernels.

``hot_kernel`` is ``numba.njit`` with ``cache=True`` and two choices that matter for speed:

* ``_nrt=False``: no reference counting of array arguments. The hot kernels never allocate,
  and atomic incref/decref pairs on every array passed down the call chain (the grid alone holds
  15 arrays) cost more than the arithmetic they guard (measured: 17-37 ns vs 2-7 ns per O(1)
  axis lookup). Any attempt to allocate inside such a kernel fails at compile time.
  ``_nrt`` is a numba-internal option (stable in 0.59-0.68); if a numba upgrade drops it,
  removing it here only costs speed.
* ``error_model="numpy"``: float division by zero gives inf/NaN instead of raising, so no
  zero checks on every division; non-finite states are caught by
  :func:`oneocean.engine.constraints.check_move` (status NONFINITE).

No ``fastmath``: NaN tests must stay honest.

What is inlined (``inline="always"``, numba's IR inliner) and what is compiled on its own is
a trade between run time and compile time. numba passes a struct (the
:class:`~oneocean.engine.grid.Grid`: 15 arrays + 20 scalars, ~1 KB when flattened; a task's
params and work arrays) by value, so an out-of-line call copies it on every call (measured
~70 ns per ``sample_current`` call when not inlined); an inlined function is typed and lowered
again at every call site, so inlining a large function into many places multiplies the
compile. The rule:

* inlined: the engine's, the sensors' and the field models' small kernels
  (:mod:`oneocean.engine`, :mod:`oneocean.sensing`, :mod:`oneocean.models`), the loop's
  phases (:mod:`oneocean.tasks.loop`), the shared observation helpers
  (:mod:`oneocean.tasks.common`), waypoint geometry (:mod:`oneocean.tasks.waypoints`) and
  steering laws (:mod:`oneocean.methods.steering`), the resets' samplers
  (:mod:`oneocean.tasks.spawn`) and the learned policy's forward pass: called per agent-step
  (or per draw) in the innermost loops;
* compiled once each, out of line: a task's hooks and helpers (``tasks/<task>.py``), its
  policy's (``methods/heuristic/<task>.py``) and the route planner (:mod:`oneocean.tasks.routing`),
  except where the measured throughput asked otherwise (UPL's ``cue``, ``after_agent`` and
  its heuristic's ``act``, whose out-of-line calls cost 15 % of UPL's agent-steps).

Measured with ``benchmarks/compile.py`` and ``benchmarks/tasks_speed.py`` (``docs/benchmarks.md``).
"""

from __future__ import annotations

import copy as _copy
import os as _os

from numba import njit


def hot_kernel(*args, **kwargs):
    """``numba.njit(cache=True, _nrt=False, error_model="numpy")``, plus ``kwargs``.

    Use bare (``@hot_kernel``) or with arguments (``@hot_kernel(inline="always")``).

    Parameters
    ----------
    *args
        The function to compile (bare use), or positional arguments of ``numba.njit`` (e.g.
        explicit signatures).
    **kwargs
        Options of ``numba.njit``; they override the defaults above.

    Returns
    -------
    numba.core.registry.CPUDispatcher or callable
        The compiled function (bare use), else a decorator.
    """
    opts = dict(cache=True, _nrt=False, error_model="numpy")
    opts.update(kwargs)
    if args and callable(args[0]) and len(args) == 1:
        return njit(**opts)(args[0])
    return njit(*args, **opts)


# ------------------------------------------------------------------- compile time of inlining
#
# numba's IR inliner (``inline="always"``, which every task kernel relies on) copies the
# callee's IR block by block, ``copy.deepcopy(block)`` with a fresh memo per block. Every
# variable deep-copies its scope, and the scope holds every variable of the function, so each
# block copy re-copies the whole scope: quadratic in the function's size (numba issue #8989,
# open). In the task kernels this was over 60 % of the compile time (profiled: 26 of 41 s for
# G2G). ``_share_block_memo`` makes the blocks of one copy share one memo, as a single
# ``deepcopy`` of the whole IR would: one copy of the scope per IR copy instead of one per
# block. Same IR, same machine code: every rollout cell, the BC dataset and weights, the
# planning cells and the tables were byte-identical with and without it; compiles
# were ~2x faster. It touches only the copy the inliner makes (its ``copy`` module attribute
# and ``FunctionIR.copy``, which starts each copy); if numba's internals differ, or
# ``ONEOCEAN_NUMBA_INLINE_MEMO=0``, nothing is changed and compiles are just slower.

_INLINE_MEMOS: dict = {}


class _BlockMemoCopy:
    """Stands in for the ``copy`` module inside ``numba.core.inline_closurecall``: a block
    copied without a memo gets the memo shared by the blocks of the same scope, reset at the
    start of every IR copy (``FunctionIR.copy``)."""

    copy = staticmethod(_copy.copy)

    def __init__(self, block_type):
        self._block = block_type

    def deepcopy(self, x, memo=None):
        if memo is None and isinstance(x, self._block):
            memo = _INLINE_MEMOS.setdefault(id(x.scope), {})
        return _copy.deepcopy(x, memo)


def _share_block_memo() -> bool:
    """Install the shared-memo block copy in numba's inliner; False if not applied."""
    if _os.environ.get("ONEOCEAN_NUMBA_INLINE_MEMO", "1") == "0":
        return False
    try:
        from numba.core import inline_closurecall as icc
        from numba.core import ir
    except ImportError:
        return False
    if isinstance(getattr(icc, "copy", None), _BlockMemoCopy):
        return True
    if getattr(icc, "copy", None) is not _copy or not hasattr(ir.FunctionIR, "copy"):
        return False
    original = ir.FunctionIR.copy

    def copy_ir(self):
        _INLINE_MEMOS.clear()
        return original(self)

    copy_ir.__wrapped__ = original
    ir.FunctionIR.copy = copy_ir
    icc.copy = _BlockMemoCopy(ir.Block)
    return True


INLINE_MEMO_SHARED = _share_block_memo()


# ----------------------------------------------------------------------------- cache hygiene
#
# numba keys a cached function on its own source file's timestamp only. Engine kernels are
# inlined into (and linked with) kernels of other modules, so editing dynamics.py would leave
# a cached kernel that inlines it (a task's episode loop) running the old dynamics.
# ``ensure_fresh_cache`` therefore fingerprints the engine sources and drops this package's
# cache entries when it changes.

import hashlib  # noqa: E402
import os  # noqa: E402
from pathlib import Path  # noqa: E402

_ENGINE_DIR = Path(__file__).resolve().parent
_MARKER = "oneocean-engine.fingerprint"


def source_fingerprint(*paths: Path) -> str:
    """Fingerprint of the engine's sources, further sources and the numba version.

    Parameters
    ----------
    *paths : path-like
        Further files, or folders of ``.py`` files, the cached kernels depend on.

    Returns
    -------
    str
        sha256 hex digest over the engine's ``.py`` files, ``paths`` and ``numba.__version__``.
    """
    import numba

    h = hashlib.sha256(numba.__version__.encode())
    for p in (_ENGINE_DIR, *map(Path, paths)):
        for f in (sorted(p.glob("*.py")) if p.is_dir() else [p]):
            h.update(f.name.encode())
            h.update(f.read_bytes())
    return h.hexdigest()


def cache_dir_of(dispatcher) -> Path | None:
    """Directory where numba caches ``dispatcher``.

    Parameters
    ----------
    dispatcher : numba dispatcher
        A function compiled with ``cache=True``.

    Returns
    -------
    pathlib.Path or None
        The cache directory; None if caching is off.
    """
    cache = getattr(dispatcher, "_cache", None)
    path = getattr(cache, "_cache_path", None)
    return Path(path) if path else None


def ensure_fresh_cache(dispatcher, module_prefixes: tuple[str, ...], *sources: Path) -> bool:
    """Remove stale numba cache files of ``module_prefixes`` next to ``dispatcher``'s cache.

    Call at import time, before any kernel runs; the task layer calls it per task module
    (:func:`oneocean.tasks.common.fresh_cache`), so editing one task recompiles only that task's
    kernel.

    Parameters
    ----------
    dispatcher : numba dispatcher
        A cached kernel whose cache directory holds the entries.
    module_prefixes : tuple of str
        File-name prefixes (``"<module>."``) of the cache entries to drop when stale.
    *sources : path-like
        Files or folders the cached kernels depend on, beyond the engine; the fingerprint
        (:func:`source_fingerprint`) covers both.

    Returns
    -------
    bool
        True if files were removed.
    """
    d = cache_dir_of(dispatcher)
    if d is None or not d.is_dir():
        return False
    fp = source_fingerprint(*sources)
    marker = d / (_MARKER if not sources else f"{_MARKER}.{module_prefixes[0]}")
    try:
        if marker.read_text() == fp:
            return False
    except OSError:
        pass
    removed = False
    for f in d.iterdir():
        if f.suffix in (".nbi", ".nbc") and f.name.startswith(module_prefixes):
            try:
                f.unlink()
                removed = True
            except OSError:
                pass
    try:
        tmp = marker.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(fp)
        os.replace(tmp, marker)
    except OSError:
        pass
    return removed
