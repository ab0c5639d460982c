"""The BC network's fit: a relu MLP trained by Adam on the squared error, in loops whose
floating-point operations have one fixed order, so that the same features, targets and seed
give the same weights bytes on every x86-64 machine.

Why not a library fit. A BLAS matrix product (NumPy's OpenBLAS, and so scikit-learn's
``MLPRegressor``) picks its kernel by the CPU it runs on (SSE3, AVX, AVX2 + FMA, AVX-512):
each kernel sums the products in its own blocking and fuses multiply-adds or not, so the
same data and seed give weights that differ in the last bits from one CPU to another, and
the rollouts, being chaotic, carry those bits into the BC success rates. Pinning the BLAS to
one thread removes the thread-count dependence but not this one.

What makes it machine-independent:

* every sum -- forward pass, back-propagated errors, weight and bias gradients, the losses,
  the features' mean and standard deviation -- is a plain ``numba`` loop over its terms in
  one fixed order (rows of the minibatch in order, inputs in order). Without ``fastmath``
  LLVM may not reassociate floating-point additions or contract a multiply and an add into
  an FMA, so vectorisation (SSE2 on one CPU, AVX-512 on another) only computes independent
  outputs side by side, never a different sum. The loops are arranged so that the innermost
  one runs over independent outputs and contiguous memory (it vectorises);
* the rest is IEEE-exact elementwise arithmetic (``+ - * /`` and ``sqrt``); the Adam bias
  corrections ``beta ** t`` are running products, not ``pow`` (libm's ``pow`` has
  CPU-dependent variants);
* no BLAS, no NumPy reduction (``np.sum`` / ``np.mean`` block their pairwise sums by SIMD
  width) and no libm call here. (The features' ``log1p`` is computed before, by
  :func:`oneocean.tasks.learned.features_rows`, the episode loop's own feature map: see
  :mod:`oneocean.methods.bc.train`.)

The forward pass is :func:`oneocean.tasks.learned.forward`'s, term for term (bias first,
then the inputs in order, zero inputs skipped), so the network the loop runs predicts exactly
what the training measured.

Semantics: those of scikit-learn's ``MLPRegressor(activation="relu", solver="adam")`` fitted
by ``partial_fit`` once per epoch (a test checks that both agree to rounding; scikit-learn
itself is not used here). Glorot-uniform initialisation (per layer, weights then biases,
``uniform(-b, b)`` with ``b = sqrt(6 / (fan_in + fan_out))``) from one ``RandomState(seed)``,
which also draws every epoch's order of the rows (``shuffle(arange(n))``); minibatches of
``batch_size`` in that order, the last one shorter; the gradient of ``0.5 * sum over outputs
of the minibatch mean of the squared error + 0.5 * alpha * |W|^2 / batch``; Adam (``beta1 =
0.9``, ``beta2 = 0.999``, ``eps = 1e-8``, step ``lr * sqrt(1 - beta2^t) / (1 - beta1^t)``)
with one state across the epochs.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ...engine._jit import hot_kernel
from ...tasks.learned import dense_layer

BETA1 = 0.9
BETA2 = 0.999
EPSILON = 1e-8


# ------------------------------------------------------------------------------ the kernels


class Net(NamedTuple):
    """The network being fitted (``L`` layers padded to ``width``)."""
    w: np.ndarray       # (L, width, width) w[l, q, j]: input q -> output j of layer l
    wt: np.ndarray      # (L, width, width) its transpose, wt[l, j, q] (the backward pass)
    b: np.ndarray       # (L, width) biases
    dims: np.ndarray    # (L + 1,) int64 layer widths


class Adam(NamedTuple):
    """Adam's first and second moments of every weight and bias, and its step counter."""
    mw: np.ndarray      # (L, width, width)
    vw: np.ndarray
    mb: np.ndarray      # (L, width)
    vb: np.ndarray
    t: np.ndarray       # (3,) [steps taken, beta1^t, beta2^t]


