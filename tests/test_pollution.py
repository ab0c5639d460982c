"""Pollution field kernels: conservation, positivity, transport accuracy, sources and sinks."""

from __future__ import annotations

import numba
import numpy as np
import pytest

from oneocean.errors import ConfigError
from oneocean.models import pollution as P

NO_DECAY = np.zeros(1)


def _grid(nx, nz, h):
    return np.zeros((nz, nx), dtype=np.uint8), P.face_coordinates(nx, nz, 0.0, 0.0, h)


def _uniform_faces(nx, nz, u, v):
    return np.full((nz, nx + 1), float(u)), np.full((nz + 1, nx), float(v))


def _swirl_faces(nx, nz, h):
    """Solid-body rotation about the domain centre plus a sinusoidal shear (max ~0.9 m/s)."""
    xu, zu, xv, zv = P.face_coordinates(nx, nz, 0.0, 0.0, h)
    xc, zc = 0.5 * (nx - 1) * h, 0.5 * (nz - 1) * h
    omega = 0.5 / (0.5 * nz * h)
    U = -omega * (zu[:, None] - zc) + 0.3 * np.sin(2 * np.pi * zu[:, None] / (nz * h)) \
        + 0.0 * xu[None, :]
    V = omega * (xv[None, :] - xc) + 0.2 * np.cos(2 * np.pi * xv[None, :] / (nx * h)) \
        + 0.0 * zv[:, None]
    return np.ascontiguousarray(U), np.ascontiguousarray(V)


def _moments(C, h, s=0):
    x, z = P.cell_centres(C.shape[2], C.shape[1], 0.0, 0.0, h)
    w = C[s] / C[s].sum()
    mx = (w.sum(0) * x).sum()
    mz = (w.sum(1) * z).sum()
    vx = (w.sum(0) * (x - mx) ** 2).sum()
    vz = (w.sum(1) * (z - mz) ** 2).sum()
    return mx, mz, vx, vz


def _swirl_run(n_steps=300, dt=20.0, kappa=0.5):
    nx, nz, h = 60, 50, 10.0
    land = np.zeros((nz, nx), dtype=np.uint8)
    land[20:28, 35:40] = 1  # an island inside the flow
    land[0:6, 0:4] = 1  # a cape on the boundary
    C = P.make_spill(nx, nz, h, (300.0, 250.0), 60.0, 1000.0, land=land)
    U, V = _swirl_faces(nx, nz, h)
    work = P.make_work(C)
    C0 = C.copy()
    out = 0.0
    mins = []
    for _ in range(n_steps):
        out += P.step_field(C, P.KIND_TRACER, NO_DECAY, U, V, land, h, dt, kappa, P.CLOSED, work)
        mins.append(C.min())
    return C0, C, land, h, out, np.array(mins)


def test_mass_conserved_closed_domain_rotating_shear_flow_with_land():
    C0, C, land, h, out, _ = _swirl_run()
    m0, m1 = P.total_mass(C0, h), P.total_mass(C, h)
    assert m0 == pytest.approx(1000.0, rel=1e-12)
    assert abs(m1 - m0) / m0 < 1e-9  # contract: 1e-6
    assert out == 0.0
    assert np.all(C[0][land != 0] == 0.0)  # nothing leaks into land
    # the field really moved: the test is not vacuous
    assert np.abs(C - C0).sum() * h * h > 0.5 * m0


def test_positivity_rotating_flow_and_sharp_initial_field():
    _, C, _, _, _, mins = _swirl_run()
    assert mins.min() >= 0.0
    # a one-cell delta in a strongly divergent/convergent flow, large dt (many sub-steps)
    nx, nz, h = 40, 40, 5.0
    land = np.zeros((nz, nx), dtype=np.uint8)
    C = np.zeros((1, nz, nx))
    C[0, 20, 20] = 1.0
    C[0, 10, 30] = 5.0
    xu, zu, xv, zv = P.face_coordinates(nx, nz, 0.0, 0.0, h)
    U = np.ascontiguousarray(np.broadcast_to(np.sin(xu / 17.0)[None, :] * 1.5, (nz, nx + 1)))
    V = np.ascontiguousarray(np.broadcast_to(np.cos(zv / 13.0)[:, None] * 1.5, (nz + 1, nx)))
    work = P.make_work(C)
    m0 = P.total_mass(C, h)
    for _ in range(50):
        P.step_field(C, 0, NO_DECAY, U, V, land, h, 60.0, 0.1, P.CLOSED, work)
        assert C.min() >= 0.0
    assert P.total_mass(C, h) == pytest.approx(m0, rel=1e-9)


