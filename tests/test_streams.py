"""The compiled episode streams are NumPy's own (states and draws, bit for bit), the compiled
route sampler draws what ``sample_route`` draws from the same streams (and fails with its
errors), and the resets built on them give the episodes the NumPy-generator resets gave."""

from __future__ import annotations

import hashlib
import math

import numpy as np
import pytest

from oneocean import engine as E
from oneocean.engine import streams
from oneocean.errors import ConfigError, NotApplicable
from oneocean.tasks import Cell
from oneocean.tasks.common import PURPOSE_RESET
from oneocean.tasks.spawn import sample_route, sample_routes
from oneocean.testing import make_test_grid

SEEDS = (0, 1, 5, 2**31 - 1, 2**32, 2**32 + 7, 123456789012345, 2**63 - 1, 2**64 - 1)


def _numpy(seed, e, purpose):
    return np.random.default_rng(np.random.SeedSequence([seed, int(e), purpose]))


@pytest.mark.parametrize("seed", SEEDS)
def test_states_and_draws_are_numpys(seed):
    eps = np.array([0, 1, 2, 17, 2**32 - 1, 2**32, 2**40 + 3])
    for purpose in (0, PURPOSE_RESET, 2**33 + 5):
        st = streams.episode_states(seed, eps, purpose)
        for r, e in enumerate(eps):
            bg = np.random.PCG64(np.random.SeedSequence([seed, int(e), purpose]))
            want = bg.state["state"]
            assert (int(st[r, 0]) << 64) | int(st[r, 1]) == want["state"]
            assert (int(st[r, 2]) << 64) | int(st[r, 3]) == want["inc"]
        u = streams.uniform_rows(st, -3.5, 7.25, 40)
        v = streams.uniform_rows(st, 2.0, 2.0, 3)      # a zero-width draw still spends one
        w = streams.uniform_rows(st, 0.0, 1.0, 1, rows=[2, 0])
        for r, e in enumerate(eps):
            g = _numpy(seed, e, purpose)
            np.testing.assert_array_equal(u[r], g.uniform(-3.5, 7.25, 40))
            np.testing.assert_array_equal(v[r], g.uniform(2.0, 2.0, 3))
            if r in (0, 2):
                assert w[[2, 0].index(r), 0] == g.random()
            # the stream as a NumPy generator continues where it is
            assert streams.generator(st[r]).random() == g.random()


@pytest.mark.parametrize("delta", [0, 1, 2, 3, 4095, 4096, 8192, 2**40 + 17, 2**64 - 1])
def test_advance_is_numpys_pcg64_advance(delta):
    """``advance`` jumps a stream as ``PCG64.advance`` does: the same state, then the same
    draws (in place and into another row)."""
    from numba import njit

    @njit
    def jump(st, i, src, j, d):
        streams.advance(st, i, src, j, d)

    for seed in (0, 7, 2**63 - 1):
        st = streams.episode_states(seed, [3, 9], PURPOSE_RESET)
        out = np.zeros((1, 4), dtype=np.uint64)
        jump(out, 0, st, 1, delta)
        ref = streams.generator(st[1])
        ref.bit_generator.advance(delta)
        s = ref.bit_generator.state["state"]
        assert [int(v) for v in out[0]] == [s["state"] >> 64, s["state"] & (2**64 - 1),
                                            s["inc"] >> 64, s["inc"] & (2**64 - 1)]
        np.testing.assert_array_equal(streams.uniform_rows(out, -2.0, 5.0, 6)[0],
                                      ref.uniform(-2.0, 5.0, 6))
        jump(st, 0, st, 0, delta)                    # in place
        ref0 = streams.generator(streams.episode_states(seed, [3], PURPOSE_RESET)[0])
        ref0.bit_generator.advance(delta)
        np.testing.assert_array_equal(streams.uniform_rows(st, 0.0, 1.0, 3, rows=[0])[0],
                                      ref0.random(3))


def test_episode_range_and_bad_seeds():
    np.testing.assert_array_equal(streams.episode_states(3, 4, 7),
                                  streams.episode_states(3, np.arange(4), 7))
    with pytest.raises(ValueError, match="seed"):
        streams.episode_states(-1, 2, 7)
    with pytest.raises(ValueError, match="seed"):
        streams.episode_states(2**64, 2, 7)
    with pytest.raises(ValueError, match="episodes"):
        streams.episode_states(1, [-1], 7)