class Scratch(NamedTuple):
    """One minibatch's activations, errors and gradients."""
    a: np.ndarray       # (L + 1, batch, width) a[0] the inputs, a[l + 1] layer l's outputs
    d: np.ndarray       # (L, batch, width) d loss / d (layer l's pre-activation)
    gw: np.ndarray      # (L, width, width) weight gradients
    gb: np.ndarray      # (L, width) bias gradients


@hot_kernel
def column_stats(X, rows, mu, sd):
    """Mean and standard deviation of the columns of ``X[rows]``, in place, in a fixed order.

    Population statistics (``ddof=0``), each a sum over ``rows`` in order; an ``sd`` below
    1e-9 becomes 1.

    Parameters
    ----------
    X : (R, F) float64
        Features.
    rows : (n,) int64
        The rows to use (e.g. the training rows).
    mu : (F,) float64
        Output: the columns' means.
    sd : (F,) float64
        Output: the columns' standard deviations.
    """
    n = rows.shape[0]
    f = X.shape[1]
    for q in range(f):
        mu[q] = 0.0
        sd[q] = 0.0
    for r in range(n):
        x = X[rows[r]]
        for q in range(f):
            mu[q] += x[q]
    for q in range(f):
        mu[q] = mu[q] / n
    for r in range(n):
        x = X[rows[r]]
        for q in range(f):
            dq = x[q] - mu[q]
            sd[q] += dq * dq
    for q in range(f):
        s = math.sqrt(sd[q] / n)
        sd[q] = s if s > 1e-9 else 1.0


@hot_kernel
def ordered_sum(x):
    """The sum ``x[0] + x[1] + ...``, left to right.

    Parameters
    ----------
    x : (n,) float64
        The terms.

    Returns
    -------
    float
        Their sum (0 for an empty array).
    """
    s = 0.0
    for r in range(x.shape[0]):
        s += x[r]
    return s


@hot_kernel
def _forward_batch(w, b, dims, a, m):
    """Rows ``a[0, :m]`` through every layer into ``a[1:]``: per output the bias, then each
    non-zero input times its weight, inputs in order (:func:`oneocean.tasks.learned.forward`);
    relu on the hidden layers."""
    n_layers = dims.shape[0] - 1
    for layer in range(n_layers):
        n_in = dims[layer]
        n_out = dims[layer + 1]
        wl = w[layer]
        bl = b[layer]
        relu = layer < n_layers - 1
        for r in range(m):
            dense_layer(wl, bl, a[layer, r], a[layer + 1, r], n_in, n_out, relu)


@hot_kernel
def _squared_errors(w, b, dims, a, Z, Y, out):
    """``out[r]``: row ``r``'s squared prediction error summed over the outputs in order; the
    rows go through the network in chunks of ``a``'s size."""
    n = Z.shape[0]
    n_layers = dims.shape[0] - 1
    n_y = dims[n_layers]
    start = 0
    while start < n:
        m = min(a.shape[1], n - start)
        for r in range(m):
            for q in range(dims[0]):
                a[0, r, q] = Z[start + r, q]
        _forward_batch(w, b, dims, a, m)
        for r in range(m):
            s = 0.0
            for j in range(n_y):
                e = a[n_layers, r, j] - Y[start + r, j]
                s += e * e
            out[start + r] = s
        start += m