def test_uniform_advection_moves_centroid_by_u_t_with_little_numerical_diffusion():
    nx, nz, h = 120, 80, 5.0
    land = np.zeros((nz, nx), dtype=np.uint8)
    u, v = 0.4, -0.3
    U, V = _uniform_faces(nx, nz, u, v)
    C = P.make_spill(nx, nz, h, (150.0, 280.0), 40.0, 50.0)
    mx0, mz0, vx0, vz0 = _moments(C, h)
    work = P.make_work(C)
    dt, n = 10.0, 40
    for _ in range(n):
        P.step_field(C, 0, NO_DECAY, U, V, land, h, dt, 0.0, P.CLOSED, work)
    mx1, mz1, vx1, vz1 = _moments(C, h)
    t = dt * n
    assert abs(mx1 - (mx0 + u * t)) < 0.2 * h  # contract: within a cell
    assert abs(mz1 - (mz0 + v * t)) < 0.2 * h
    # first-order upwind would add ~2 * (|u| h / 2) t = 800 m2 of variance along x; an
    # uncorrected forward-Euler MUSCL step is anti-diffusive (variance shrinks)
    assert 0.0 <= vx1 - vx0 < 100.0
    assert 0.0 <= vz1 - vz0 < 100.0


def test_pure_diffusion_spreads_variance_2_kappa_t_per_axis():
    nx, nz, h = 80, 80, 5.0
    land = np.zeros((nz, nx), dtype=np.uint8)
    U, V = _uniform_faces(nx, nz, 0.0, 0.0)
    C = P.make_spill(nx, nz, h, (200.0, 190.0), 30.0, 10.0)
    _, _, vx0, vz0 = _moments(C, h)
    work = P.make_work(C)
    kappa, dt, n = 2.0, 5.0, 40
    for _ in range(n):
        P.step_field(C, 0, NO_DECAY, U, V, land, h, dt, kappa, P.CLOSED, work)
    _, _, vx1, vz1 = _moments(C, h)
    expect = 2.0 * kappa * dt * n
    assert vx1 - vx0 == pytest.approx(expect, rel=0.01)
    assert vz1 - vz0 == pytest.approx(expect, rel=0.01)


@pytest.mark.parametrize("u,v", [(0.6, 0.15), (-0.6, 0.1), (0.1, 0.6), (-0.15, -0.6)])
def test_open_boundary_budget_closes(u, v):
    nx, nz, h = 50, 40, 10.0
    land = np.zeros((nz, nx), dtype=np.uint8)
    land[5:9, 5:9] = 1  # an island near a corner
    U, V = _uniform_faces(nx, nz, u, v)
    C = P.make_spill(nx, nz, h, (250.0, 200.0), 50.0, 100.0, land=land)
    m0 = P.total_mass(C, h)
    work = P.make_work(C)
    outflow = 0.0
    for _ in range(80):
        outflow += P.step_field(C, 0, NO_DECAY, U, V, land, h, 10.0, 1.0, P.OPEN_ALL, work)
        assert C.min() >= 0.0
    assert outflow > 0.5 * m0  # the test exercises the boundary
    assert P.total_mass(C, h) + outflow == pytest.approx(m0, rel=1e-10)


def test_open_boundary_diffusive_outflow_is_symmetric_and_closes_budget():
    nx, nz, h = 21, 21, 10.0
    land = np.zeros((nz, nx), dtype=np.uint8)
    U, V = _uniform_faces(nx, nz, 0.0, 0.0)
    C0 = P.make_spill(nx, nz, h, (100.0, 100.0), 40.0, 1.0)
    outs = []
    for side in (P.OPEN_WEST, P.OPEN_EAST, P.OPEN_SOUTH, P.OPEN_NORTH, P.OPEN_ALL):
        C = C0.copy()
        work = P.make_work(C)
        out = sum(P.step_field(C, 0, NO_DECAY, U, V, land, h, 20.0, 5.0, side, work)
                  for _ in range(15))
        assert P.total_mass(C, h) + out == pytest.approx(1.0, rel=1e-12)
        outs.append(out)
    assert outs[0] > 0.01  # diffusion carries mass out through the open side
    np.testing.assert_allclose(outs[:4], outs[0], rtol=1e-9)
    assert outs[4] > 3.0 * outs[0]


