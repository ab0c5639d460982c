"""Counter-based random numbers: a pure function of (seed, episode, purpose, counter).

Kernels never hold random state: every draw is ``hash(seed, episode, purpose, counter)``
(SplitMix64 finaliser), so results do not depend on thread count or on the order in which
episodes run. Orchestration code that prefers NumPy generators uses :func:`episode_rng`
(``np.random.SeedSequence([seed, episode, purpose])``).
"""

from __future__ import annotations

import numpy as np
from ._jit import hot_kernel

#: Purpose codes (keep stable: they are part of every seeded result).
PURPOSE_SPAWN = 1
PURPOSE_GOAL = 2
PURPOSE_ACTION_NOISE = 3
PURPOSE_START_TIME = 4
PURPOSE_TASK = 100  # first code free for the task layer

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_S11 = np.uint64(11)
_INV53 = 1.0 / 9007199254740992.0  # 2**-53
_MASK64 = (1 << 64) - 1


@hot_kernel
def _mix(x):
    """SplitMix64 step on a uint64."""
    z = x + _GOLDEN
    z = (z ^ (z >> _S30)) * _M1
    z = (z ^ (z >> _S27)) * _M2
    return z ^ (z >> _S31)


@hot_kernel
def hash64(seed, episode, purpose, counter):
    """uint64 hash of four non-negative integers (a counter-based random word).

    Parameters
    ----------
    seed : int
        Run seed.
    episode : int
        Episode index.
    purpose : int
        Purpose code (the ``PURPOSE_*`` constants; tasks use codes from ``PURPOSE_TASK``).
    counter : int
        Draw index within the stream.

    Returns
    -------
    numpy.uint64
        The random word.
    """
    h = _mix(np.uint64(seed))
    h = _mix(h ^ np.uint64(episode))
    h = _mix(h ^ np.uint64(purpose))
    return _mix(h ^ np.uint64(counter))


@hot_kernel
def uniform01(seed, episode, purpose, counter):
    """Uniform float64 in [0, 1) from :func:`hash64` (53 random bits).

    Parameters
    ----------
    seed, episode, purpose, counter : int
        Stream and draw index, as for :func:`hash64`.

    Returns
    -------
    float
        The draw, in [0, 1).
    """
    return float(hash64(seed, episode, purpose, counter) >> _S11) * _INV53


@hot_kernel
def normal(seed, episode, purpose, counter):
    """Standard normal float64 (Box-Muller on two counter-based uniforms).

    Parameters
    ----------
    seed, episode, purpose, counter : int
        Stream and draw index, as for :func:`hash64`; the draw uses the uniforms at counters
        ``2 counter`` and ``2 counter + 1`` of the stream.

    Returns
    -------
    float
        The draw.
    """
    u1 = uniform01(seed, episode, purpose, 2 * counter)
    u2 = uniform01(seed, episode, purpose, 2 * counter + 1)
    return np.sqrt(-2.0 * np.log(1.0 - u1)) * np.cos(2.0 * np.pi * u2)


def hash64_py(seed: int, episode: int, purpose: int, counter: int) -> int:
    """Pure-Python twin of :func:`hash64` (used by tests to pin the bit pattern).

    Parameters
    ----------
    seed, episode, purpose, counter : int
        As for :func:`hash64`.

    Returns
    -------
    int
        The hash, in ``[0, 2**64)``.
    """
    def mix(x):
        z = (x + 0x9E3779B97F4A7C15) & _MASK64
        z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & _MASK64
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _MASK64
        return z ^ (z >> 31)
    h = mix(seed & _MASK64)
    for v in (episode, purpose, counter):
        h = mix(h ^ (v & _MASK64))
    return h


def episode_rng(seed: int, episode: int, purpose: int) -> np.random.Generator:
    """A NumPy generator for one (seed, episode, purpose) stream, via ``SeedSequence``.

    Parameters
    ----------
    seed : int
        Run seed.
    episode : int
        Episode index.
    purpose : int
        Purpose code (the ``PURPOSE_*`` constants).

    Returns
    -------
    numpy.random.Generator
        Generator seeded with ``SeedSequence([seed, episode, purpose])``.
    """
    return np.random.default_rng(np.random.SeedSequence([int(seed), int(episode), int(purpose)]))