@hot_kernel
def _backward(net, scr, m, alpha):
    """Gradients of ``0.5 * sum over outputs of the mean squared error + 0.5 * alpha * |W|^2
    / m`` over the ``m`` rows in ``scr.a`` (forward pass done, ``scr.d[L - 1]`` holding
    prediction - target) into ``scr.gw``, ``scr.gb``; each a sum over the rows in order."""
    dims = net.dims
    a, d, gw, gb = scr.a, scr.d, scr.gw, scr.gb
    for layer in range(dims.shape[0] - 2, -1, -1):
        n_in = dims[layer]
        n_out = dims[layer + 1]
        g = gw[layer]
        for q in range(n_in):
            for j in range(n_out):
                g[q, j] = 0.0
        for r in range(m):
            x = a[layer, r]
            dr = d[layer, r]
            for q in range(n_in):
                s = x[q]
                if s != 0.0:
                    gq = g[q]
                    for j in range(n_out):
                        gq[j] += s * dr[j]
        wl = net.w[layer]
        for q in range(n_in):
            for j in range(n_out):
                g[q, j] = (g[q, j] + alpha * wl[q, j]) / m
        for j in range(n_out):
            gb[layer, j] = 0.0
        for r in range(m):
            for j in range(n_out):
                gb[layer, j] += d[layer, r, j]
        for j in range(n_out):
            gb[layer, j] = gb[layer, j] / m
        if layer > 0:
            # the error one layer down, d[layer] w[layer]^T: per input a sum over the outputs
            # in order; zero where the relu was off
            wt = net.wt[layer]
            for r in range(m):
                dr = d[layer, r]
                dp = d[layer - 1, r]
                x = a[layer, r]
                for q in range(n_in):
                    dp[q] = 0.0
                for j in range(n_out):
                    s = dr[j]
                    if s != 0.0:
                        wj = wt[j]
                        for q in range(n_in):
                            dp[q] += s * wj[q]
                for q in range(n_in):
                    if x[q] == 0.0:
                        dp[q] = 0.0


@hot_kernel
def _adam_step(net, opt, scr, lr):
    """One Adam step on every weight and bias (elementwise; ``beta ** t`` as running
    products)."""
    dims = net.dims
    opt.t[0] += 1.0
    opt.t[1] *= BETA1
    opt.t[2] *= BETA2
    step = lr * math.sqrt(1.0 - opt.t[2]) / (1.0 - opt.t[1])
    for layer in range(dims.shape[0] - 1):
        n_in = dims[layer]
        n_out = dims[layer + 1]
        for q in range(n_in):
            for j in range(n_out):
                g = scr.gw[layer, q, j]
                mm = BETA1 * opt.mw[layer, q, j] + (1.0 - BETA1) * g
                vv = BETA2 * opt.vw[layer, q, j] + (1.0 - BETA2) * (g * g)
                opt.mw[layer, q, j] = mm
                opt.vw[layer, q, j] = vv
                net.w[layer, q, j] += -step * mm / (math.sqrt(vv) + EPSILON)
                net.wt[layer, j, q] = net.w[layer, q, j]
        for j in range(n_out):
            g = scr.gb[layer, j]
            mm = BETA1 * opt.mb[layer, j] + (1.0 - BETA1) * g
            vv = BETA2 * opt.vb[layer, j] + (1.0 - BETA2) * (g * g)
            opt.mb[layer, j] = mm
            opt.vb[layer, j] = vv
            net.b[layer, j] += -step * mm / (math.sqrt(vv) + EPSILON)


@hot_kernel
def _epoch(net, opt, scr, Z, Y, order, batch, lr, alpha):
    """One pass over the rows ``order`` of (``Z``, ``Y``) in minibatches of ``batch`` (the
    last one shorter): forward, backward, Adam step."""
    n = order.shape[0]
    dims = net.dims
    last = dims.shape[0] - 2
    start = 0
    while start < n:
        m = min(batch, n - start)
        for r in range(m):
            src = Z[order[start + r]]
            for q in range(dims[0]):
                scr.a[0, r, q] = src[q]
        _forward_batch(net.w, net.b, dims, scr.a, m)
        for r in range(m):
            y = Y[order[start + r]]
            for j in range(dims[last + 1]):
                scr.d[last, r, j] = scr.a[last + 1, r, j] - y[j]
        _backward(net, scr, m, alpha)
        _adam_step(net, opt, scr, lr)
        start += m