def test_open_side_mask_only_opens_the_named_side():
    nx, nz, h = 40, 30, 10.0
    land = np.zeros((nz, nx), dtype=np.uint8)
    U, V = _uniform_faces(nx, nz, 0.5, 0.0)
    C_w = P.make_spill(nx, nz, h, (300.0, 150.0), 40.0, 1.0)
    C_e = C_w.copy()
    work = P.make_work(C_w)
    out_w = out_e = 0.0
    for _ in range(40):
        out_w += P.step_field(C_w, 0, NO_DECAY, U, V, land, h, 10.0, 0.0, P.OPEN_WEST, work)
        out_e += P.step_field(C_e, 0, NO_DECAY, U, V, land, h, 10.0, 0.0, P.OPEN_EAST, work)
    assert out_w == 0.0  # flow runs east; without diffusion nothing reaches the west edge
    assert out_e > 0.5
    assert P.total_mass(C_w, h) == pytest.approx(1.0, rel=1e-12)


def test_tracer_decay_is_exact_exponential():
    nx, nz, h = 10, 8, 2.0
    C = np.full((1, nz, nx), 3.0)
    land = np.zeros((nz, nx), dtype=np.uint8)
    U, V = _uniform_faces(nx, nz, 0.1, 0.1)
    kind, params = P.field_params("tracer", decay=1e-3)
    work = P.make_work(C)
    for _ in range(10):
        P.step_field(C, kind, params, U, V, land, h, 50.0, 0.2, P.CLOSED, work)
    assert P.total_mass(C, h) == pytest.approx(3.0 * nx * nz * h * h * np.exp(-0.5), rel=1e-12)


def test_reaction_kind_converts_species_conserving_total_mass():
    nx, nz, h = 30, 20, 5.0
    land = np.zeros((nz, nx), dtype=np.uint8)
    land[5:8, 10:14] = 1
    k = 2e-3
    # A -> B at rate k, B -> C at rate k/2; columns sum to 0 (no net loss)
    K = np.array([[-k, 0.0, 0.0], [k, -k / 2, 0.0], [0.0, k / 2, 0.0]])
    kind, params = P.field_params("reaction", 3, reaction=K)
    C = P.make_spill(nx, nz, h, (75.0, 60.0), 25.0, 10.0, n_species=3, land=land)
    U, V = _swirl_faces(nx, nz, h)
    work = P.make_work(C)
    dt, n = 30.0, 50
    for _ in range(n):
        P.step_field(C, kind, params, U, V, land, h, dt, 0.3, P.CLOSED, work)
        assert C.min() >= 0.0
    t = dt * n
    assert P.total_mass(C, h) == pytest.approx(10.0, rel=1e-9)
    a = np.exp(-k * t)
    b = 2.0 * (np.exp(-k * t / 2) - np.exp(-k * t))  # analytic A -> B -> C chain
    assert P.species_mass(C, 0, h) == pytest.approx(10.0 * a, rel=1e-9)
    assert P.species_mass(C, 1, h) == pytest.approx(10.0 * b, rel=1e-9)


