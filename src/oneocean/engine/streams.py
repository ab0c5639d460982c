"""NumPy's per-episode random streams, compiled: the same numbers, bit for bit.

The scenarios draw each episode (or candidate) from its own generator,
``numpy.random.default_rng(SeedSequence([seed, episode, purpose]))``. Making one in Python
costs about 20 us and every draw from it a few more, which is most of a reset's time when
thousands of candidates are drawn. This module holds the same streams as rows of a
``(n, 4)`` uint64 array (a PCG64 state: ``state_hi, state_lo, inc_hi, inc_lo``), seeded in
one compiled call, and draws from them in compiled code:

* :func:`episode_states` - the rows of ``SeedSequence([seed, e, purpose])`` for episodes
  ``e`` (NumPy's ``SeedSequence`` hash with its default pool of four words, then
  ``PCG64``'s seeding from ``generate_state(4, uint64)``);
* :func:`next_double` / :func:`uniform` (jitted, inline) - ``Generator.random()`` and
  ``Generator.uniform(lo, hi)``: ``(next_uint64 >> 11) 2**-53`` and ``lo + (hi - lo) u``;
* :func:`advance` (jitted, inline) - ``PCG64.advance(delta)``: a row ``delta`` draws on, in
  ``O(log delta)`` steps;
* :func:`uniform_rows` - ``k`` uniforms from each of several rows (``Generator.uniform(lo,
  hi, k)`` on each), from Python;
* :func:`generator` - a NumPy generator in a row's state (for a rare path left in Python,
  e.g. to raise the error NumPy-driven code raises).

The streams equal NumPy's own (``tests/test_streams.py`` compares states and draws with
``numpy.random`` for small, 32-bit and 63-bit seeds), so a scenario drawn here is the one
drawn with NumPy generators. Integer arithmetic only, plus one multiply and one add per
uniform, which NumPy and numba both evaluate without fused multiply-add: the same bits on
every CPU.
"""

from __future__ import annotations

import numpy as np

from ._jit import hot_kernel

__all__ = ["episode_states", "next_double", "uniform", "uniform_rows", "advance", "seed_words",
           "generator"]

_M32 = np.uint64(0xFFFFFFFF)
_S32 = np.uint64(32)
_M32 = np.uint64(0xFFFFFFFF)
_S16 = np.uint64(16)
_S11 = np.uint64(11)
_S58 = np.uint64(58)
_S63 = np.uint64(63)
_ONE = np.uint64(1)
_ZERO = np.uint64(0)
# SeedSequence's hash constants (numpy/random/bit_generator.pyx)
_INIT_A = np.uint64(0x43b0d7e5)
_MULT_A = np.uint64(0x931e8875)
_INIT_B = np.uint64(0x8b51f9dd)
_MULT_B = np.uint64(0x58f38ded)
_MIX_L = np.uint64(0xca01f9dd)
_MIX_R = np.uint64(0x4973f715)
_POOL = 4
# PCG64's 128-bit multiplier (numpy/random/src/pcg64/pcg64.h)
_MUL_HI = np.uint64(2549297995355413924)
_MUL_LO = np.uint64(4865540595714422341)
_INV53 = 1.0 / 9007199254740992.0
#: Most entropy words of one stream: a seed of up to 64 bits (2 words), the episode index
#: and the purpose (up to 2 words each).
MAX_WORDS = 6


def seed_words(seed: int) -> np.ndarray:
    """The uint32 words of a seed as ``SeedSequence`` takes an int: least significant first,
    ``[0]`` for 0.

    Parameters
    ----------
    seed : int
        A non-negative seed below ``2**64``.

    Returns
    -------
    (1,) or (2,) uint32

    Raises
    ------
    ValueError
        A negative seed or one of 64 bits or more (which ``SeedSequence`` would take, but
        these streams do not).
    """
    s = int(seed)
    if s < 0 or s >= 2 ** 64:
        raise ValueError(f"seed: must be in [0, 2**64), got {seed}")
    words = [s & 0xFFFFFFFF]
    if s >> 32:
        words.append(s >> 32)
    return np.array(words, dtype=np.uint32)


@hot_kernel(inline="always")
def _hashmix(value, hc):
    """SeedSequence's ``hashmix`` on uint32 values held in uint64; returns (value, hc)."""
    value = (value ^ hc) & _M32
    hc = (hc * _MULT_A) & _M32
    value = (value * hc) & _M32
    value ^= value >> _S16
    return value, hc