# ------------------------------------------------------------------------------- the driver

#: Rows per chunk when predicting (any size gives the same numbers: rows are independent).
_CHUNK = 256


class MLP:
    """A relu MLP with an identity output, as padded arrays.

    The layout of :class:`oneocean.tasks.learned.LearnedNet`: ``w[l, :dims[l], :dims[l+1]]``
    and ``b[l, :dims[l+1]]`` are layer ``l``'s weights (input, output) and biases.

    Parameters
    ----------
    w : (L, width, width) float64
        Layer weights, padded with zeros.
    b : (L, width) float64
        Layer biases, padded with zeros.
    dims : (L + 1,) int64
        Layer widths: inputs, hidden layers, outputs.
    """

    def __init__(self, w: np.ndarray, b: np.ndarray, dims: np.ndarray):
        self.w = np.ascontiguousarray(w, dtype=np.float64)
        self.b = np.ascontiguousarray(b, dtype=np.float64)
        self.dims = np.ascontiguousarray(dims, dtype=np.int64)

    @property
    def coefs_(self) -> list[np.ndarray]:
        """Layer weights ``(dims[l], dims[l+1])``, as scikit-learn names them."""
        d = self.dims
        return [self.w[k, :d[k], :d[k + 1]].copy() for k in range(len(d) - 1)]

    @property
    def intercepts_(self) -> list[np.ndarray]:
        """Layer biases ``(dims[l+1],)``."""
        d = self.dims
        return [self.b[k, :d[k + 1]].copy() for k in range(len(d) - 1)]

    def _scratch(self) -> np.ndarray:
        return np.zeros((len(self.dims), _CHUNK, self.w.shape[1]))

    def predict(self, Z: np.ndarray) -> np.ndarray:
        """The network's outputs for standardised features.

        The loop's forward pass (:func:`oneocean.tasks.learned.forward`), the same operations in
        the same order.

        Parameters
        ----------
        Z : (R, dims[0]) float64
            Standardised features.

        Returns
        -------
        (R, dims[-1]) float64
            Outputs (actions / ``v_max`` for the BC network).
        """
        Z = np.ascontiguousarray(Z, dtype=np.float64)
        n_layers = len(self.dims) - 1
        out = np.empty((Z.shape[0], int(self.dims[-1])))
        a = self._scratch()
        for start in range(0, Z.shape[0], _CHUNK):
            m = min(_CHUNK, Z.shape[0] - start)
            a[0, :m, :Z.shape[1]] = Z[start:start + m]
            _forward_batch(self.w, self.b, self.dims, a, m)
            out[start:start + m] = a[n_layers, :m, :out.shape[1]]
        return out

    def squared_errors(self, Z: np.ndarray, Y: np.ndarray) -> np.ndarray:
        """Per row, the squared error of the prediction summed over the outputs.

        Parameters
        ----------
        Z : (R, dims[0]) float64
            Standardised features.
        Y : (R, dims[-1]) float64
            Targets.

        Returns
        -------
        (R,) float64
            Squared errors, summed over the outputs in order.
        """
        out = np.empty(Z.shape[0])
        _squared_errors(self.w, self.b, self.dims, self._scratch(),
                        np.ascontiguousarray(Z, dtype=np.float64),
                        np.ascontiguousarray(Y, dtype=np.float64), out)
        return out


def mse(sq: np.ndarray, n_outputs: int) -> float:
    """Mean squared error over rows and outputs, summed in row order.

    Parameters
    ----------
    sq : (R,) float64
        Per-row squared errors summed over the outputs (:meth:`MLP.squared_errors`).
    n_outputs : int
        Outputs per row.

    Returns
    -------
    float
        The MSE (NaN without rows).
    """
    sq = np.ascontiguousarray(sq, dtype=np.float64)
    return float(ordered_sum(sq) / (sq.shape[0] * n_outputs)) if sq.shape[0] else float("nan")