def test_removal_never_negative_and_equals_drop_in_total():
    nx, nz, h = 40, 30, 4.0
    C = P.make_spill(nx, nz, h, (80.0, 60.0), 30.0, 7.0, n_species=2)
    C[1] = 0.5 * C[0]
    before = C.copy()
    m0 = P.total_mass(C, h)
    removed = P.remove_in_radius(C, 81.0, 59.0, 10.0, 0.2, 1.5, 0.0, 0.0, h)
    x, z = P.cell_centres(nx, nz, 0.0, 0.0, h)
    inside = (x[None, :] - 81.0) ** 2 + (z[:, None] - 59.0) ** 2 <= 100.0
    assert removed > 0.0
    assert removed == pytest.approx(m0 - P.total_mass(C, h), rel=1e-12)
    np.testing.assert_allclose(C[:, inside], 0.7 * before[:, inside], rtol=1e-15)
    np.testing.assert_array_equal(C[:, ~inside], before[:, ~inside])
    # efficiency * dt > 1 is capped: everything within the radius goes, nothing goes negative
    removed2 = P.remove_in_radius(C, 81.0, 59.0, 10.0, 5.0, 1.0, 0.0, 0.0, h)
    assert C.min() >= 0.0
    assert np.all(C[:, inside] == 0.0)
    assert removed2 == pytest.approx(0.7 * before[:, inside].sum() * h * h, rel=1e-12)
    # off the grid: nothing removed
    assert P.remove_in_radius(C, -500.0, 59.0, 10.0, 5.0, 1.0, 0.0, 0.0, h) == 0.0


@pytest.mark.parametrize("x,z", [(41.3, 27.9), (0.0, 0.0), (-1.9, 30.0), (157.9, 117.9),
                                 (100.0, 48.0)])
def test_emission_adds_exactly_rate_dt(x, z):
    nx, nz, h = 40, 30, 4.0
    C = np.zeros((2, nz, nx))
    added = P.emit(C, 1, x, z, 0.25, 3.0, 0.0, 0.0, h)
    assert added == 0.75
    assert P.total_mass(C, h) == pytest.approx(0.75, rel=1e-14)
    assert C[0].sum() == 0.0
    if 0.0 <= x <= (nx - 1) * h and 0.0 <= z <= (nz - 1) * h:
        # bilinear weights put the centre of the added mass on the source
        xc, zc, m = P.centroid(C, 1, 0.0, 0.0, h)
        assert (xc, zc) == pytest.approx((x, z), abs=1e-9)
        assert m == pytest.approx(0.75)


def test_emission_outside_extent_adds_nothing():
    C = np.zeros((1, 10, 10))
    assert P.emit(C, 0, -3.0, 5.0, 1.0, 1.0, 0.0, 0.0, 4.0) == 0.0  # west of x0 - h/2
    assert P.emit(C, 0, 5.0, 38.5, 1.0, 1.0, 0.0, 0.0, 4.0) == 0.0  # north of the extent
    assert not C.any()


def test_probe_is_exact_on_a_linear_field_and_zero_outside():
    nx, nz, h, x0, z0 = 25, 20, 3.0, -30.0, 100.0
    x, z = P.cell_centres(nx, nz, x0, z0, h)
    C = np.zeros((2, nz, nx))
    C[1] = 2.0 + 0.05 * x[None, :] - 0.02 * z[:, None]
    rng = np.random.default_rng(0)
    px = rng.uniform(x[0], x[-1], 50)
    pz = rng.uniform(z[0], z[-1], 50)
    for a, b in zip(px, pz):
        assert P.probe(C, 1, a, b, x0, z0, h) == pytest.approx(2.0 + 0.05 * a - 0.02 * b,
                                                               abs=1e-12)
        assert P.probe(C, 0, a, b, x0, z0, h) == 0.0
    assert P.probe(C, 1, x[3], z[7], x0, z0, h) == C[1, 7, 3]
    assert P.probe(C, 1, x0 - 2.0, z[5], x0, z0, h) == 0.0
    assert P.probe(C, 1, x[5], z[-1] + 2.0, x0, z0, h) == 0.0
    # the half cell inside the extent holds the edge value
    assert P.probe(C, 1, x0 - 1.0, z[5], x0, z0, h) == pytest.approx(C[1, 5, 0])


def test_deterministic():
    a = _swirl_run(n_steps=50)[1]
    b = _swirl_run(n_steps=50)[1]
    assert a.tobytes() == b.tobytes()