@pytest.mark.parametrize("n_legs, leg_m, turn, vary", [(0, 0.0, math.pi, False),
                                                       (1, 900.0, math.pi, False),
                                                       (3, 400.0, math.radians(120), False),
                                                       (3, 300.0, math.radians(120), True)])
def test_sample_routes_is_sample_route_from_the_same_streams(coast, n_legs, leg_m, turn, vary):
    n = 24
    st = streams.episode_states(11, n, PURPOSE_RESET)
    routes, failed = sample_routes(coast, st, n_legs, leg_m, (2.0, 10.0), 5.0,
                                   max_turn_rad=turn, vary_depth=vary)
    assert not failed
    for e in range(n):
        g = _numpy(11, e, PURPOSE_RESET)
        want = sample_route(coast, g, n_legs, leg_m, (2.0, 10.0), 5.0, max_turn_rad=turn,
                            vary_depth=vary)
        np.testing.assert_array_equal(routes[e], want)
        assert streams.uniform_rows(st, 0.0, 1.0, 1, [e])[0, 0] == g.random()
    # a subset of rows draws the same routes for those rows
    st2 = streams.episode_states(11, n, PURPOSE_RESET)
    some, _ = sample_routes(coast, st2, n_legs, leg_m, (2.0, 10.0), 5.0, rows=[5, 2],
                            max_turn_rad=turn, vary_depth=vary)
    np.testing.assert_array_equal(some, routes[[5, 2]])


def test_sample_routes_fails_as_sample_route(coast):
    def errors(**kw):
        st = streams.episode_states(3, 2, PURPOSE_RESET)
        _, failed = sample_routes(coast, st, what=lambda j: f"cand {j}", **kw)
        want = []
        for e in range(2):
            with pytest.raises(NotApplicable) as exc:
                sample_route(coast, _numpy(3, e, PURPOSE_RESET), what=f"cand {e}", **kw)
            want.append(str(exc.value))
        return [str(failed[j]) for j in sorted(failed)], want

    # no start point: water 10 km deep does not exist (the start point's reasons counted)
    got, want = errors(n_legs=0, leg_m=0.0, depth_m=(2.0, 10.0), clearance=1e4)
    assert got == want and "spawn: found only 0 of 1" in got[0]
    # a leg off the grid from every start
    got, want = errors(n_legs=1, leg_m=1e6, depth_m=(2.0, 10.0), clearance=5.0, tries=3)
    assert got == want and "found in 3 tries" in got[0]


def _reset_hash(grid, task, tier, seed):
    d = Cell(grid, task, tier).reset(48, seed)
    h = hashlib.sha256()
    for k in sorted(d):
        h.update(k.encode())
        v = d[k]
        h.update(v.tobytes() if isinstance(v, np.ndarray) else repr(v).encode())
    return h.hexdigest()[:16]


# the episodes as the NumPy-generator resets drew them (48 episodes of the test coast)
@pytest.mark.parametrize("task, tier, seed, want", [
    ("SK", 2, 7, "9bd97ec00934b2f5"), ("SK", 1, 2**40 + 3, "ca6b53d4022f8bbd"),
    ("G2G", 2, 7, "0b75ead3f922276a"), ("G2G", 1, 2**40 + 3, "8c73ca918deb50df"),
    ("RF", 2, 7, "d3b1b38b7d1c76be"), ("RF", 1, 2**40 + 3, "6d0bbaf728432712"),
    ("DPT", 2, 7, "a0a928ecd79162a7"), ("DPT", 1, 2**40 + 3, "d087159438d11e07"),
    ("FT", 2, 7, "ee35d73f7bec7586"), ("FT", 1, 2**40 + 3, "4976eb0f3ab88f1b"),
    ("FH", 2, 7, "614e2720ea50d772"), ("FH", 1, 2**40 + 3, "6a5965ddfb94855a"),
    ("UPL", 2, 7, "f8213a49fad08c26"), ("UPL", 1, 2**40 + 3, "7e729705e0fa08f5"),
    ("AS", 2, 7, "c370646ea7ca1e01"), ("AS", 1, 2**40 + 3, "a8e7686e71d01419"),
    ("PI", 2, 7, "4aa3622c39467c7a"), ("PI", 1, 2**40 + 3, "f220dbbd17e2a01b"),
    ("SPC", 2, 7, "b1d50503625782fc"), ("SPC", 1, 2**40 + 3, "ee63a3268dfe1c5a")])