def init_layers(dims, rng: np.random.RandomState) -> tuple[np.ndarray, np.ndarray]:
    """Glorot-uniform weights and biases, padded (scikit-learn's draws for a relu network).

    Per layer, ``(fan_in, fan_out)`` weights then ``fan_out`` biases from
    ``rng.uniform(-bound, bound)``, ``bound = sqrt(6 / (fan_in + fan_out))``.

    Parameters
    ----------
    dims : sequence of int
        Layer widths: inputs, hidden layers, outputs.
    rng : numpy.random.RandomState
        The draws' generator.

    Returns
    -------
    w : (L, width, width) float64
        Weights, zero-padded (``width = max(dims)``).
    b : (L, width) float64
        Biases, zero-padded.
    """
    dims = [int(d) for d in dims]
    width = max(dims)
    n_layers = len(dims) - 1
    w = np.zeros((n_layers, width, width))
    b = np.zeros((n_layers, width))
    for layer in range(n_layers):
        fan_in, fan_out = dims[layer], dims[layer + 1]
        bound = np.sqrt(6.0 / (fan_in + fan_out))
        w[layer, :fan_in, :fan_out] = rng.uniform(-bound, bound, (fan_in, fan_out))
        b[layer, :fan_out] = rng.uniform(-bound, bound, fan_out)
    return w, b


class Fit:
    """Adam on a relu MLP, one :meth:`epoch` at a time.

    Parameters
    ----------
    Z : (R, F) float64
        Standardised training features.
    Y : (R, K) float64
        Targets.
    hidden : sequence of int
        Hidden layer widths.
    batch_size : int
        Minibatch rows (clipped to ``[1, R]``).
    learning_rate : float
        Adam step size.
    alpha : float
        L2 penalty (``0.5 * alpha * |W|^2 / batch`` added to the loss).
    rng : numpy.random.RandomState
        Draws the initial weights (here) and every epoch's order (:meth:`epoch`).
    """

    def __init__(self, Z: np.ndarray, Y: np.ndarray, hidden, *, batch_size: int,
                 learning_rate: float, alpha: float, rng: np.random.RandomState):
        self.Z = np.ascontiguousarray(Z, dtype=np.float64)
        self.Y = np.ascontiguousarray(Y, dtype=np.float64)
        dims = np.asarray([self.Z.shape[1], *[int(h) for h in hidden], self.Y.shape[1]],
                          np.int64)
        self.rng = rng
        w, b = init_layers(dims, rng)
        self.net = Net(w, np.ascontiguousarray(w.transpose(0, 2, 1)), b, dims)
        self.opt = Adam(np.zeros_like(w), np.zeros_like(w), np.zeros_like(b),
                        np.zeros_like(b), np.array([0.0, 1.0, 1.0]))
        self.batch = int(min(max(int(batch_size), 1), self.Z.shape[0]))
        self.scr = Scratch(np.zeros((len(dims), self.batch, w.shape[1])),
                           np.zeros((len(dims) - 1, self.batch, w.shape[1])),
                           np.zeros_like(w), np.zeros_like(b))
        self.lr = float(learning_rate)
        self.alpha = float(alpha)

    def epoch(self) -> None:
        """One epoch: a fresh permutation of the rows, then one pass in that order.

        The permutation is ``rng.shuffle(arange(R))``; the pass runs minibatches of
        ``batch_size`` rows (the last one shorter), each a forward pass, a backward pass and an
        Adam step.
        """
        order = np.arange(self.Z.shape[0], dtype=np.int64)
        self.rng.shuffle(order)
        _epoch(self.net, self.opt, self.scr, self.Z, self.Y, order, self.batch, self.lr,
               self.alpha)

    def model(self) -> MLP:
        """A copy of the current network.

        Returns
        -------
        MLP
            The network's weights, biases and widths, copied.
        """
        return MLP(self.net.w.copy(), self.net.b.copy(), self.net.dims.copy())
