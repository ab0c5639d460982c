"""The loop's learned controller: a network over features of the public view.

A method given as the weights of a feed-forward network (``method kind learned``: behaviour
cloning, :mod:`oneocean.methods.bc`, trains one; any method that writes a weights file in
this layout runs the same way) acts inside the fused loop through this module, on exactly
what every method may know: each agent's observation row (:data:`oneocean.tasks.common.OBS_FIELDS`
and the task's own fields) and the briefing's time limit. It plans nothing: the target it
steers for is the task's own cue, updated by the task for every method. Everything here is a
plain ``hot_kernel`` function on arrays, used twice: by the loop, and by the training code
(through :func:`features_rows`) on recorded observations -- one implementation, so the
features a network is trained on are the features it acts on.

Features (:func:`feature_names`):

* ``goal_u{x,y,z}``: the cue offset ``g / (|g| + 1 m)`` (a unit vector far away, the offset
  itself in metres close in), ``goal_log_dist = log(1 + |g|)`` and ``goal_c{x,y,z}``, the
  offset clipped to ``CUE_CLIP_M`` (what a proportional law on the cue reads);
* ``current_{e,n}_ms``: the current estimate;
* ``depth_m``, ``altitude_m`` (NaN -> 0);
* ``pollution_log = log(1 + max(p, 0))`` and ``has_pollution`` (0 where the task has no field);
* per teammate ``m`` (nearest first): ``mate{m}_u{x,z}`` (offset / (d + 1 m)) and
  ``mate{m}_close = 1 / (1 + d)``; all 0 when there is no such teammate;
* ``time_left``: ``1 - t / t_lim`` (the briefing's time limit);
* ``extra{j}``: the task's own observation fields in their order (its ``OBS_EXTRA``: the
  energy used against the allocation, acoustic fixes, the attachment state, ...), non-finite
  values as 0, zeros after the task's last field (:data:`N_EXTRA` slots);
* ``task_<ID>``: one-hot over the tasks the network was trained on.

Not the vehicle's own velocity: it is mostly the last action's effect, so a network given it
learns to repeat itself (behaviour cloning's "copycat" confusion) and drifts once it errs.

The network's output is a through-water velocity request divided by the vehicle's ``v_max``
(a REMUS 100 and a BlueROV2 share one network); the loop multiplies it back by ``v_max``.
Features are standardised with the training set's mean and standard deviation
(:class:`LearnedNet` ``mu``, ``sd``), then ``relu`` hidden layers and an identity output,
exactly scikit-learn's ``MLPRegressor`` (``activation="relu"``). A weights file
(:func:`load_weights`) holds :data:`WEIGHT_KEYS`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..engine._jit import hot_kernel
from .common import N_MATES, OBS, OBS_DIM

#: Arrays of a weights file (:func:`load_weights`).
WEIGHT_KEYS = ("mu", "sd", "w", "b", "dims", "tasks", "features")

#: Feature names before the task one-hot (see the module docstring).
#: Slots for the task's own observation fields (the widest task's ``OBS_EXTRA``).
N_EXTRA = 8
#: The cue offset's clip, m (the clipped offset is the features ``goal_c{x,y,z}``).
CUE_CLIP_M = 20.0
BASE_FEATURES = (("goal_ux", "goal_uy", "goal_uz", "goal_log_dist", "goal_cx", "goal_cy",
                  "goal_cz", "current_e_ms",
                  "current_n_ms", "depth_m", "altitude_m", "pollution_log", "has_pollution")
                 + tuple(f"mate{m + 1}_{c}" for m in range(N_MATES)
                         for c in ("ux", "uz", "close"))
                 + ("time_left",)
                 + tuple(f"extra{j + 1}" for j in range(N_EXTRA)))
N_BASE = len(BASE_FEATURES)


def feature_names(tasks) -> tuple[str, ...]:
    """Every feature's name, the task one-hot last.

    Parameters
    ----------
    tasks : sequence of str
        The tasks of the one-hot, in order.

    Returns
    -------
    tuple of str
        ``BASE_FEATURES`` then ``task_<ID>`` per task.
    """
    return BASE_FEATURES + tuple(f"task_{t}" for t in tasks)


class LearnedNet(NamedTuple):
    """An MLP as arrays for the loop (``L`` layers, widths ``dims``), plus its scratch.

    ``w[l, :dims[l], :dims[l+1]]`` and ``b[l, :dims[l+1]]`` are layer ``l``'s weights and bias
    (scikit-learn's ``coefs_[l]`` / ``intercepts_[l]``); ``task`` is this rollout's index in
    the one-hot of ``n_tasks``; ``obs`` (E, 1, N, OBS_DIM), ``act`` and ``buf`` (E, 2, width) are
    per-episode scratch (an episode is computed by one thread)."""
    mu: np.ndarray      # (F,) feature means of the training set
    sd: np.ndarray      # (F,) feature standard deviations (>= 1e-9)
    w: np.ndarray       # (L, width, width) float64
    b: np.ndarray       # (L, width) float64
    dims: np.ndarray    # (L + 1,) int64 layer widths, dims[0] = F, dims[L] = 3
    task: int           # index of this rollout's task in the one-hot
    n_tasks: int        # size of the one-hot
    buf: np.ndarray     # (E, 2, width) activation scratch


def load_weights(path) -> dict:
    """The arrays of a network weights file.

    Parameters
    ----------
    path : str or Path
        An ``.npz`` holding :data:`WEIGHT_KEYS`, as
        :func:`oneocean.methods.bc.train.write_weights` writes it.

    Returns
    -------
    dict
        Every array of the file by name.

    Raises
    ------
    ConfigError
        One line naming the file when it is missing, unreadable or lacks a key of
        :data:`WEIGHT_KEYS`.
    """
    from ..errors import ConfigError

    try:
        with np.load(path, allow_pickle=False) as z:
            out = {k: z[k] for k in z.files}
    except (OSError, ValueError) as exc:
        raise ConfigError(f"{path}: not a network weights file ({exc.__class__.__name__}: "
                          f"{str(exc).splitlines()[0] if str(exc) else ''})") from None
    missing = [k for k in WEIGHT_KEYS if k not in out]
    if missing:
        raise ConfigError(f"{path}: network weights file lacks {', '.join(missing)}")
    return out


def no_net() -> LearnedNet:
    """The placeholder network the loop carries for every method that is not a network.

    Returns
    -------
    LearnedNet
        A minimal network of the same numba type as a real one, so all methods share one
        compiled kernel.
    """
    return LearnedNet(np.zeros(1), np.ones(1), np.zeros((1, 1, 1)), np.zeros((1, 1)),
                      np.zeros(2, np.int64), 0, 1, np.zeros((1, 2, 1)))


def make_net(weights: dict, task: str, n_episodes: int, n_agents: int) -> LearnedNet:
    """The loop's :class:`LearnedNet` for a task from a weights file's arrays.

    Parameters
    ----------
    weights : dict
        The arrays of a weights file (:func:`load_weights`): ``mu``, ``sd``, ``w``, ``b``,
        ``dims``, ``tasks``.
    task : str
        The rollout's task id.
    n_episodes : int
        Episodes E of the rollout (the scratch's leading axis).
    n_agents : int
        Agents N.

    Returns
    -------
    LearnedNet
        The network with per-episode scratch.

    Raises
    ------
    NotApplicable
        One line when the network was not trained on ``task`` (a ConfigError subclass: the
        cell is written not applicable with this reason).
    """
    from ..errors import NotApplicable

    tasks = [str(t) for t in weights["tasks"]]
    if task not in tasks:
        # a cell, not a crash: on a small region the teacher had no episodes of this task
        # (e.g. a scene cell of G2G when the region hosts no G2G training episodes)
        raise NotApplicable(f"learned controller: the network was trained on tasks {tasks}, "
                            f"not on {task!r}")
    width = int(weights["w"].shape[1])
    return LearnedNet(np.ascontiguousarray(weights["mu"], dtype=np.float64),
                 np.ascontiguousarray(weights["sd"], dtype=np.float64),
                 np.ascontiguousarray(weights["w"], dtype=np.float64),
                 np.ascontiguousarray(weights["b"], dtype=np.float64),
                 np.ascontiguousarray(weights["dims"], dtype=np.int64),
                      tasks.index(task), len(tasks), np.zeros((n_episodes, 2, width)))


@hot_kernel(inline="always")
def _finite(v):
    return v if math.isfinite(v) else 0.0


_LN2_HI = 6.93147180369123816490e-01   # fdlibm's split of log(2)
_LN2_LO = 1.90821492927058770002e-10
_SQRT2 = 1.4142135623730951


@hot_kernel(inline="always")
def log1p_pos(x):
    """``log(1 + x)`` for ``x >= 0`` in plain arithmetic, the same bits on every CPU.

    libm's ``log1p`` has FMA and non-FMA variants that differ in the last bit.
    ``1 + x = m 2^k`` with ``m`` in ``[1, sqrt 2)`` (exact halvings), the rounding of ``1 + x``
    corrected as fdlibm does, and ``log m = 2 atanh(s)``, ``s = (m - 1) / (m + 1)``, by its
    series to ``s^21`` (``|s| < 0.172``: truncation below 1e-17). Within 2 ulp of libm.

    Parameters
    ----------
    x : float
        Argument, >= 0.

    Returns
    -------
    float
        ``log(1 + x)``; ``x`` itself for ``x >= 1e300``, inf or NaN.
    """
    if not x < 1e300:
        return x
    y = 1.0 + x
    c = (x - (y - 1.0)) / y
    m = y
    k = 0
    while m >= _SQRT2:
        m *= 0.5
        k += 1
    s = (m - 1.0) / (m + 1.0)
    z = s * s
    p = 1.0 / 21.0
    for j in range(19, 0, -2):
        p = 1.0 / j + z * p
    return k * _LN2_HI + (2.0 * s * p + (c + k * _LN2_LO))


@hot_kernel
def featurize(o, t_lim, task, n_tasks, out):
    """The features (:func:`feature_names`) of one observation row.

    Parameters
    ----------
    o : (D,) float64
        Observation row (:data:`oneocean.tasks.common.OBS_FIELDS`, then the task's own
        fields).
    t_lim : float
        The briefing's time limit, s.
    task : int
        Index of the row's task in the one-hot.
    n_tasks : int
        Size of the one-hot.
    out : (F,) float64
        Features, written in place.
    """
    gx = _finite(o[0])
    gy = _finite(o[1])
    gz = _finite(o[2])
    d = math.sqrt(gx * gx + gy * gy + gz * gz)
    out[0] = gx / (d + 1.0)
    out[1] = gy / (d + 1.0)
    out[2] = gz / (d + 1.0)
    out[3] = log1p_pos(d)
    out[4] = min(max(gx, -CUE_CLIP_M), CUE_CLIP_M)
    out[5] = min(max(gy, -CUE_CLIP_M), CUE_CLIP_M)
    out[6] = min(max(gz, -CUE_CLIP_M), CUE_CLIP_M)
    out[7] = _finite(o[3])
    out[8] = _finite(o[4])
    out[9] = _finite(o[5])
    out[10] = _finite(o[6])
    p = o[7]
    if math.isfinite(p):
        out[11] = log1p_pos(max(p, 0.0))
        out[12] = 1.0
    else:
        out[11] = 0.0
        out[12] = 0.0
    for m in range(N_MATES):
        dx = o[8 + 2 * m]
        dz = o[9 + 2 * m]
        j = 13 + 3 * m
        if math.isfinite(dx) and math.isfinite(dz):
            dm = math.sqrt(dx * dx + dz * dz)
            out[j] = dx / (dm + 1.0)
            out[j + 1] = dz / (dm + 1.0)
            out[j + 2] = 1.0 / (1.0 + dm)
        else:
            out[j] = 0.0
            out[j + 1] = 0.0
            out[j + 2] = 0.0
    j = 13 + 3 * N_MATES
    out[j] = 1.0 - _finite(o[20]) / t_lim if t_lim > 0.0 else 0.0
    j += 1
    n_x = o.shape[0] - OBS_DIM
    for q in range(N_EXTRA):
        out[j + q] = _finite(o[OBS_DIM + q]) if q < n_x else 0.0
    for t in range(n_tasks):
        out[N_BASE + t] = 1.0 if t == task else 0.0


@hot_kernel(inline="always")
def dense_layer(wl, bl, x, o, n_in, n_out, relu):
    """One layer, ``o = relu?(bl + x @ wl)``, in a fixed order of operations.

    Per output the bias, then each non-zero input times its weight row, inputs in order (the
    inner loop runs over contiguous weights and independent outputs, so it vectorises without
    reordering any sum; the zeros relu leaves in the input are skipped). The in-loop forward
    pass and the training's (:mod:`oneocean.methods.bc.fit`) both use it, so their outputs
    agree bit for bit.

    Parameters
    ----------
    wl : (>= n_in, >= n_out) float64
        Weights, row ``q`` for input ``q``.
    bl : (>= n_out,) float64
        Bias.
    x : (>= n_in,) float64
        Input.
    o : (>= n_out,) float64
        Output, written in place (not aliasing ``x``).
    n_in, n_out : int
        Layer widths.
    relu : bool
        Apply ``relu`` to the output.
    """
    for j in range(n_out):
        o[j] = bl[j]
    for q in range(n_in):
        s = x[q]
        if s != 0.0:
            wq = wl[q]
            for j in range(n_out):
                o[j] += s * wq[j]
    if relu:
        for j in range(n_out):
            if o[j] < 0.0:
                o[j] = 0.0


@hot_kernel
def forward(net, x, h):
    """The network's output for standardised features: ``relu`` hidden layers, identity output.

    Parameters
    ----------
    net : LearnedNet
        The network.
    x : (F,) float64
        Standardised features; may be ``h[0]``.
    h : (2, width) float64
        Activation scratch.

    Returns
    -------
    ax, ay, az : float
        The output: a through-water velocity request in units of ``v_max``.
    """
    n_layers = net.dims.shape[0] - 1
    cur = 0
    src = x
    for layer in range(n_layers):
        n_in = net.dims[layer]
        n_out = net.dims[layer + 1]
        dst = h[1 - cur]
        dense_layer(net.w[layer], net.b[layer], src, dst, n_in, n_out, layer < n_layers - 1)
        src = dst
        cur = 1 - cur
    return src[0], src[1], src[2]


@hot_kernel
def learned_act(net, t_lim, O, e, i, v_max):
    """Agent ``i``'s action from its observation ``O[e, i]`` and the briefing's time limit:
    features, standardisation, forward pass, times ``v_max``. (Plain arguments, no task's
    types: one cached copy serves every task, a plugin's too.)

    Parameters
    ----------
    net : LearnedNet
        The network with its scratch.
    t_lim : float
        The briefing's time limit, s.
    O : (E, N, D) float64
        This step's observations.
    e, i : int
        Episode and agent.
    v_max : float
        The vehicle's speed limit, m s-1.

    Returns
    -------
    ax, ay, az : float
        World-frame through-water velocity request, m s-1 (not clipped; the loop clips it).
    """
    h = net.buf[e]
    x = h[0]
    featurize(O[e, i], t_lim, net.task, net.n_tasks, x)
    for q in range(net.dims[0]):
        x[q] = (x[q] - net.mu[q]) / net.sd[q]
    ax, ay, az = forward(net, x, h)
    return ax * v_max, ay * v_max, az * v_max


@hot_kernel
def features_rows(obs, t_lim, task, n_tasks, out):
    """:func:`featurize` for every row of an observation matrix.

    Parameters
    ----------
    obs : (R, D) float64
        Observation rows.
    t_lim : float
        The briefing's time limit, s.
    task, n_tasks : int
        The rows' task in the one-hot, and its size.
    out : (R, F) float64
        Features, written.
    """
    for r in range(obs.shape[0]):
        featurize(obs[r], t_lim, task, n_tasks, out[r])