def test_resets_draw_the_numpy_generator_episodes(coast, task, tier, seed, want):
    assert _reset_hash(coast, task, tier, seed) == want


def _fh_reset_numpy(grid, tier, n, seed):
    """FH's reset as NumPy generators and ``_try_episode`` draw it, one episode at a time."""
    from oneocean.tasks import fh
    from oneocean.tasks.spawn import episode_generators, start_times

    rngs = episode_generators(seed, n)
    t0 = start_times(grid, rngs, float(tier["time_limit_s"]))
    rows = []
    for e, rng in enumerate(rngs):
        for _ in range(200):
            found = fh._try_episode(grid, rng, int(tier["fish_count"]),
                                    float(tier["zone_distance_m"]), float(tier["zone_radius_m"]))
            if found is not None:
                break
        if found is None:
            raise NotApplicable(f"episode {e}: none")
        rows.append(found)
    return t0, rows


@pytest.mark.parametrize("tier, seed", [(1, 0), (2, 2**40 + 3), (3, 2**64 - 1)])
def test_fh_reset_draws_what_the_python_sampler_draws(coast, tier, seed):
    """FH's compiled geometry sampler gives ``_try_episode``'s schools, zones and starts from
    the same streams, and fails with the route sampler's error where it does."""
    from oneocean.tasks import fh

    params = dict(Cell(coast, "FH", tier).params)
    d = fh.reset(coast, params, 8, 12, seed)
    t0, rows = _fh_reset_numpy(coast, params, 12, seed)
    np.testing.assert_array_equal(d["t0"], t0)
    for e, (fx, fz, zone, starts) in enumerate(rows):
        np.testing.assert_array_equal(d["fish0"][e, 0], fx)
        np.testing.assert_array_equal(d["fish0"][e, 1], fz)
        np.testing.assert_array_equal(d["zone"][e], zone)
        np.testing.assert_array_equal(d["pos0"][e], starts)
    # a region too shallow for the school's route: the route sampler's own message
    shallow = E.load_grid(make_test_grid(nt=3, nz=3, ny=20, nx=30, max_depth_m=3.0,
                                         depths=[0.5, 1.0, 2.0]))
    with pytest.raises(NotApplicable) as got:
        fh.reset(shallow, params, 8, 3, seed)
    with pytest.raises(NotApplicable) as want:
        _fh_reset_numpy(shallow, params, 3, seed)
    assert str(got.value) == str(want.value) and "spawn: found only 0 of 1" in str(got.value)
    # no zone fits: every episode's 200 draws fail
    with pytest.raises(NotApplicable, match="3000 m zone found in 200 draws"):
        fh.reset(coast, {**params, "zone_radius_m": 3000.0}, 8, 2, seed)


@pytest.mark.parametrize("tier, seed", [(1, 0), (2, 2**40 + 3), (3, 2**64 - 1)])
def test_upl_reset_draws_what_the_python_sampler_draws(coast, tier, seed):
    """UPL's compiled site sampler gives the sites, slot phases, starts and charts that
    ``_site_candidates`` and ``_try_site`` draw from the same streams (then the chart's
    normal draws), and fails where they find no site."""
    from oneocean.tasks import upl
    from oneocean.tasks.spawn import episode_generators, start_times

    params = dict(Cell(coast, "UPL", tier).params)
    d = upl.reset(coast, params, 5, 10, seed)
    rngs = episode_generators(seed, 10)
    np.testing.assert_array_equal(d["t0"], start_times(coast, rngs, params["time_limit_s"]))
    hi = float(params["site_depth_m"])
    for e, rng in enumerate(rngs):
        found = None
        for _ in range(8):
            for x, z in upl._site_candidates(coast, rng, hi - upl.SITE_DEPTH_SPAN_M, hi)[:50]:
                found = upl._try_site(coast, rng, float(x), float(z),
                                      float(params["start_distance_m"]))
                if found is not None:
                    break
            if found is not None:
                break
        obj, phase, starts = found
        np.testing.assert_array_equal(d["obj0"][e], obj)
        np.testing.assert_array_equal(d["slot_off"][e], upl.slot_offsets(phase))
        np.testing.assert_array_equal(d["pos0"][e], starts)
        err = np.clip(rng.normal(0.0, 1.0, 2), -3.0, 3.0) * float(params["survey_std_m"])
        np.testing.assert_array_equal(d["chart"][e], upl._chart_point(coast, obj, err))
    with pytest.raises(NotApplicable, match=r"no site with seafloor depth in \[485, 500\] m"):
        upl.reset(coast, {**params, "site_depth_m": 500.0}, 5, 2, seed)