def test_faces_from_centers():
    nz, nx = 4, 5
    x = np.arange(nx, dtype=float)
    z = np.arange(nz, dtype=float)
    uc = np.ascontiguousarray(np.broadcast_to(2.0 * x[None, :], (nz, nx)))
    vc = np.ascontiguousarray(np.broadcast_to(-1.0 * z[:, None], (nz, nx)))
    vc[1, 2] = np.nan
    uf, vf = P.faces_from_centers(uc, vc)
    assert uf.shape == (nz, nx + 1) and vf.shape == (nz + 1, nx)
    np.testing.assert_allclose(uf[:, 1:-1], 2.0 * (x[:-1] + 0.5)[None, :].repeat(nz, 0))
    np.testing.assert_allclose(uf[:, 0], 0.0)
    np.testing.assert_allclose(uf[:, -1], 2.0 * (nx - 1))
    assert vf[1, 2] == 0.0  # the NaN centre reads as 0 (its other neighbour is v = 0 at z = 0)
    assert vf[2, 2] == -1.0  # mean of 0 (NaN) and -2
    assert vf[3, 1] == -2.5
    assert np.isfinite(vf).all()


def test_make_spill_mass_land_and_rng():
    land = np.zeros((30, 40), dtype=np.uint8)
    land[10:20, 15:20] = 1
    C = P.make_spill(40, 30, 5.0, (90.0, 75.0), 20.0, 3.5, land=land)
    assert P.total_mass(C, 5.0) == pytest.approx(3.5, rel=1e-12)
    assert np.all(C[0][land != 0] == 0.0)
    r1 = P.make_spill(40, 30, 5.0, (90.0, 75.0), 20.0, 3.5, np.random.default_rng(3))
    r2 = P.make_spill(40, 30, 5.0, (90.0, 75.0), 20.0, 3.5, np.random.default_rng(3))
    r3 = P.make_spill(40, 30, 5.0, (90.0, 75.0), 20.0, 3.5, np.random.default_rng(4))
    assert r1.tobytes() == r2.tobytes() and r1.tobytes() != r3.tobytes()
    xc, zc, _ = P.centroid(r1, 0, 0.0, 0.0, 5.0)
    assert (xc, zc) == pytest.approx((90.0, 75.0), abs=0.5)


def test_bad_inputs_raise():
    nx, nz = 6, 5
    C = np.ones((1, nz, nx))
    land = np.zeros((nz, nx), dtype=np.uint8)
    U, V = _uniform_faces(nx, nz, 0.1, 0.0)
    work = P.make_work(C)
    with pytest.raises(ValueError, match="unknown field kind"):
        P.step_field(C, 7, NO_DECAY, U, V, land, 1.0, 1.0, 0.0, 0, work)
    with pytest.raises(ValueError, match="work is too short"):
        P.step_field(C, 0, NO_DECAY, U, V, land, 1.0, 1.0, 0.0, 0, work[:5])
    with pytest.raises(ValueError, match="u_face_x"):
        P.step_field(C, 0, NO_DECAY, np.zeros((nz, nx)), V, land, 1.0, 1.0, 0.0, 0, work)
    with pytest.raises(ValueError, match="n_species"):
        P.step_field(C, 1, np.zeros(0), U, V, land, 1.0, 1.0, 0.0, 0, work)
    with pytest.raises(ValueError, match="species index"):
        P.emit(C, 1, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 1.0)
    with pytest.raises(ValueError, match="species index"):
        P.probe(C, -1, 1.0, 1.0, 0.0, 0.0, 1.0)
    with pytest.raises(ConfigError, match="off-diagonal"):
        P.field_params("reaction", 2, reaction=[[0.0, -1.0], [0.0, 0.0]])
    with pytest.raises(ConfigError, match="Valid options"):
        P.field_params("ocpnet")


@numba.njit(cache=True)
def _jitted_rollout(C, U, V, land, h, work, n):
    """What a task's rollout loop does: emit, transport, remove, probe, all inside njit."""
    removed = 0.0
    emitted = 0.0
    outflow = 0.0
    sensed = 0.0
    params = np.zeros(1)
    for k in range(n):
        emitted += P.emit(C, 0, 52.0, 47.0, 0.01, 2.0, 0.0, 0.0, h)
        outflow += P.step_field(C, P.KIND_TRACER, params, U, V, land, h, 2.0, 0.5, P.OPEN_ALL,
                                work)
        removed += P.remove_in_radius(C, 60.0 + 0.1 * k, 50.0, 6.0, 0.3, 2.0, 0.0, 0.0, h)
        sensed += P.probe(C, 0, 58.0, 49.0, 0.0, 0.0, h)
    return emitted, outflow, removed, sensed