@hot_kernel(inline="always")
def _mix(x, y):
    r = ((_MIX_L * x) - (_MIX_R * y)) & _M32
    return r ^ (r >> _S16)


@hot_kernel(inline="always")
def _mulhi(a, b):
    """High 64 bits of the 128-bit product of two uint64."""
    a_lo = a & _M32
    a_hi = a >> _S32
    b_lo = b & _M32
    b_hi = b >> _S32
    p0 = a_lo * b_lo
    p1 = a_lo * b_hi
    p2 = a_hi * b_lo
    p3 = a_hi * b_hi
    cy = ((p0 >> _S32) + (p1 & _M32) + (p2 & _M32)) >> _S32
    return p3 + (p1 >> _S32) + (p2 >> _S32) + cy


@hot_kernel(inline="always")
def _step(st, i):
    """One PCG64 step of row ``i``: ``state = state * MUL + inc`` (mod 2**128)."""
    sh = st[i, 0]
    sl = st[i, 1]
    lo = sl * _MUL_LO
    hi = _mulhi(sl, _MUL_LO) + sh * _MUL_LO + sl * _MUL_HI
    lo2 = lo + st[i, 3]
    carry = _ONE if lo2 < lo else _ZERO
    st[i, 0] = hi + st[i, 2] + carry
    st[i, 1] = lo2


@hot_kernel(inline="always")
def _mul128(ah, al, bh, bl):
    """(a * b) mod 2**128 of two (hi, lo) uint64 pairs: (hi, lo)."""
    return _mulhi(al, bl) + ah * bl + al * bh, al * bl


@hot_kernel(inline="always")
def _add128(ah, al, bh, bl):
    """(a + b) mod 2**128 of two (hi, lo) uint64 pairs: (hi, lo)."""
    lo = al + bl
    return ah + bh + (_ONE if lo < al else _ZERO), lo


@hot_kernel(inline="always")
def advance(st, i, src, j, delta):
    """Row ``i`` := row ``j`` of ``src`` advanced by ``delta`` steps (``PCG64.advance``).

    The state ``delta`` draws of :func:`next_uint64` later, in ``O(log delta)``: the LCG's
    jump ahead (``state * MUL**delta + inc * (MUL**delta - 1) / (MUL - 1)``, by squaring).
    A scenario that draws a block of numbers of which it reads only the first few reads
    those and jumps over the rest: the same numbers, the same state after the block.

    Parameters
    ----------
    st : (n, 4) uint64
        Stream states; row ``i`` is written.
    i : int
        Row written.
    src : (m, 4) uint64
        Stream states read (may be ``st``; ``i == j`` advances a row in place).
    j : int
        Row read.
    delta : int
        Steps, >= 0.
    """
    inc_h = src[j, 2]
    inc_l = src[j, 3]
    am_h, am_l = _ZERO, _ONE                 # accumulated multiplier
    ap_h, ap_l = _ZERO, _ZERO                # accumulated increment
    cm_h, cm_l = _MUL_HI, _MUL_LO            # MUL ** (2 ** bit)
    cp_h, cp_l = inc_h, inc_l                # its increment
    d = np.uint64(delta)
    while d > _ZERO:
        if d & _ONE:
            am_h, am_l = _mul128(am_h, am_l, cm_h, cm_l)
            ph, pl = _mul128(ap_h, ap_l, cm_h, cm_l)
            ap_h, ap_l = _add128(ph, pl, cp_h, cp_l)
        m1_h, m1_l = _add128(cm_h, cm_l, _ZERO, _ONE)
        cp_h, cp_l = _mul128(m1_h, m1_l, cp_h, cp_l)
        cm_h, cm_l = _mul128(cm_h, cm_l, cm_h, cm_l)
        d = d >> _ONE
    sh, sl = _mul128(am_h, am_l, src[j, 0], src[j, 1])
    sh, sl = _add128(sh, sl, ap_h, ap_l)
    st[i, 0] = sh
    st[i, 1] = sl
    st[i, 2] = inc_h
    st[i, 3] = inc_l


@hot_kernel(inline="always")
def next_uint64(st, i):
    """PCG64's next 64-bit output of row ``i`` (XSL-RR of the stepped state).

    Parameters
    ----------
    st : (n, 4) uint64
        Stream states (:func:`episode_states`), advanced in place.
    i : int
        Row.

    Returns
    -------
    numpy.uint64
    """
    _step(st, i)
    hi = st[i, 0]
    v = hi ^ st[i, 1]
    rot = hi >> _S58
    return (v >> rot) | (v << ((_ZERO - rot) & _S63))