def test_bounded_integers_are_numpys():
    """``streams.integers`` (with the 32-bit half each row keeps) draws what NumPy's
    ``Generator.integers(high)`` draws, interleaved with doubles, for bounds from 1 to
    2**32; a generator made from a row and its kept half continues the same stream."""
    from numba import njit

    @njit
    def draw(st, buf, highs, out):
        for i in range(st.shape[0]):
            for k in range(highs.shape[0]):
                out[i, 2 * k] = streams.integers(st, buf, i, highs[k])
                out[i, 2 * k + 1] = streams.next_double(st, i) if k % 3 == 0 else -1.0

    highs = np.array([1, 2, 3, 7, 1000, 2**31 - 1, 2**31, 2**31 + 1, 3 * 2**30, 2**32 - 1,
                      2**32, 5, 2, 1, 2**20 + 3] * 3, dtype=np.int64)
    eps = np.array([0, 1, 9, 2**33 + 1])
    st = streams.episode_states(11, eps, PURPOSE_RESET)
    buf = np.zeros((eps.size, 2), dtype=np.uint64)
    out = np.empty((eps.size, 2 * highs.size))
    draw(st, buf, highs, out)
    for r, e in enumerate(eps):
        rng = _numpy(11, e, PURPOSE_RESET)
        want = []
        for k, h in enumerate(highs):
            want.append(float(rng.integers(int(h))))
            want.append(rng.random() if k % 3 == 0 else -1.0)
        np.testing.assert_array_equal(out[r], want)
        cont = streams.generator(st[r], buf[r])
        assert cont.integers(1000, size=5).tolist() == rng.integers(1000, size=5).tolist()
        assert cont.random() == rng.random()


@pytest.mark.parametrize("tier, seed", [(1, 0), (2, 2**40 + 3), (3, 2**64 - 1)])
def test_as_reset_draws_what_the_python_samplers_draw(coast, tier, seed):
    """AS's compiled region and spawn sampler gives ``sample_region``'s regions and
    ``spawn_positions``' starts from the same streams (bounded integers included), and
    fails with their errors."""
    from oneocean.tasks import as_
    from oneocean.tasks.spawn import episode_generators, start_times

    params = dict(Cell(coast, "AS", tier).params)
    d = as_.reset(coast, params, 4, 10, seed)
    rngs = episode_generators(seed, 10)
    np.testing.assert_array_equal(d["t0"], start_times(coast, rngs, params["time_limit_s"]))
    for e, rng in enumerate(rngs):
        box, ax, starts = as_._episode_python(coast, rng, params, 4, e)
        np.testing.assert_array_equal(d["region"][e], box)
        assert d["long_axis"][e] == ax
        np.testing.assert_array_equal(d["pos0"][e], starts)
    with pytest.raises(NotApplicable, match=r"depth in \[500, 600\] m .* in 3000 tries"):
        as_.reset(coast, {**params, "seafloor_min_m": 500.0, "seafloor_max_m": 600.0}, 4, 2,
                  seed)
    small = {**params, "seafloor_min_m": 0.0, "seafloor_max_m": 7.0, "min_relief_m": 0.0,
             "region_long_m": 60.0, "region_short_m": 30.0}
    with pytest.raises(ConfigError) as got:
        as_.reset(coast, small, 1, 3, 5)
    rng = episode_generators(5, 1)[0]
    start_times(coast, [rng], params["time_limit_s"])
    with pytest.raises(ConfigError) as want:
        as_._episode_python(coast, rng, small, 1, 0)
    assert str(got.value) == str(want.value) and "spawn: found only 0 of 1" in str(got.value)