def test_kernels_compose_inside_a_jitted_rollout_loop():
    nx, nz, h = 30, 25, 4.0
    land = np.zeros((nz, nx), dtype=np.uint8)
    land[3:6, 3:6] = 1
    U, V = _uniform_faces(nx, nz, 0.2, 0.05)
    C = P.make_spill(nx, nz, h, (50.0, 50.0), 10.0, 2.0, land=land)
    emitted, outflow, removed, sensed = _jitted_rollout(C, U, V, land, h, P.make_work(C), 100)
    assert removed > 0.1 and sensed > 0.0
    assert P.total_mass(C, h) == pytest.approx(2.0 + emitted - outflow - removed, rel=1e-10)


# ---- the transport scheme, written out plainly (Python floats: IEEE doubles, as compiled)

def _ref_face(u, c_up2, c_up, c_dn, c_dn2, dt, h, kappa):
    """Flux through an interior face between water cells ``c_up`` (west/south) and ``c_dn``;
    ``c_up2``/``c_dn2`` are the second neighbours, None where land or outside."""
    nu = abs(u) * dt * (1.0 / h)
    flux = 0.0
    if u > 0.0:
        a, b = (c_up - c_up2, c_dn - c_up) if c_up2 is not None else (0.0, 0.0)
        slope = 2.0 * a * b / (a + b) if a * b > 0.0 else 0.0
        flux = u * (c_up + 0.5 * (1.0 - nu) * slope)
    elif u < 0.0:
        a, b = (c_dn - c_up, c_dn2 - c_dn) if c_dn2 is not None else (0.0, 0.0)
        slope = 2.0 * a * b / (a + b) if a * b > 0.0 else 0.0
        flux = u * (c_dn - 0.5 * (1.0 - nu) * slope)
    return flux - kappa * (c_dn - c_up) * (1.0 / h)


def _ref_substep(C, U, V, land, h, dt, kappa, open_bc):
    """One sub-step of ``step_field``'s scheme (van Leer upwind fluxes + diffusion, open sides
    with zero-concentration ghosts); returns the new field and the mass that left."""
    nz, nx = C.shape
    inv_h = 1.0 / h
    c = [[float(x) for x in row] for row in C]

    def fluxes(c, vel, land, lo_side, hi_side):
        """Fluxes through the faces along each row of ``c`` (x-faces; z-faces transposed)."""
        rows, n = len(c), len(c[0])

        def at(j, i):
            return c[j][i] if 0 <= i < n and land[j, i] == 0 else None

        F = [[0.0] * (n + 1) for _ in range(rows)]
        for j in range(rows):
            for f in range(n + 1):
                u = float(vel[j, f]) if np.isfinite(vel[j, f]) else 0.0
                if f == 0 or f == n:
                    inner, side = (0, lo_side) if f == 0 else (n - 1, hi_side)
                    if open_bc & side and land[j, inner] == 0:
                        # outflow carries the inner cell's value, inflow zero; ghost 0 outside
                        cin, out_pos = c[j][inner], f == n
                        flux = u * cin if (u > 0.0 if out_pos else u < 0.0) else 0.0
                        F[j][f] = (flux + kappa * cin * inv_h if out_pos
                                   else flux - kappa * cin * inv_h)
                elif at(j, f - 1) is not None and at(j, f) is not None:
                    F[j][f] = _ref_face(u, at(j, f - 2), c[j][f - 1], c[j][f], at(j, f + 1),
                                        dt, h, kappa)
        return F

    FX = fluxes(c, U, land, P.OPEN_WEST, P.OPEN_EAST)
    FZ = [list(r) for r in zip(*fluxes([list(r) for r in zip(*c)], V.T, land.T,
                                       P.OPEN_SOUTH, P.OPEN_NORTH))]
    out = 0.0
    for j in range(nz):
        out -= FX[j][0] * h * dt
        out += FX[j][nx] * h * dt
    for i in range(nx):
        out -= FZ[0][i] * h * dt
        out += FZ[nz][i] * h * dt
    new = np.array(c)
    lam = dt * inv_h
    for j in range(nz):
        for i in range(nx):
            if land[j, i] == 0:
                x = c[j][i] - lam * (FX[j][i + 1] - FX[j][i] + FZ[j + 1][i] - FZ[j][i])
                new[j, i] = x if x > 0.0 else 0.0
    return new, out


