"""Controllers that run inside the jitted rollout loop, selected by an int kind.

Every controller writes a raw command ``[ax, ay, az, psi_cmd, thrust]`` (see
:mod:`oneocean.engine.dynamics`): a desired velocity relative to the water in world
coordinates (m s-1; the rollout clips it to ``v_max``), a heading (rad, NaN = automatic) and a
thrust switch.

Kinds
-----
``GOAL`` (0)
    P-control toward per-agent goals: ``a = kp (goal - p) - ff * c`` where ``c`` is the probed
    current at the agent (current feed-forward when ``ff = 1``). ``goals`` (E, A, 4):
    x, y, z (m) and heading (rad, NaN = face the direction of travel).
``MLP`` (1)
    A tanh MLP on the features ``[goal - p (3), ce, cn, y, extra...]`` (m, m s-1, m), inputs
    standardised with stored mean/std, linear output times ``out_scale`` (m s-1). Weights are
    packed by :func:`pack_mlp`.
``PLAN`` (2)
    Follows per-agent waypoint lists ``plan`` (E, A, W, 3) with ``plan_len`` (E, A) valid
    entries: GOAL control toward waypoint ``wp_idx``, advancing when within ``wp_radius``.
    An outer Python loop may rewrite the plans between segments (every K steps).
``OPEN_LOOP`` (3)
    Prescribed actions ``actions`` (S, E, A, 3) for the S steps of one :func:`run` call.

Any kind can run with ``thrust = False`` (the unactuated vehicle drifts; zero action).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError
from ._jit import hot_kernel

GOAL, MLP, PLAN, OPEN_LOOP = 0, 1, 2, 3
KINDS = {"goal": GOAL, "mlp": MLP, "plan": PLAN, "open_loop": OPEN_LOOP}

CP_KP = 0          # position gain, s-1
CP_FF = 1          # 1 = subtract the probed current (feed-forward)
CP_WP_RADIUS = 2   # waypoint acceptance radius, m
CP_THRUST = 3      # 1 = thrust on, 0 = unactuated
CP_OUT_SCALE = 4   # MLP output scale, m s-1
CP_DIM = 8

N_BASE_FEATURES = 6  # goal delta (3), ce, cn, depth


@dataclass
class Controller:
    """A controller spec: kind, parameter vector and its arrays (episodes E, agents A).

    Arrays may be rewritten in place between :func:`oneocean.engine.rollout.run` segments
    (e.g. ``ctrl.goals[...] = ...`` or a new plan).
    """

    kind: int
    params: np.ndarray
    goals: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 4)))
    plan: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0, 3)))
    plan_len: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), np.int64))
    mlp_sizes: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    mlp_weights: np.ndarray = field(default_factory=lambda: np.zeros(0))
    features: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0)))
    actions: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0, 3)))

    def describe(self) -> dict:
        """JSON-able summary for manifests."""
        name = {v: k for k, v in KINDS.items()}[self.kind]
        d = {"kind": name, "kp": float(self.params[CP_KP]),
             "feedforward": bool(self.params[CP_FF]), "thrust": bool(self.params[CP_THRUST])}
        if self.kind == PLAN:
            d["wp_radius_m"] = float(self.params[CP_WP_RADIUS])
        if self.kind == MLP:
            d["mlp_sizes"] = [int(v) for v in self.mlp_sizes]
            d["out_scale_ms"] = float(self.params[CP_OUT_SCALE])
        return d


def _params(kp=0.0, feedforward=False, wp_radius=0.0, thrust=True, out_scale=1.0):
    p = np.zeros(CP_DIM)
    p[CP_KP] = float(kp)
    p[CP_FF] = 1.0 if feedforward else 0.0
    p[CP_WP_RADIUS] = float(wp_radius)
    p[CP_THRUST] = 1.0 if thrust else 0.0
    p[CP_OUT_SCALE] = float(out_scale)
    if not np.all(np.isfinite(p)) or kp < 0 or wp_radius < 0:
        raise ConfigError(f"controller: gains must be finite and >= 0 (kp={kp}, "
                          f"wp_radius={wp_radius}, out_scale={out_scale})")
    return p


def _goals4(goals) -> np.ndarray:
    g = np.asarray(goals, dtype=np.float64)
    if g.ndim != 3 or g.shape[2] not in (3, 4):
        raise ConfigError(f"goals: expected shape (episodes, agents, 3 or 4), got {g.shape}")
    if g.shape[2] == 3:
        g = np.concatenate([g, np.full(g.shape[:2] + (1,), np.nan)], axis=2)
    if not np.all(np.isfinite(g[..., :3])):
        raise ConfigError("goals: positions must be finite")
    return np.ascontiguousarray(g)


def goal_controller(goals, kp: float = 0.3, feedforward: bool = True,
                    thrust: bool = True) -> Controller:
    """P-control toward ``goals`` (E, A, 3|4) m [+ heading rad] with gain ``kp`` (s-1)."""
    return Controller(GOAL, _params(kp, feedforward, thrust=thrust), goals=_goals4(goals))


def drift_controller(n_episodes: int, n_agents: int) -> Controller:
    """Thrust off: an unactuated vehicle that drifts with the current."""
    return Controller(GOAL, _params(0.0, False, thrust=False),
                      goals=np.zeros((n_episodes, n_agents, 4)))


def plan_controller(plan, plan_len=None, kp: float = 0.3, wp_radius: float = 5.0,
                    feedforward: bool = True, thrust: bool = True) -> Controller:
    """Waypoint following of ``plan`` (E, A, W, 3) m with ``plan_len`` (E, A) valid entries."""
    pl = np.ascontiguousarray(plan, dtype=np.float64)
    if pl.ndim != 4 or pl.shape[3] != 3 or pl.shape[2] < 1:
        raise ConfigError("plan: expected shape (episodes, agents, waypoints>=1, 3), "
                          f"got {pl.shape}")
    if plan_len is None:
        plan_len = np.full(pl.shape[:2], pl.shape[2], dtype=np.int64)
    n = np.ascontiguousarray(plan_len, dtype=np.int64)
    if n.shape != pl.shape[:2] or np.any(n < 1) or np.any(n > pl.shape[2]):
        raise ConfigError(f"plan_len: expected shape {pl.shape[:2]} with values in "
                          f"[1, {pl.shape[2]}], got shape {n.shape}")
    return Controller(PLAN, _params(kp, feedforward, wp_radius, thrust), plan=pl, plan_len=n)


def open_loop_controller(actions, thrust: bool = True) -> Controller:
    """Prescribed actions (S, E, A, 3) m s-1 for the S steps of one run call."""
    a = np.ascontiguousarray(actions, dtype=np.float64)
    if a.ndim != 4 or a.shape[3] != 3:
        raise ConfigError(f"actions: expected shape (steps, episodes, agents, 3), got {a.shape}")
    return Controller(OPEN_LOOP, _params(thrust=thrust), actions=a)


def pack_mlp(weights, biases, in_mean=None, in_std=None) -> tuple[np.ndarray, np.ndarray]:
    """Pack an MLP into (sizes int64 (L+1,), flat float64) for the kernel.

    ``weights[l]`` has shape (n_l, n_{l+1}) (input-major, ``h_{l+1} = h_l @ W + b``), the last
    layer must output 3 values; hidden layers use tanh, the output is linear.
    """
    if len(weights) != len(biases) or not weights:
        raise ConfigError("mlp: need as many bias vectors as weight matrices (>= 1)")
    sizes = [int(np.shape(weights[0])[0])]
    for l, (w, b) in enumerate(zip(weights, biases)):
        w = np.asarray(w, dtype=np.float64)
        b = np.asarray(b, dtype=np.float64)
        if w.ndim != 2 or w.shape[0] != sizes[-1] or b.shape != (w.shape[1],):
            raise ConfigError(f"mlp layer {l}: weight {w.shape} / bias {b.shape} do not chain "
                              f"from width {sizes[-1]}")
        sizes.append(w.shape[1])
    if sizes[-1] != 3:
        raise ConfigError(f"mlp: output width must be 3 (ax, ay, az), got {sizes[-1]}")
    n0 = sizes[0]
    mean = np.zeros(n0) if in_mean is None else np.asarray(in_mean, dtype=np.float64)
    std = np.ones(n0) if in_std is None else np.asarray(in_std, dtype=np.float64)
    if mean.shape != (n0,) or std.shape != (n0,) or np.any(~(std > 0)):
        raise ConfigError(f"mlp: in_mean/in_std must have shape ({n0},), std > 0")
    flat = [mean, 1.0 / std] + [np.concatenate([np.asarray(w, np.float64).ravel(),
                                                np.asarray(b, np.float64)])
                                for w, b in zip(weights, biases)]
    out = np.concatenate(flat)
    if not np.all(np.isfinite(out)):
        raise ConfigError("mlp: weights must be finite")
    return np.asarray(sizes, dtype=np.int64), out


def mlp_controller(weights, biases, goals, in_mean=None, in_std=None, features=None,
                   out_scale: float = 1.0, thrust: bool = True) -> Controller:
    """MLP policy (see module docs); ``features`` (E, A, n_extra) are appended to the base 6."""
    sizes, flat = pack_mlp(weights, biases, in_mean, in_std)
    g = _goals4(goals)
    if features is None:
        features = np.zeros(g.shape[:2] + (0,))
    f = np.ascontiguousarray(features, dtype=np.float64)
    if f.ndim != 3 or f.shape[:2] != g.shape[:2]:
        raise ConfigError(f"features: expected shape {g.shape[:2] + ('n_extra',)}, got {f.shape}")
    if sizes[0] != N_BASE_FEATURES + f.shape[2]:
        raise ConfigError(f"mlp: input width {sizes[0]} != {N_BASE_FEATURES} base features + "
                          f"{f.shape[2]} extra")
    return Controller(MLP, _params(thrust=thrust, out_scale=out_scale), goals=g,
                      mlp_sizes=sizes, mlp_weights=flat, features=f)


def mlp_forward_py(sizes, flat, x) -> np.ndarray:
    """Plain-NumPy forward pass of a packed MLP (reference for tests)."""
    n0 = int(sizes[0])
    h = (np.asarray(x, dtype=np.float64) - flat[:n0]) * flat[n0:2 * n0]
    o = 2 * n0
    for l in range(len(sizes) - 1):
        a, b = int(sizes[l]), int(sizes[l + 1])
        w = flat[o:o + a * b].reshape(a, b)
        o += a * b
        h = h @ w + flat[o:o + b]
        o += b
        if l < len(sizes) - 2:
            h = np.tanh(h)
    return h


@hot_kernel
def mlp_forward(sizes, flat, buf, nin):
    """Forward pass on ``buf[0:nin]`` (raw features); returns the offset of the 3 outputs in buf.

    ``buf`` must hold ``2 * max(sizes)`` floats; layers ping-pong between its halves.
    """
    half = buf.shape[0] // 2
    n0 = sizes[0]
    for i in range(nin):
        buf[i] = (buf[i] - flat[i]) * flat[n0 + i]
    o = 2 * n0
    src = 0
    dst = half
    nl = sizes.shape[0] - 1
    for layer in range(nl):
        a = sizes[layer]
        b = sizes[layer + 1]
        for j in range(b):
            acc = flat[o + a * b + j]
            for i in range(a):
                acc += buf[src + i] * flat[o + i * b + j]
            if layer < nl - 1:
                acc = np.tanh(acc)
            buf[dst + j] = acc
        o += a * b + b
        src, dst = dst, src
    return src


@hot_kernel(inline="always")
def compute_command(kind, cp, ei, ai, k, s, ce, cn, goals, plan, plan_len, wp_idx,
                    mlp_sizes, mlp_w, feats, actions, buf, cmd):
    """Write agent ``ai`` of episode ``ei``'s raw command into ``cmd`` (CMD_DIM,).

    ``k`` is the step index within the current run call (for OPEN_LOOP); ``s`` the agent's
    state row; (ce, cn) the probed current (m s-1). ``wp_idx`` (E, A) is updated by PLAN.
    """
    cmd[3] = np.nan
    cmd[4] = cp[CP_THRUST]
    x = s[0]
    y = s[1]
    z = s[2]
    if kind == OPEN_LOOP:
        cmd[0] = actions[k, ei, ai, 0]
        cmd[1] = actions[k, ei, ai, 1]
        cmd[2] = actions[k, ei, ai, 2]
        return
    if kind == PLAN:
        w = wp_idx[ei, ai]
        gx = plan[ei, ai, w, 0]
        gy = plan[ei, ai, w, 1]
        gz = plan[ei, ai, w, 2]
        r = cp[CP_WP_RADIUS]
        if w < plan_len[ei, ai] - 1 and (gx - x) ** 2 + (gy - y) ** 2 + (gz - z) ** 2 <= r * r:
            w += 1
            wp_idx[ei, ai] = w
            gx = plan[ei, ai, w, 0]
            gy = plan[ei, ai, w, 1]
            gz = plan[ei, ai, w, 2]
    else:
        gx = goals[ei, ai, 0]
        gy = goals[ei, ai, 1]
        gz = goals[ei, ai, 2]
        cmd[3] = goals[ei, ai, 3]
    if kind == MLP:
        buf[0] = gx - x
        buf[1] = gy - y
        buf[2] = gz - z
        buf[3] = ce
        buf[4] = cn
        buf[5] = y
        nx = feats.shape[2]
        for i in range(nx):
            buf[6 + i] = feats[ei, ai, i]
        o = mlp_forward(mlp_sizes, mlp_w, buf, 6 + nx)
        sc = cp[CP_OUT_SCALE]
        cmd[0] = sc * buf[o]
        cmd[1] = sc * buf[o + 1]
        cmd[2] = sc * buf[o + 2]
        return
    kp = cp[CP_KP]
    ax = kp * (gx - x)
    ay = kp * (gy - y)
    az = kp * (gz - z)
    if cp[CP_FF] != 0.0:
        ax -= ce
        az -= cn
    cmd[0] = ax
    cmd[1] = ay
    cmd[2] = az