@hot_kernel(inline="always")
def next_double(st, i):
    """``Generator.random()`` of row ``i``: a float64 in [0, 1) (53 bits).

    Parameters
    ----------
    st : (n, 4) uint64
        Stream states, advanced in place.
    i : int
        Row.

    Returns
    -------
    float
    """
    return float(next_uint64(st, i) >> _S11) * _INV53


@hot_kernel(inline="always")
def uniform(st, i, lo, hi):
    """``Generator.uniform(lo, hi)`` of row ``i``: ``lo + (hi - lo) * random()``.

    Parameters
    ----------
    st : (n, 4) uint64
        Stream states, advanced in place.
    i : int
        Row.
    lo, hi : float
        Bounds.

    Returns
    -------
    float
    """
    r = hi - lo
    return lo + r * next_double(st, i)


@hot_kernel(inline="always")
def next_uint32(st, buf, i):
    """PCG64's next 32-bit output of row ``i``: the low half of a new 64-bit output, its high
    half kept for the next call (the bit generator's ``has_uint32`` / ``uinteger``).

    Parameters
    ----------
    st : (n, 4) uint64
        Stream states, advanced in place.
    buf : (n, 2) uint64
        Each row's kept half: ``[has, value]`` (zeros for a fresh stream), updated in place.
    i : int
        Row.

    Returns
    -------
    numpy.uint64
        The 32-bit value.
    """
    if buf[i, 0] != _ZERO:
        buf[i, 0] = _ZERO
        return buf[i, 1]
    v = next_uint64(st, i)
    buf[i, 0] = _ONE
    buf[i, 1] = v >> _S32
    return v & _M32


@hot_kernel(inline="always")
def integers(st, buf, i, high):
    """``Generator.integers(high)`` (int64) of row ``i`` for ``1 <= high <= 2**32``: NumPy's
    bounded draw (Lemire's rejection on 32-bit outputs; no draw when ``high == 1``).

    Parameters
    ----------
    st : (n, 4) uint64
        Stream states, advanced in place.
    buf : (n, 2) uint64
        The rows' kept 32-bit halves (:func:`next_uint32`), updated in place.
    i : int
        Row.
    high : int
        Exclusive upper bound.

    Returns
    -------
    int
        A value in ``[0, high)``.
    """
    rng = np.uint64(high - 1)
    if rng == _ZERO:
        return np.int64(0)
    if rng == _M32:
        return np.int64(next_uint32(st, buf, i))
    excl = rng + _ONE
    m = next_uint32(st, buf, i) * excl
    left = m & _M32
    if left < excl:
        threshold = (_M32 - rng) % excl
        while left < threshold:
            m = next_uint32(st, buf, i) * excl
            left = m & _M32
    return np.int64(m >> _S32)


@hot_kernel
def _seed_rows(words0, n0, episodes, purpose, ent, pool, s32, out):
    # ent, pool, s32: scratch (MAX_WORDS, 4 and 8 uint64: the kernel allocates nothing)
    for r in range(episodes.shape[0]):
        # the entropy words: the seed's, the episode's, the purpose's (each int as
        # SeedSequence splits it: least significant word first, [0] for 0)
        m = 0
        for w in range(n0):
            ent[m] = words0[w]
            m += 1
        for v in (episodes[r], purpose):
            ent[m] = v & _M32
            m += 1
            if v >> _S32:
                ent[m] = v >> _S32
                m += 1
        # mix_entropy
        hc = _INIT_A
        for k in range(_POOL):
            val = ent[k] if k < m else _ZERO
            pool[k], hc = _hashmix(val, hc)
        for a in range(_POOL):
            for b in range(_POOL):
                if a != b:
                    h, hc = _hashmix(pool[a], hc)
                    pool[b] = _mix(pool[b], h)
        for a in range(_POOL, m):
            for b in range(_POOL):
                h, hc = _hashmix(ent[a], hc)
                pool[b] = _mix(pool[b], h)
        # generate_state(4, uint64): 8 uint32 words, paired little-endian
        hb = _INIT_B
        for k in range(2 * _POOL):
            d = (pool[k % _POOL] ^ hb) & _M32
            hb = (hb * _MULT_B) & _M32
            d = (d * hb) & _M32
            d ^= d >> _S16
            s32[k] = d
        seed_hi = s32[0] | (s32[1] << _S32)
        seed_lo = s32[2] | (s32[3] << _S32)
        inc_hi = s32[4] | (s32[5] << _S32)
        inc_lo = s32[6] | (s32[7] << _S32)
        # pcg_setseq_128_srandom_r: state 0, inc = initseq << 1 | 1, step, += initstate, step
        out[r, 0] = _ZERO
        out[r, 1] = _ZERO
        out[r, 2] = (inc_hi << _ONE) | (inc_lo >> _S63)
        out[r, 3] = (inc_lo << _ONE) | _ONE
        _step(out, r)
        lo = out[r, 1] + seed_lo
        carry = _ONE if lo < out[r, 1] else _ZERO
        out[r, 0] = out[r, 0] + seed_hi + carry
        out[r, 1] = lo
        _step(out, r)
    return out