@pytest.mark.parametrize("tier, seed", [(1, 0), (2, 2**40 + 3), (3, 2**64 - 1)])
def test_pi_reset_draws_what_the_python_samplers_draw(coast, tier, seed):
    """PI's compiled pipeline, leak and spawn sampler gives ``sample_pipeline``'s lines,
    ``sample_leaks``' leaks, ``spawn_positions``' starts and the leak rates from the same
    streams, and fails with their errors."""
    from oneocean.tasks import pi
    from oneocean.tasks.spawn import episode_generators, start_times

    params = dict(Cell(coast, "PI", tier).params)
    d = pi.reset(coast, params, 3, 8, seed)
    rngs = episode_generators(seed, 8)
    np.testing.assert_array_equal(d["t0"], start_times(coast, rngs, params["time_limit_s"]))
    for e, rng in enumerate(rngs):
        want = pi._episode_python(coast, rng, params, 3, e)
        for key, w in zip(("poly", "leaks", "leak_rate", "sections", "pos0"), want):
            np.testing.assert_array_equal(d[key][e], w)
    with pytest.raises(NotApplicable, match=r"depth in \[500, 600\] m found in 3000 tries"):
        pi.reset(coast, {**params, "seafloor_min_m": 500.0, "seafloor_max_m": 600.0}, 3, 2,
                 seed)
    with pytest.raises(ConfigError, match="cannot place 9 leaks 400 m apart"):
        pi.reset(coast, {**params, "n_leaks": 9, "leak_spacing_m": 400.0}, 3, 2, seed)


@pytest.mark.parametrize("tier, seed", [(1, 0), (2, 2**40 + 3), (3, 2**64 - 1)])
def test_spc_reset_draws_what_the_python_sampler_draws(coast, tier, seed):
    """SPC's compiled site, staging and spill sampler gives ``_candidate_python``'s starts,
    spill box, origin and centroid from the same streams (slack water included: its own
    bearing draw), and fails with its errors in the episodes' order."""
    from oneocean.tasks import spc
    from oneocean.tasks.spawn import episode_generators, start_times

    params = dict(Cell(coast, "SPC", tier).params)
    calm = E.load_grid(make_test_grid(nt=5, nz=3, ny=30, nx=40, speed_ms=0.0, tide_ms=0.0,
                                      has_tide=False))
    for grid in (coast, calm):
        d = spc.reset_candidates(grid, params, 3, 8, seed)
        rngs = episode_generators(seed, 8)
        np.testing.assert_array_equal(d["t0"], start_times(grid, rngs, params["time_limit_s"]))
        raw = grid._replace(gain=1.0, tide_layers=0)
        for e, rng in enumerate(rngs):
            want = spc._candidate_python(grid, raw, rng, params, 3, float(d["t0"][e]), e)
            for key, w in zip(("starts", "spill", "origin", "report"), want):
                assert np.asarray(d[key][e]).tobytes() == np.asarray(w, float).tobytes(), key
    with pytest.raises(NotApplicable, match=r"episode 0\): no spill site clear of land within "
                                            r"\d+ m with a clear staging point 1e\+06 m away"):
        spc.reset_candidates(coast, {**params, "staging_distance_m": 1e6}, 3, 2, seed)
    g = make_test_grid(nt=5, nz=3, ny=30, nx=40, dt_s=3600.0)
    g["land_mask"] = np.ones_like(g["land_mask"])
    with pytest.raises(NotApplicable, match=r"episode 0\): spawn: found only 0 of 1"):
        spc.reset_candidates(E.load_grid(g), params, 3, 2, seed)


@pytest.mark.parametrize("n", [0, 1, 7, 8, 9, 127, 128, 129, 136, 255, 1000, 3600, 4097, 20011])
def test_pairwise_sum_is_numpys_sum(n):
    """The compiled spill's total adds in NumPy's pairwise order: the same bits as ``np.sum``
    (mixed signs, zeros and magnitudes, where another order rounds differently)."""
    from oneocean.models.pollution import pairwise_sum

    rng = np.random.default_rng(n)
    stack = np.empty((64, 5))
    for _ in range(20):
        a = (rng.random(n) - 0.3) * rng.random(n) ** 8 * 1e3
        a[rng.random(n) < 0.4] = 0.0
        assert 0.0 + pairwise_sum(a, 0, n, stack) == a.sum()
        lo = n // 3
        assert 0.0 + pairwise_sum(a, lo, n - lo, stack) == a[lo:].sum()
    if n > 300:   # the naive sequential sum is not NumPy's (the test can tell the orders apart)
        a = (rng.random(n) - 0.3) * rng.random(n) ** 8 * 1e3
        assert math.fsum(a) != a.sum() or sum(a.tolist()) != a.sum()
