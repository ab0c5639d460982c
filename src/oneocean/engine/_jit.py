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

Small kernels that take the :class:`~oneocean.engine.grid.Grid` (15 arrays + 20 scalars,
~1 KB when flattened) or many arrays are declared ``inline="always"``: numba passes such
structs by value, and an out-of-line call copies them on every call (measured ~70 ns per
``sample_current`` call before inlining).
"""

from __future__ import annotations

from numba import njit


def hot_kernel(*args, **kwargs):
    """``numba.njit(cache=True, _nrt=False, error_model="numpy")`` (plus ``kwargs``)."""
    opts = dict(cache=True, _nrt=False, error_model="numpy")
    opts.update(kwargs)
    if args and callable(args[0]) and len(args) == 1:
        return njit(**opts)(args[0])
    return njit(*args, **opts)


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
    """sha256 over the engine's ``.py`` sources and ``paths`` (files, or folders of ``.py``
    files), plus the numba version."""
    import numba

    h = hashlib.sha256(numba.__version__.encode())
    for p in (_ENGINE_DIR, *map(Path, paths)):
        for f in (sorted(p.glob("*.py")) if p.is_dir() else [p]):
            h.update(f.name.encode())
            h.update(f.read_bytes())
    return h.hexdigest()


def cache_dir_of(dispatcher) -> Path | None:
    """Directory where numba caches ``dispatcher`` (None if caching is off)."""
    cache = getattr(dispatcher, "_cache", None)
    path = getattr(cache, "_cache_path", None)
    return Path(path) if path else None


def ensure_fresh_cache(dispatcher, module_prefixes: tuple[str, ...], *sources: Path) -> bool:
    """Remove stale numba cache files of ``module_prefixes`` next to ``dispatcher``'s cache.

    The fingerprint covers the engine and ``sources`` (the files or folders the cached kernels
    depend on). Returns True if files were removed. Call at import time, before any kernel
    runs; the task layer calls it per task module (:func:`oneocean.tasks.common.fresh_cache`),
    so editing one task recompiles only that task's kernel.
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