def episode_states(seed: int, episodes, purpose: int) -> np.ndarray:
    """The PCG64 states of ``default_rng(SeedSequence([seed, e, purpose]))`` for every ``e``
    in ``episodes``.

    Parameters
    ----------
    seed : int
        Run seed, in ``[0, 2**64)``.
    episodes : int or array_like of int
        The episode (candidate) indices, non-negative; an int ``n`` means ``0 .. n-1``.
    purpose : int
        Stream purpose (``PURPOSE_*``), non-negative.

    Returns
    -------
    (len(episodes), 4) uint64
        One stream per row: ``state_hi, state_lo, inc_hi, inc_lo``.

    Raises
    ------
    ValueError
        A seed, episode index or purpose out of range.
    """
    eps = (np.arange(int(episodes)) if np.ndim(episodes) == 0
           else np.asarray(episodes).reshape(-1))
    if eps.size and (int(eps.min()) < 0 or int(eps.max()) >= 2 ** 63):
        raise ValueError("episodes: indices must be in [0, 2**63)")
    if not 0 <= int(purpose) < 2 ** 63:
        raise ValueError(f"purpose: must be in [0, 2**63), got {purpose}")
    words = seed_words(seed).astype(np.uint64)
    out = np.empty((eps.size, 4), dtype=np.uint64)
    return _seed_rows(words, words.size, eps.astype(np.uint64), np.uint64(int(purpose)),
                      np.empty(MAX_WORDS, dtype=np.uint64), np.empty(_POOL, dtype=np.uint64),
                      np.empty(2 * _POOL, dtype=np.uint64), out)


@hot_kernel
def _uniform_rows(st, rows, lo, hi, out):
    for j in range(rows.shape[0]):
        for k in range(out.shape[1]):
            out[j, k] = uniform(st, rows[j], lo, hi)
    return out


def uniform_rows(st: np.ndarray, lo: float, hi: float, k: int = 1, rows=None) -> np.ndarray:
    """``Generator.uniform(lo, hi, k)`` from each stream of ``rows`` (default all), in order.

    Parameters
    ----------
    st : (n, 4) uint64
        Stream states (:func:`episode_states`), advanced in place.
    lo, hi : float
        Bounds.
    k : int
        Draws per stream.
    rows : array_like of int, optional
        Which streams (default all).

    Returns
    -------
    (len(rows), k) float64
    """
    rows = (np.arange(st.shape[0]) if rows is None
            else np.asarray(rows, dtype=np.int64).reshape(-1))
    out = np.empty((rows.size, int(k)))
    return _uniform_rows(st, rows.astype(np.int64), float(lo), float(hi), out)


def generator(row, kept=None) -> np.random.Generator:
    """A NumPy generator in the state of one stream (its next draws are the stream's).

    Parameters
    ----------
    row : (4,) uint64
        One row of :func:`episode_states` (as advanced so far).
    kept : (2,) uint64, optional
        The row's kept 32-bit half (:func:`next_uint32`'s ``buf`` row); default none.

    Returns
    -------
    numpy.random.Generator
        A ``PCG64`` generator at that state.
    """
    hi, lo, ihi, ilo = (int(v) for v in np.asarray(row, dtype=np.uint64))
    bg = np.random.PCG64()
    bg.state = {"bit_generator": "PCG64", "state": {"state": (hi << 64) | lo,
                                                    "inc": (ihi << 64) | ilo},
                "has_uint32": 0 if kept is None else int(kept[0]),
                "uinteger": 0 if kept is None else int(kept[1])}
    return np.random.Generator(bg)
