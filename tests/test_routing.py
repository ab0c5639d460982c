"""The route planner (oneocean.tasks.routing) on hand-made fields: the straight line in a
uniform current, a jet across and along the straight line, land, time-varying fields, the
power model, the forecast mapping, path following, bit-for-bit determinism, and the compiled
search against the same search written plainly (heapq, no pruning)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from oneocean.tasks import routing as R

H = 50.0
X0 = Z0 = -2000.0
N = 81   # 4 km x 4 km lattice


def _field(ce=0.0, cn=0.0, n=N):
    cur = np.zeros((1, n, n, 2))
    cur[..., 0] = ce
    cur[..., 1] = cn
    return cur, np.array([0.0]), np.ones((n, n))


def _coords(n=N):
    return X0 + H * np.arange(n)


def _free_along(free, path, step=1.0):
    """The bilinear passability margin every ``step`` m along a polyline."""
    out = []
    for a, b in zip(path[:-1], path[1:]):
        L = float(np.hypot(*(b - a)))
        for s in np.linspace(0.0, L, max(2, int(L / step) + 1)):
            p = a + (b - a) * s / L if L > 0 else a
            out.append(R._free(free, X0, Z0, H, p[0], p[1]))
    return np.array(out)


# ------------------------------------------------------------------------------ uniform

@pytest.mark.parametrize("ce, cn, start, goal", [
    (0.3, -0.4, (-1500.0, -1234.5), (1333.0, 1500.0)),
    (-0.6, 0.2, (1700.0, 250.0), (-1650.0, -900.0)),
    (0.0, 0.0, (-100.0, -100.0), (1800.0, 40.0)),
])
def test_uniform_current_straight_line_is_optimal(ce, cn, start, goal):
    cur, t, free = _field(ce, cn)
    r = R.plan_route(cur, t, free, X0, Z0, H, start, goal, 1.0, 0.0)
    assert r.ok
    np.testing.assert_array_equal(r.path, [start, goal])      # one straight segment
    d = np.subtract(goal, start)
    D = float(np.hypot(*d))
    g = R.ground_speed(ce, cn, d[0] / D, d[1] / D, 1.0)
    # ground speed of the crab: along-track current plus what the cross current leaves
    c_par = (ce * d[0] + cn * d[1]) / D
    assert math.isclose(g, c_par + math.sqrt(1.0 - (ce * ce + cn * cn - c_par ** 2)))
    np.testing.assert_allclose(r.t[-1], D / g, rtol=1e-12)
    np.testing.assert_allclose(r.cost, D / g, rtol=1e-12)
    # the straight line's own cost is the same
    assert math.isclose(R.route_cost(cur, t, free, X0, Z0, H, [start, goal], 1.0, 0.0), D / g,
                        rel_tol=1e-12)


def test_uniform_current_least_energy_speed():
    # with a power model the route is still the straight line, flown at the speed with the
    # least energy per metre, P(u) / g(u)
    cur, t, free = _field(-0.8, 0.3)
    speeds = R.mission_speeds(2.5)
    pw = (23.5, 5.96)
    start, goal = (-1500.0, 0.0), (1500.0, 0.0)              # against the current
    r = R.plan_route(cur, t, free, X0, Z0, H, start, goal, speeds, 0.0, power=pw, hold=0.1)
    assert r.ok and np.all(r.path[:, 1] == 0.0)
    assert r.path[0, 0] == start[0] and r.path[-1, 0] == goal[0]
    g = [R.ground_speed(-0.8, 0.3, 1.0, 0.0, u) for u in speeds]
    per_m = [(pw[0] + pw[1] * u ** 3) / gu if gu > R.G_MIN and u - 0.3 >= 0.1 else np.inf
             for u, gu in zip(speeds, g)]
    best = speeds[int(np.argmin(per_m))]
    assert best > 1.25                                      # a head current: faster than cruise
    np.testing.assert_array_equal(r.speed, best)
    np.testing.assert_allclose(r.cost, 3000.0 * min(per_m), rtol=1e-12)


# ------------------------------------------------------------------------------ jets

def test_head_jet_along_the_straight_line_is_avoided():
    # a 0.8 m/s head current in the band |z| <= 100 m along the straight line, calm outside
    cur, t, free = _field()
    zs = _coords()
    cur[0, np.abs(zs) <= 100.0, :, 0] = 0.8
    start, goal = (1000.0, 0.0), (-1000.0, 0.0)
    u = 1.0
    straight = R.route_cost(cur, t, free, X0, Z0, H, [start, goal], u, 0.0)
    np.testing.assert_allclose(straight, 2000.0 / (u - 0.8), rtol=1e-12)   # 10 000 s
    r = R.plan_route(cur, t, free, X0, Z0, H, start, goal, u, 0.0)
    # a route that leaves the jet: across it (150 m, where the bilinear current ends) at
    # the crab's ground speed sqrt(u^2 - 0.8^2) at worst, 2 km in calm water, and back
    bound = 2 * 150.0 / math.sqrt(u * u - 0.8 ** 2) + 2000.0 / u + 2 * 2 * H / u
    assert r.ok and r.t[-1] <= bound
    assert r.t[-1] < 0.3 * straight                          # the margin the plan buys
    # and it really leaves the jet
    assert np.max(np.abs(r.path[:, 1])) >= 150.0


def test_following_jet_off_the_line_is_used():
    # a 1.5 m/s following current in the band 300 <= z <= 500 m, calm on the straight line
    cur, t, free = _field()
    zs = _coords()
    cur[0, (zs >= 300.0) & (zs <= 500.0), :, 0] = 1.5
    start, goal = (-1500.0, 0.0), (1500.0, 0.0)
    u = 1.0
    straight = R.route_cost(cur, t, free, X0, Z0, H, [start, goal], u, 0.0)
    np.testing.assert_allclose(straight, 3000.0 / u, rtol=1e-12)
    r = R.plan_route(cur, t, free, X0, Z0, H, start, goal, u, 0.0)
    # through the jet: 2 x ~500 m of diagonal legs at >= u, 2 km at u + 1.5, computed bound
    bound = 2 * math.hypot(500.0, 400.0) / u + 2000.0 / (u + 1.5)
    assert r.ok and r.t[-1] <= bound < straight
    assert np.max(r.path[:, 1]) >= 300.0                     # it rides the jet


# ------------------------------------------------------------------------------ land

def test_land_is_never_crossed():
    # a wall of land across the straight line with a 300 m gap near its north end
    cur, t, free = _field(0.2, 0.0)
    xs = _coords()
    zs = _coords()
    wall = (np.abs(xs) <= 100.0)[None, :] & (zs <= 1200.0)[:, None]
    free[wall] = -1.0
    start, goal = (-1500.0, 0.0), (1500.0, 0.0)
    assert math.isinf(R.route_cost(cur, t, free, X0, Z0, H, [start, goal], 1.0, 0.0))
    r = R.plan_route(cur, t, free, X0, Z0, H, start, goal, 1.0, 0.0)
    assert r.ok and math.isfinite(r.t[-1])
    assert np.all(_free_along(free, r.path) > 0.0)           # every metre in water
    assert np.max(r.path[:, 1]) > 1200.0                     # through the gap
    # no way through at all: unreachable, the straight line returned with ok False
    free[wall | (np.abs(xs) <= 100.0)[None, :]] = -1.0
    r = R.plan_route(cur, t, free, X0, Z0, H, start, goal, 1.0, 0.0)
    assert not r.ok and math.isinf(r.t[-1]) and math.isinf(r.cost)
    np.testing.assert_array_equal(r.path, [start, goal])


def test_current_stronger_than_the_vehicle_is_impassable():
    cur, t, free = _field(0.0, 1.2)                          # across an east-west track
    r = R.plan_route(cur, t, free, X0, Z0, H, (-1000.0, 0.0), (1000.0, 0.0), 1.0, 0.0)
    assert not r.ok
    # with speed in hand it is passable, and the plan keeps the cross-current headroom
    r = R.plan_route(cur, t, free, X0, Z0, H, (-1000.0, 0.0), (1000.0, 0.0),
                     R.mission_speeds(2.5), 0.0, power=(23.5, 5.96), hold=0.1)
    assert r.ok and np.all(r.speed >= 1.3)


# ------------------------------------------------------------------------------ time

def test_time_varying_field_is_integrated_in_time():
    # calm for the first 1000 s, then a 0.5 m/s following current: straight-line time
    cur = np.zeros((2, N, N, 2))
    cur[1, ..., 0] = 0.5
    times = np.array([1000.0, 1000.0 + 1e-6])
    free = np.ones((N, N))
    r = R.plan_route(cur, times, free, X0, Z0, H, (-1500.0, 0.0), (1500.0, 0.0), 1.0, 0.0,
                     piece=10.0)
    # 1000 m in the calm, 2000 m at 1.5 m/s (to the piece's resolution)
    assert r.ok and abs(r.t[-1] - (1000.0 + 2000.0 / 1.5)) < 10.0
    later = R.plan_route(cur, times, free, X0, Z0, H, (-1500.0, 0.0), (1500.0, 0.0), 1.0,
                         1001.0)
    np.testing.assert_allclose(later.t[-1] - 1001.0, 2000.0, rtol=1e-12)


def _random_field(seed=3, nt=4):
    rng = np.random.default_rng(seed)
    # a smooth random field: a few Fourier modes, varying in time
    xs = _coords()
    X, Z = np.meshgrid(xs, xs)
    cur = np.zeros((nt, N, N, 2))
    for k in range(nt):
        for _ in range(4):
            kx, kz = rng.normal(size=2) / 1500.0
            ph = rng.uniform(0, 2 * np.pi)
            a = rng.normal(size=2) * 0.4
            cur[k, ..., 0] += a[0] * np.sin(kx * X + kz * Z + ph + 0.3 * k)
            cur[k, ..., 1] += a[1] * np.cos(kx * X - kz * Z + ph - 0.2 * k)
    free = np.ones((N, N))
    free[30:45, 38:42] = -1.0
    return cur, 3600.0 * np.arange(nt), free


def test_deterministic_bit_for_bit():
    cur, times, free = _random_field()
    args = (cur, times, free, X0, Z0, H, (-1700.0, -1300.0), (1600.0, 1500.0))
    for power in (None, (23.5, 5.96)):
        a = R.plan_route(*args, R.mission_speeds(2.5), 500.0, power=power, hold=0.1)
        b = R.plan_route(*args, R.mission_speeds(2.5), 500.0, power=power, hold=0.1)
        assert a.ok
        for k in ("path", "speed", "t"):
            assert np.array_equal(getattr(a, k), getattr(b, k)), k
        assert a.cost == b.cost
        assert np.all(_free_along(free, a.path, 5.0) > 0.0)
        # never worse than the straight line it could have taken
        s = R.route_cost(*args[:6], [args[6], args[7]], R.mission_speeds(2.5), 500.0,
                         power=power, hold=0.1)
        assert a.cost <= s


def _plain_dijkstra(cur, times, free, sx, sz, gx, gz, speeds, ph, pk, hold, t0, step):
    """The planner's search written plainly: heapq on (cost, node), every edge of every
    settled node integrated (no lower-bound pruning), the compiled segment integrator."""
    import heapq

    nos = np.empty(0, np.int64)
    ny, nx = free.shape

    def seg(ax, az, bx, bz, t, first):
        return R._segment(cur, times, free, X0, Z0, H, ax, az, bx, bz, speeds, ph, pk, hold,
                          t, step, first, nos)

    cost = np.full(ny * nx, np.inf)
    tarr = np.full(ny * nx, np.inf)
    parent = np.full(ny * nx, -3)
    done = np.zeros(ny * nx, bool)
    r2 = (2.3 * H) ** 2
    bt, bc = seg(sx, sz, gx, gz, t0, True)
    gp = -1 if math.isfinite(bc) else -2
    heap = []
    for j in range(ny):
        for i in range(nx):
            px, pz = X0 + i * H, Z0 + j * H
            if (px - sx) ** 2 + (pz - sz) ** 2 > r2 or not free[j, i] > 0.0:
                continue
            ta, ca = seg(sx, sz, px, pz, t0, True)
            n = j * nx + i
            if ca < cost[n]:
                cost[n], tarr[n], parent[n] = ca, ta, -1
                heapq.heappush(heap, (ca, n))
    while heap:
        c, n = heapq.heappop(heap)
        if done[n] or c > cost[n]:
            continue
        if c >= bc:
            break
        done[n] = True
        i, j = n % nx, n // nx
        px, pz, t = X0 + i * H, Z0 + j * H, tarr[n]
        if (px - gx) ** 2 + (pz - gz) ** 2 <= r2:
            tg, cg = seg(px, pz, gx, gz, t, False)
            if c + cg < bc:
                bc, bt, gp = c + cg, tg, n
        for di, dj in R.EDGES:
            ii, jj = i + di, j + dj
            if not (0 <= ii < nx and 0 <= jj < ny):
                continue
            m = jj * nx + ii
            if done[m] or not free[jj, ii] > 0.0:
                continue
            tm, cm = seg(px, pz, X0 + ii * H, Z0 + jj * H, t, False)
            if c + cm < cost[m]:
                cost[m], tarr[m], parent[m] = c + cm, tm, n
                heapq.heappush(heap, (c + cm, m))
    return cost, tarr, parent, gp, bc, bt


@pytest.mark.parametrize("power", [None, (23.5, 5.96)])
def test_search_finds_the_plain_dijkstras_route_bit_for_bit(power):
    # the compiled search (its heap, A*'s estimate of the cost to the goal, the edges' lower
    # bounds that skip integrations, the start's and goal's attachments) ends with the plain
    # search's goal cost, time and parent and the same route, every node of it with the same
    # cost, time and parent, on a time-varying field with land and a jet; it labels fewer
    # nodes, never one cheaper than the plain search does
    cur, times, free = _random_field(seed=5, nt=3)
    n = 41
    cur, free = cur[:, :n, :n].copy(), free[:n, :n].copy()
    free[12:20, 25:28] = -1.0
    cur[:, 20:24, :, 0] += 1.2          # a jet the vehicle cannot cross at its slow speeds
    sp = R.mission_speeds(2.5)
    ph, pk = (0.0, 0.0) if power is None else power
    for (sx, sz), (gx, gz), t0 in [((-1710.3, -1622.9), (-402.5, -310.2), 300.0),
                                   ((-160.0, -1800.0), (-1900.0, -130.0), 4000.0)]:
        args = (cur, times, free, sx, sz, gx, gz, sp, ph, pk, 0.1, t0, 60.0)
        got = R._dijkstra(cur, times, free, X0, Z0, H, sx, sz, gx, gz, sp, ph, pk, 0.1, t0,
                          60.0, R.EDGES)
        want = _plain_dijkstra(*args)
        assert got[3] >= 0 and np.isfinite(got[4])
        assert got[3] == want[3] and got[4] == want[4] and got[5] == want[5]
        route = []
        m = got[3]
        while m >= 0:
            route.append(m)
            m = got[2][m]
        assert len(route) > 10 and m == -1
        for a, b in zip(got[:3], want[:3]):
            assert np.array_equal(a[route], b[route])
        lab = np.isfinite(got[0])
        assert lab.sum() < np.isfinite(want[0]).sum()
        assert np.all(got[0][lab] >= want[0][lab])


def test_schedule_speeds_follow_the_current():
    # along a fixed east-going line: head current on the first half, following on the second
    cur, t, free = _field()
    xs = _coords()
    cur[0, :, xs < 0.0, 0] = -0.9
    cur[0, :, xs >= 0.0, 0] = 0.9
    r = R.schedule(cur, t, free, X0, Z0, H, [(-1500.0, 0.0), (1500.0, 0.0)],
                   R.mission_speeds(2.5), 0.0, power=(23.5, 5.96), hold=0.1, piece=100.0)
    assert r.ok
    mid = 0.5 * (r.path[:-1, 0] + r.path[1:, 0])
    assert np.all(r.speed[mid < -200.0] > 1.25) and np.all(r.speed[mid > 200.0] < 1.25)
    assert np.all(np.diff(r.t) > 0.0)


# ------------------------------------------------------------------------------ models

def test_power_model_of_the_transit_vehicle():
    pw = R.power_model("remus100")
    # the data sheet's two endurance points (1 kWh: 22 h at 3 kn, 8 h at 5 kn)
    np.testing.assert_allclose(pw.battery_wh / pw.power(3 * 0.5144), 22.0, rtol=0.01)
    np.testing.assert_allclose(pw.battery_wh / pw.power(5 * 0.5144), 8.0, rtol=0.01)
    assert 1.2 < pw.range_speed < 1.3
    assert R.cruise_speed(2.5, pw) == 1.25
    assert R.cruise_speed(2.5, None) == 2.5
    np.testing.assert_allclose(R.mission_speeds(2.5), np.arange(0.75, 2.51, 0.25))
    from oneocean.errors import ConfigError
    with pytest.raises(ConfigError, match="power model"):
        R.power_model("bluerov2_heavy")


def test_forecast_field_is_the_sensing_models_forecast():
    from oneocean.sensing.kernels import forecast
    cur, times, _ = _random_field(nt=2)
    fc = np.array([[1.0, 1.0, 0.0, 0.0, 0.0], [1.3, math.cos(0.4), math.sin(0.4), 0.05, -0.1]])
    f0 = R.forecast_field(cur, fc, 0)
    np.testing.assert_array_equal(f0, cur)                  # no error: the truth
    f1 = R.forecast_field(cur, fc, 1)
    j, i = 17, 60
    np.testing.assert_array_equal(f1[1, j, i], forecast(fc, 1, cur[1, j, i, 0], cur[1, j, i, 1]))
    assert not np.allclose(f1, cur)


def test_follow_path_visits_corners_and_passes_straight_vertices():
    wps = np.zeros((1, 8, 2))
    wps[0, :4] = [(0.0, 0.0), (0.0, 100.0), (0.0, 200.0), (700.0, 200.0)]
    wspd = np.zeros((1, 8))
    wspd[0, :3] = (1.25, 1.5, 1.75)
    cnt = np.array([4])
    idx = np.zeros(1, np.int64)
    # the carrot runs on across a straight vertex (only the programmed speed changes there)
    cx, cz, u = R.follow_path(wps, wspd, cnt, idx, 0, 3.0, 90.0, 20.0, 2.0, 1)
    assert (cx, cz, u) == (0.0, 110.0, 1.25) and idx[0] == 0
    # ... but stops at a corner: the vehicle steers at it until it is captured
    cx, cz, u = R.follow_path(wps, wspd, cnt, idx, 0, 14.0, 195.0, 20.0, 2.0, 1)
    assert (cx, cz, u) == (0.0, 200.0, 1.5) and idx[0] == 1
    cx, cz, u = R.follow_path(wps, wspd, cnt, idx, 0, 1.0, 199.5, 20.0, 2.0, 1)
    assert (cx, cz, u) == (21.0, 200.0, 1.75) and idx[0] == 2
    # without commit the index is only read
    idx[0] = 0
    assert R.follow_path(wps, wspd, cnt, idx, 0, 1.0, 199.5, 20.0, 2.0, 0)[:2] == (21.0, 200.0)
    assert idx[0] == 0
    # at the end: the last vertex
    cx, cz, _ = R.follow_path(wps, wspd, cnt, idx, 0, 695.0, 201.0, 20.0, 2.0, 1)
    assert (cx, cz) == (700.0, 200.0) and idx[0] == 2


def test_hold_speed_keeps_headroom_and_progress():
    # cross current 1.4 m/s: 1.25 is raised to 1.5 (0.1 m/s headroom)
    assert math.isclose(R.hold_speed(1.25, 1.0, 0.0, 0.0, 1.4, 2.5), 1.5)
    # head current 1.4 m/s: raised to keep 0.05 m/s over ground
    assert math.isclose(R.hold_speed(1.25, 1.0, 0.0, -1.4, 0.0, 2.5), 1.45)
    # never above the speed limit; unchanged when the current allows the plan
    assert R.hold_speed(1.25, 1.0, 0.0, -3.0, 0.0, 2.5) == 2.5
    assert R.hold_speed(1.25, 1.0, 0.0, 0.5, 0.3, 2.5) == 1.25