@pytest.mark.parametrize("open_bc", [P.CLOSED, P.OPEN_ALL, P.OPEN_WEST | P.OPEN_NORTH])
def test_step_field_is_the_scheme_bit_for_bit(open_bc):
    """The compiled transport (whose open-water faces take a vectorised loop and the others
    the general form) equals the scheme written out face by face, to the last bit: land in
    some rows, all-water rows and columns, both flow signs, still and non-finite faces."""
    rng = np.random.default_rng(7)
    nz, nx, h, dt, kappa = 11, 13, 10.0, 1.2, 0.8
    land = np.zeros((nz, nx), dtype=np.uint8)
    land[3, 5:8] = 1
    land[7:9, 0:2] = 1
    land[10, 12] = 1
    C0 = rng.random((nz, nx)) ** 3 * (1 - land)
    U = rng.normal(0.0, 0.5, (nz, nx + 1))
    V = rng.normal(0.0, 0.5, (nz + 1, nx))
    U[2, 4] = 0.0
    U[5, 6] = np.nan
    V[6, 3] = np.inf
    C = C0[None].copy()
    work = P.make_work(C)
    ref, ref_out = C0.copy(), 0.0
    for _ in range(6):
        out = P.step_field(C, P.KIND_TRACER, NO_DECAY, U, V, land, h, dt, kappa, open_bc, work)
        # dt is within one sub-step here (asserted), so the reference takes one
        umax = max(abs(x) for x in np.nan_to_num(U, nan=0.0, posinf=0.0).ravel())
        vmax = max(abs(x) for x in np.nan_to_num(V, nan=0.0, posinf=0.0).ravel())
        assert (2.0 * (umax + vmax) / h + 4.0 * kappa / h ** 2) * dt <= 0.9
        ref, ref_out = _ref_substep(ref, U, V, land, h, dt, kappa, open_bc)
        assert np.array_equal(C[0].view(np.int64), ref.view(np.int64))
        assert out == ref_out


def test_max_face_speeds_are_the_largest_flux_carrying_speeds():
    """The CFL speeds (taken on the values' bits) are the largest |u| and |v| over the faces
    that can carry flux, NaN and inf read as 0: every boundary setting, land, signed zeros,
    subnormals and huge values."""
    rng = np.random.default_rng(11)
    for _ in range(100):
        nz, nx = (int(n) for n in rng.integers(1, 9, 2))
        U = rng.normal(0.0, 1.0, (nz, nx + 1)) * 10.0 ** rng.integers(-300, 300)
        V = rng.normal(0.0, 1.0, (nz + 1, nx))
        for A in (U, V):
            m = rng.random(A.shape) < 0.15
            A[m] = rng.choice([np.nan, np.inf, -np.inf, 0.0, -0.0, 5e-324], int(m.sum()))
        land = (rng.random((nz, nx)) < 0.2).astype(np.uint8)
        water = land == 0
        for bc in range(16):
            ux = np.zeros((nz, nx + 1), bool)
            ux[:, 1:nx] = water[:, :-1] & water[:, 1:]
            ux[:, 0] = bool(bc & P.OPEN_WEST) & water[:, 0]
            ux[:, nx] = bool(bc & P.OPEN_EAST) & water[:, -1]
            vz = np.zeros((nz + 1, nx), bool)
            vz[1:nz] = water[:-1] & water[1:]
            vz[0] = bool(bc & P.OPEN_SOUTH) & water[0]
            vz[nz] = bool(bc & P.OPEN_NORTH) & water[-1]
            speeds = [np.abs(np.where(np.isfinite(A), A, 0.0))[m] for A, m in ((U, ux), (V, vz))]
            want = [float(s.max()) if s.size else 0.0 for s in speeds]
            got = P._max_face_speeds(U, V, land, bc, np.zeros(4))
            assert [float(g) for g in got] == want
