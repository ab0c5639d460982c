"""How the compiled kernels are called: a kernel over a range of episodes on numba's thread
count (:func:`over_range`) and a kernel's compiled entry point for given
argument types, without numba's dispatch (:func:`fast_entry`)."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np

_EXECUTOR: ThreadPoolExecutor | None = None


def _executor(n_threads: int) -> ThreadPoolExecutor:
    """A process-wide thread pool of at least ``n_threads`` workers (kept between calls: the
    step API calls the kernels every step)."""
    global _EXECUTOR
    if _EXECUTOR is None or _EXECUTOR._max_workers < n_threads:
        _EXECUTOR = ThreadPoolExecutor(max_workers=n_threads)
    return _EXECUTOR


def over_range(kernel, lo: int, hi: int, *args) -> None:
    """Run ``kernel(*args, e_lo, e_hi)`` over episodes ``lo .. hi-1`` on
    ``numba.get_num_threads()`` threads, each a contiguous block of episodes.

    Task kernels are serial ``njit(cache=True, nogil=True)`` loops over a block of episodes,
    so threads run them without the GIL; ``prange`` is not used, since numba's parfor pass
    more than doubles every task kernel's compile time. Every episode is computed by one
    thread with counter-based random streams, so results do not depend on the thread count
    (tested).

    Parameters
    ----------
    kernel : callable
        A compiled kernel taking ``(*args, e_lo, e_hi)``.
    lo, hi : int
        The episodes ``lo .. hi-1`` to run (one block, in the calling thread, when
        ``hi - lo <= 1``).
    *args
        The kernel's leading arguments, passed to every block.
    """
    lo, hi = int(lo), int(hi)
    if hi - lo <= 1:               # one episode: no split (and no thread-count query)
        kernel(*args, lo, hi)
        return
    import numba

    n_thr = max(1, min(int(numba.get_num_threads()), hi - lo))
    if n_thr == 1:
        kernel(*args, lo, hi)
        return
    bounds = np.linspace(lo, hi, n_thr + 1).astype(np.int64)
    futures = [_executor(n_thr).submit(kernel, *args, int(bounds[j]), int(bounds[j + 1]))
               for j in range(n_thr)]
    for f in futures:
        f.result()


#: Scalar classes :func:`_type_key` keys by their class alone.
_SCALAR_TYPES = frozenset((complex, np.float64, np.float32, np.int64, np.int32, np.uint64,
                           np.uint32, np.uint8, np.int8, np.bool_, np.complex128))
#: fast_entry's entry points: (dispatcher, argument type key) -> entry
_FAST: dict = {}
_MAX_FAST = 256


class _Unkeyed(Exception):
    """An argument whose numba type :func:`_type_key` does not derive."""


def _type_key(v):
    """A hashable key that determines numba's argument type of ``v`` (``typeof(v,
    Purpose.argument)``): for an ndarray its dtype, ndim, layout flags, writeability and alignment
    (what numba's ``_typeof_ndarray`` reads), for a tuple or NamedTuple its class and its items'
    keys, for a Python int its bit-length class (``_typeof_int``), for the other scalars
    their class. Anything else raises :class:`_Unkeyed`."""
    t = type(v)
    if t is np.ndarray:
        f = v.flags
        return (v.dtype, v.ndim, f.c_contiguous, f.f_contiguous, f.writeable, f.aligned)
    if t is float or t is bool or v is None or t in _SCALAR_TYPES:
        return t
    if t is int:
        n = v.bit_length()
        return (int, n < 32, n < 64, n == 64 and v >= 0)
    if isinstance(v, tuple):
        return (t,) + tuple(_type_key(x) for x in v)
    raise _Unkeyed


def fast_entry(dispatcher, args):
    """The compiled entry point of the numba ``dispatcher`` for the types of ``args``.

    The entry point skips numba's per-call type resolution (about 20 us with the loop's
    NamedTuple arguments, several times a small batch's step). Valid while the arguments keep
    their types. Found once per dispatcher and argument types: later calls with arguments of
    the same types (every batch of a cell) look it up by :func:`_type_key`, which costs a
    small part of numba's type resolution of the same arguments.

    Parameters
    ----------
    dispatcher : numba dispatcher
        A compiled (``njit``) function.
    args : tuple
        All its arguments, as a call would pass them.

    Returns
    -------
    callable
        The compiled entry point; the dispatcher itself where no compiled version matches or
        numba's internals differ.
    """
    try:
        key = (dispatcher, _type_key(tuple(args)))
    except _Unkeyed:
        key = None
    hit = _FAST.get(key) if key is not None else None
    if hit is not None:
        return hit
    try:
        sig = tuple(dispatcher.typeof_pyval(a) for a in args)
        cres = dispatcher.overloads.get(sig)
    except Exception:   # pragma: no cover - a numba without these internals
        return dispatcher
    if cres is None:
        return dispatcher
    if key is not None:
        if len(_FAST) >= _MAX_FAST:
            _FAST.clear()
        _FAST[key] = cres.entry_point
    return cres.entry_point
