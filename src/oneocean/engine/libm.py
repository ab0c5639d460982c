"""Element-wise float64 math with the same bits on every x86-64 CPU.

NumPy dispatches its float64 ``sin``, ``cos``, ``exp``, ``log`` and ``tanh`` loops by CPU
(AVX2 and AVX-512 versions), and ``arctan2``, ``arctan``, ``arcsin`` (and others) to Intel's
SVML on AVX-512 machines. These loops agree with each other only to a few units in the last
place: ``np.tanh`` on an AVX2 CPU differs from the C library's ``tanh`` in about 8 % of
random inputs, and an AVX-512 machine's ``np.arctan2`` from both. A grid, an episode's start
or a model built with them therefore changes in its last bits from one machine to another,
and a learned policy can turn such a change into another outcome.

The functions here apply the C library's scalar function to every element, in a compiled
loop (numba lowers ``math.sin`` etc. to the libm call; it would vectorise them only with
Intel's SVML, ``numba.config.USING_SVML``, which needs the optional ``icc_rt`` package that
none of :mod:`oneocean`'s dependencies installs). They are what code outside the jitted
kernels uses instead of NumPy's transcendental ufuncs (``tests/test_libm.py`` checks both the
bits and that no module calls NumPy's). Inside jitted kernels ``math.*`` already is libm.

Each function takes a scalar or an array (any shape; ``arctan2`` broadcasts its two
arguments) and returns a float for a scalar, else a new float64 array of the input's shape.
"""

from __future__ import annotations

import math

import numpy as np

from ._jit import hot_kernel

__all__ = ["sin", "cos", "exp", "log", "tanh", "arctan", "arcsin", "arctan2", "power", "log1p"]


# operation codes of the two kernels (one compiled loop each; the branch costs nothing next to
# the libm call)
_SIN, _COS, _EXP, _LOG, _LOG1P, _TANH, _ATAN, _ASIN = range(8)
_ATAN2, _POW = range(2)


@hot_kernel
def _unary_kernel(op, x, out):
    # numba's math.log / math.asin follow C outside their domain (-inf / NaN), as NumPy does,
    # where Python's raise
    for i in range(x.size):
        v = x[i]
        if op == _SIN:
            out[i] = math.sin(v)
        elif op == _COS:
            out[i] = math.cos(v)
        elif op == _EXP:
            out[i] = math.exp(v)
        elif op == _LOG:
            out[i] = math.log(v)
        elif op == _LOG1P:
            out[i] = math.log1p(v)
        elif op == _TANH:
            out[i] = math.tanh(v)
        elif op == _ATAN:
            out[i] = math.atan(v)
        else:
            out[i] = math.asin(v)


@hot_kernel
def _binary_kernel(op, a, b, out):
    for i in range(a.size):
        if op == _ATAN2:
            out[i] = math.atan2(a[i], b[i])
        else:
            out[i] = math.pow(a[i], b[i])


def _unary(op, x):
    a = np.asarray(x, dtype=np.float64, order="C")         # keeps a scalar 0-d
    out = np.empty(a.shape, dtype=np.float64)
    if a.size:
        _unary_kernel(op, a.reshape(-1), out.reshape(-1))
    return float(out) if out.ndim == 0 else out


def sin(x):
    """``sin(x)`` element-wise, as the C library computes it.

    Parameters
    ----------
    x : float or array_like
        Angle, rad.

    Returns
    -------
    float or ndarray
        Sine, dimensionless. A float for a scalar ``x``, else a float64 array of ``x``'s shape.
    """
    return _unary(_SIN, x)


def cos(x):
    """``cos(x)`` element-wise, as the C library computes it.

    Parameters
    ----------
    x : float or array_like
        Angle, rad.

    Returns
    -------
    float or ndarray
        Cosine, dimensionless. A float for a scalar ``x``, else a float64 array of ``x``'s shape.
    """
    return _unary(_COS, x)


def exp(x):
    """``exp(x)`` element-wise, as the C library computes it.

    Parameters
    ----------
    x : float or array_like
        Exponent.

    Returns
    -------
    float or ndarray
        ``e ** x`` (``inf`` on overflow). A float for a scalar ``x``, else a float64 array of ``x``'s shape.
    """
    return _unary(_EXP, x)


def log(x):
    """Natural logarithm element-wise, as the C library computes it.

    Parameters
    ----------
    x : float or array_like
        Argument.

    Returns
    -------
    float or ndarray
        ``log(x)``: ``-inf`` at 0, NaN below 0. A float for a scalar ``x``, else a float64 array of ``x``'s shape.
    """
    return _unary(_LOG, x)


def log1p(x):
    """``log(1 + x)`` element-wise, as the C library computes it.

    Parameters
    ----------
    x : float or array_like
        Argument (accurate for small ``x``).

    Returns
    -------
    float or ndarray
        ``log(1 + x)``: ``-inf`` at -1, NaN below. A float for a scalar ``x``, else a float64 array of ``x``'s shape.
    """
    return _unary(_LOG1P, x)


def tanh(x):
    """``tanh(x)`` element-wise, as the C library computes it.

    Parameters
    ----------
    x : float or array_like
        Argument.

    Returns
    -------
    float or ndarray
        Hyperbolic tangent, in [-1, 1]. A float for a scalar ``x``, else a float64 array of ``x``'s shape.
    """
    return _unary(_TANH, x)


def arctan(x):
    """``arctan(x)`` element-wise, as the C library computes it.

    Parameters
    ----------
    x : float or array_like
        Argument.

    Returns
    -------
    float or ndarray
        Angle in (-pi/2, pi/2), rad. A float for a scalar ``x``, else a float64 array of ``x``'s shape.
    """
    return _unary(_ATAN, x)


def arcsin(x):
    """``arcsin(x)`` element-wise, as the C library computes it.

    Parameters
    ----------
    x : float or array_like
        Argument.

    Returns
    -------
    float or ndarray
        Angle in [-pi/2, pi/2], rad (NaN outside [-1, 1]). A float for a scalar ``x``, else a float64 array of ``x``'s shape.
    """
    return _unary(_ASIN, x)


def _binary(op, a, b):
    ab, bb = np.broadcast_arrays(np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64))
    a1, b1 = np.asarray(ab, order="C"), np.asarray(bb, order="C")
    out = np.empty(a1.shape, dtype=np.float64)
    if out.size:
        _binary_kernel(op, a1.reshape(-1), b1.reshape(-1), out.reshape(-1))
    return float(out) if out.ndim == 0 else out


def arctan2(y, x):
    """``arctan2(y, x)`` element-wise with broadcasting, as the C library computes it.

    Parameters
    ----------
    y, x : float or array_like
        Ordinate and abscissa (broadcast together).

    Returns
    -------
    float or ndarray
        Angle of the point ``(x, y)`` in [-pi, pi], rad: a float for scalars, else a float64
        array of the broadcast shape.
    """
    return _binary(_ATAN2, y, x)


def power(x, p):
    """``x ** p`` element-wise with broadcasting, as the C library's ``pow`` computes it.

    NumPy computes the exponents 2, 0.5, 1 and -1 exactly by arithmetic; this is for the
    others.

    Parameters
    ----------
    x, p : float or array_like
        Base and exponent (broadcast together).

    Returns
    -------
    float or ndarray
        ``x ** p``: a float for scalars, else a float64 array of the broadcast shape.
    """
    return _binary(_POW, x, p)
