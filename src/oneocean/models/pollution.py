"""Pollution concentration fields on a local regular grid: one interface, several kinds.

A *field* is three things, all passable to ``@njit`` code:

- ``C`` : (n_species, nz, nx) float64, concentration in kg m-2 (mass per horizontal area);
  cell ``(j, i)`` is centred at world ``(x0 + i*h, z0 + j*h)`` (x east, z north, metres) and
  covers ``[x - h/2, x + h/2] x [z - h/2, z + h/2]``; the field's extent is therefore
  ``[x0 - h/2, x0 + (nx - 1/2) h] x [z0 - h/2, z0 + (nz - 1/2) h]``.
- ``kind`` : int, the source/sink model every kernel dispatches on
  (:data:`KIND_TRACER`, :data:`KIND_REACTION`).
- ``params`` : (n_params,) float64, the kind's parameters (layouts below; build them with
  :func:`field_params`).

Kinds and their ``params`` layout:

``KIND_TRACER = 0``
    Passive tracer(s) with first-order decay: ``params = [decay_rate (s-1)]`` (an empty vector
    means no decay); every species decays at the same rate.
``KIND_REACTION = 1``
    Multi-species linear reaction ``dC/dt = K C`` applied cell by cell (exactly, through a
    non-negative matrix exponential): ``params = K.ravel()`` (row-major, ``n_species**2``
    values, s-1). ``K`` must be Metzler (off-diagonals >= 0); columns summing to 0 conserve
    total mass. This is the slot for richer (OCPNet-style) multi-species fields: a new kind
    adds a branch to the reaction dispatch and a layout here, and tasks do not change.

Transport is the same for every kind and species: conservative finite-volume advection
(flux form, upwind-biased with a van Leer-limited second-order reconstruction) plus explicit
diffusion, with internal CFL-safe sub-steps. Land cells and closed boundaries pass no flux;
open boundaries (bitmask :data:`OPEN_WEST` ... :data:`OPEN_NORTH`) let mass leave by advection
(inflow carries zero concentration) and diffusion (zero concentration outside), and the mass
that left is returned so budgets close.

Velocities live on cell faces:

- ``u_face_x`` : (nz, nx + 1) float64, m s-1, eastward velocity on x-faces; face ``(j, i)`` is
  the west face of cell ``(j, i)`` at world ``(x0 + (i - 1/2) h, z0 + j h)``.
- ``v_face_z`` : (nz + 1, nx) float64, m s-1, northward velocity on z-faces; face ``(j, i)`` is
  the south face of cell ``(j, i)`` at world ``(x0 + i h, z0 + (j - 1/2) h)``.

:func:`face_coordinates` gives those positions (for sampling currents there) and
:func:`faces_from_centers` averages cell-centre velocities onto faces.

The kernels run without reference counting (:func:`oneocean.engine._jit.hot_kernel`). In a
transport sub-step, faces whose two cells and their outer neighbours are water (away from
the domain's edge) take a branch-light loop the compiler vectorises; every other face takes
the general form. Both do the same arithmetic, so no result depends on which loop a face
took (tested against the scheme written out face by face).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ..engine._jit import hot_kernel
from ..errors import ConfigError, DataError
from ..engine import libm

__all__ = [
    "KIND_TRACER", "KIND_REACTION", "KINDS",
    "CLOSED", "OPEN_WEST", "OPEN_EAST", "OPEN_SOUTH", "OPEN_NORTH", "OPEN_ALL",
    "step_field", "emit", "remove_in_radius", "probe", "total_mass", "species_mass",
    "centroid", "faces_from_centers", "work_size",
    "make_work", "field_params", "face_coordinates", "cell_centres", "make_spill",
]

#: Kind 0: passive tracer with first-order decay.
KIND_TRACER = 0
#: Kind 1: multi-species linear reaction ``dC/dt = K C``.
KIND_REACTION = 1
KINDS = {"tracer": KIND_TRACER, "reaction": KIND_REACTION}

#: Boundary bitmask for ``step_field(..., open_bc, ...)``: 0 closes every side.
CLOSED = 0
OPEN_WEST = 1
OPEN_EAST = 2
OPEN_SOUTH = 4
OPEN_NORTH = 8
OPEN_ALL = OPEN_WEST | OPEN_EAST | OPEN_SOUTH | OPEN_NORTH

_U = np.uint64  # an unsigned index skips numba's negative-index wrap-around

#: Fraction of the positivity-limit time step actually used by a sub-step.
_CFL_SAFETY = 0.9


# ------------------------------------------------------------------------------------------
# transport
# ------------------------------------------------------------------------------------------

@hot_kernel(error_model="python")
def work_size(n_species, nz, nx):
    """Length of the float64 work vector :func:`step_field` needs.

    Parameters
    ----------
    n_species, nz, nx : int
        Shape of the concentration array ``C``.

    Returns
    -------
    int
        ``nz*(nx+1) + (nz+1)*nx + 3*n_species**2 + n_species``.
    """
    return nz * (nx + 1) + (nz + 1) * nx + 3 * n_species * n_species + n_species


@numba.njit(cache=True, inline="always", error_model="numpy")
def _vanleer(a, b):
    """Van Leer limited slope from the backward and forward differences ``a`` and ``b``.

    Inlined into the transport's face loops (a call per face cost as much as the face's
    arithmetic) and branch-free: the quotient is computed either way and selected (its
    callers use the numpy error model, so ``a + b == 0`` gives inf/NaN there, unused, instead
    of raising). The same value as the branching form (``a * b > 0`` implies ``a + b != 0``)."""
    q = 2.0 * a * b / (a + b)
    return 0.0 if a * b <= 0.0 else q


@numba.njit(cache=True, inline="always")
def _clean(u):
    """Velocity read from a face: NaN or inf count as 0 (no flow)."""
    if math.isfinite(u):
        return u
    return 0.0


@numba.njit(cache=True, inline="always")
def _water_row(land, j):
    """True when row ``j`` of ``land`` has no land cell (an OR over the row: no early exit,
    so the scan vectorises)."""
    acc = 0
    for i in range(land.shape[1]):
        acc |= land[j, i]
    return acc == 0


@numba.njit(cache=True, inline="always", error_model="numpy")
def _open_face_flux(u, cu2, cu, cd, cd2, dt, inv_h, kappa):
    """Flux through an interior face between two water cells whose second neighbours on both
    sides are water too: ``cu2, cu`` upstream of the face for ``u > 0`` (west/south), ``cd,
    cd2`` downstream. The same arithmetic as the general face (:func:`_face`): the limited
    slope is formed from the differences the velocity's sign selects."""
    nu = abs(u) * dt * inv_h
    up = u > 0.0
    # the upwind reconstruction: from the west/south cell for u > 0, the east/north otherwise;
    # (cd - a) is (cd + (-a)) and a sign flip of a product is exact, so one form serves both
    slope = _vanleer(cu - cu2 if up else cd - cu, cd - cu if up else cd2 - cd)
    flux = u * ((cu if up else cd) + 0.5 * (1.0 - nu) * (slope if up else -slope))
    flux = flux if u != 0.0 else 0.0
    flux -= kappa * (cd - cu) * inv_h
    return flux


@numba.njit(cache=True, inline="always")
def _at(A, s, line, k, along_z):
    """``A[s, line, k]`` along x (``line`` the row), ``A[s, k, line]`` along z."""
    return A[s, k, line] if along_z else A[s, line, k]


@numba.njit(cache=True, inline="always")
def _wet(land, line, k, along_z):
    """Cell ``k`` along ``line`` is water (:func:`_at`'s indexing)."""
    return (land[k, line] if along_z else land[line, k]) == 0


@numba.njit(cache=True, inline="always", error_model="numpy")
def _face(C, s, vel, land, line, f, n, dt, inv_h, kappa, open_lo, open_hi, along_z):
    """Flux through face ``f`` of ``line``, any face (domain edge, land, missing neighbours):
    x-face ``(line, f)`` (``vel = u_face_x``) or, ``along_z``, z-face ``(f, line)``
    (``vel = v_face_z``); ``n`` cells along the line, ``open_lo``/``open_hi`` its west/south
    and east/north sides."""
    lo = f - 1  # cell west/south of the face
    hi = f  # cell east/north of the face
    flux = 0.0
    u = _clean(vel[f, line] if along_z else vel[line, f])
    nu = abs(u) * dt * inv_h
    if lo < 0 or hi >= n:
        # domain boundary
        inner = hi if lo < 0 else lo
        is_open = open_lo if lo < 0 else open_hi
        if is_open and _wet(land, line, inner, along_z):
            c = _at(C, s, line, inner, along_z)
            # upwind value when flowing out; zero-concentration inflow
            if lo < 0:
                if u < 0.0:
                    flux += u * c
                flux -= kappa * c * inv_h  # ghost 0 to the west/south: flux points out
            else:
                if u > 0.0:
                    flux += u * c
                flux += kappa * c * inv_h  # ghost concentration 0 to the east/north
    elif _wet(land, line, lo, along_z) and _wet(land, line, hi, along_z):
        cw = _at(C, s, line, lo, along_z)
        ce = _at(C, s, line, hi, along_z)
        if u > 0.0:
            # reconstruct from the west/south cell
            slope = 0.0
            if lo - 1 >= 0 and _wet(land, line, lo - 1, along_z):
                slope = _vanleer(cw - _at(C, s, line, lo - 1, along_z), ce - cw)
            flux = u * (cw + 0.5 * (1.0 - nu) * slope)
        elif u < 0.0:
            slope = 0.0
            if hi + 1 < n and _wet(land, line, hi + 1, along_z):
                slope = _vanleer(ce - cw, _at(C, s, line, hi + 1, along_z) - ce)
            flux = u * (ce - 0.5 * (1.0 - nu) * slope)
        flux -= kappa * (ce - cw) * inv_h
    return flux


@hot_kernel
def _transport_substep(C, s, u_face_x, v_face_z, land, h, dt, kappa, open_bc, work):
    """One forward-Euler flux-form sub-step of species ``s``; returns the mass that left.

    Faces whose stencil (two cells each side) is all water away from the domain's edge take
    a branch-light loop (:func:`_open_face_flux`) that the compiler vectorises; every other
    face takes the general form (:func:`_face`). Both do the same
    arithmetic, so the result does not depend on which loop a face took.
    """
    nz = C.shape[1]
    nx = C.shape[2]
    ox = 0  # x-face fluxes, (nz, nx + 1) row-major, kg m-1 s-1
    oz = nz * (nx + 1)  # z-face fluxes, (nz + 1, nx) row-major
    inv_h = 1.0 / h
    open_w = (open_bc & OPEN_WEST) != 0
    open_e = (open_bc & OPEN_EAST) != 0
    open_s = (open_bc & OPEN_SOUTH) != 0
    open_n = (open_bc & OPEN_NORTH) != 0

    # ---- x-faces
    for j in range(nz):
        o = ox + j * (nx + 1)
        if nx >= 4 and _water_row(land, j):
            for f in range(2, nx - 1):
                # unsigned indices: no negative-index wrap-around test, so no gathers
                a = _U(f)
                work[_U(o + f)] = _open_face_flux(_clean(u_face_x[_U(j), a]),
                                                  C[_U(s), _U(j), a - _U(2)],
                                                  C[_U(s), _U(j), a - _U(1)],
                                                  C[_U(s), _U(j), a], C[_U(s), _U(j), a + _U(1)],
                                                  dt, inv_h, kappa)
            for f in (0, 1, nx - 1, nx):
                work[o + f] = _face(C, s, u_face_x, land, j, f, nx, dt, inv_h, kappa,
                                    open_w, open_e, False)
        else:
            for f in range(nx + 1):
                work[o + f] = _face(C, s, u_face_x, land, j, f, nx, dt, inv_h, kappa,
                                    open_w, open_e, False)

    # ---- z-faces (water flags of rows f - 2 .. f + 1 rolled along)
    w2 = False
    w1 = False
    w0 = _water_row(land, 0)
    wn = nz > 1 and _water_row(land, 1)
    for f in range(nz + 1):
        o = oz + f * nx
        if 2 <= f <= nz - 2 and w2 and w1 and w0 and wn:
            for i in range(nx):
                a = _U(i)
                work[_U(o + i)] = _open_face_flux(_clean(v_face_z[_U(f), a]),
                                                  C[_U(s), _U(f - 2), a],
                                                  C[_U(s), _U(f - 1), a], C[_U(s), _U(f), a],
                                                  C[_U(s), _U(f + 1), a], dt, inv_h, kappa)
        else:
            for i in range(nx):
                work[o + i] = _face(C, s, v_face_z, land, i, f, nz, dt, inv_h, kappa,
                                    open_s, open_n, True)
        w2 = w1
        w1 = w0
        w0 = wn
        wn = f + 2 < nz and _water_row(land, f + 2)

    # ---- outflow through open boundaries (kg): outward flux * face length * dt
    out = 0.0
    for j in range(nz):
        out -= work[ox + j * (nx + 1)] * h * dt
        out += work[ox + j * (nx + 1) + nx] * h * dt
    for i in range(nx):
        out -= work[oz + i] * h * dt
        out += work[oz + nz * nx + i] * h * dt

    # ---- conservative update
    lam = dt * inv_h
    for j in range(nz):
        ow = ox + j * (nx + 1)
        os_ = oz + j * nx
        on = oz + (j + 1) * nx
        if _water_row(land, j):
            for i in range(nx):
                a = _U(i)
                div = (work[_U(ow + 1) + a] - work[_U(ow) + a] + work[_U(on) + a]
                       - work[_U(os_) + a])
                c = C[_U(s), _U(j), a] - lam * div
                # positivity-preserving sub-step; this only removes round-off (~1e-17 C)
                C[_U(s), _U(j), a] = c if c > 0.0 else 0.0
        else:
            for i in range(nx):
                if land[j, i] != 0:
                    continue
                div = work[ow + i + 1] - work[ow + i] + work[on + i] - work[os_ + i]
                c = C[s, j, i] - lam * div
                C[s, j, i] = c if c > 0.0 else 0.0
    return out


_ABS_BITS = np.int64(0x7FFFFFFFFFFFFFFF)   # all but the sign bit
_INF_BITS = np.int64(0x7FF0000000000000)   # the first non-finite magnitude


@numba.njit(cache=True, inline="always")
def _speed_bits(b):
    """The bits of ``abs(_clean(x))`` from the bits ``b`` of ``x``: the sign cleared, inf and
    NaN (exponent all ones) read as 0. For values >= 0 the bits order as the values do, so
    maxima can be taken on integers (a reduction the compiler vectorises; float maxima it
    may not reorder)."""
    a = b & _ABS_BITS
    return a if a < _INF_BITS else np.int64(0)


@numba.njit(cache=True, inline="always")
def _max_speed_bits(bits, j, lo, hi):
    """Bits of the largest ``|_clean(x)|`` over ``x = row j, columns lo..hi-1`` (0 if none)."""
    m = np.int64(0)
    for k in range(_U(lo), _U(hi)):
        a = _speed_bits(bits[_U(j), k])
        m = a if a > m else m
    return m


@hot_kernel(error_model="python")
def _max_face_speeds(u_face_x, v_face_z, land, open_bc, work):
    """Largest |u| over x-faces and |v| over z-faces that can carry flux (NaN and inf read
    as 0), taken on the values' bits (:func:`_speed_bits`: the same maxima); ``work[0]`` is
    used to turn the bits back into floats."""
    nz = land.shape[0]
    nx = land.shape[1]
    ub = u_face_x.view(np.int64)
    vb = v_face_z.view(np.int64)
    open_w = (open_bc & OPEN_WEST) != 0
    open_e = (open_bc & OPEN_EAST) != 0
    umax = np.int64(0)
    for j in range(nz):
        if open_w and land[j, 0] == 0:
            a = _speed_bits(ub[j, 0])
            umax = a if a > umax else umax
        if _water_row(land, j):
            a = _max_speed_bits(ub, j, 1, nx)
            umax = a if a > umax else umax
        else:
            for f in range(1, nx):
                if land[j, f - 1] == 0 and land[j, f] == 0:
                    a = _speed_bits(ub[j, f])
                    umax = a if a > umax else umax
        if open_e and land[j, nx - 1] == 0:
            a = _speed_bits(ub[j, nx])
            umax = a if a > umax else umax
    vmax = np.int64(0)
    if (open_bc & OPEN_SOUTH) != 0:
        for i in range(nx):
            if land[0, i] == 0:
                a = _speed_bits(vb[0, i])
                vmax = a if a > vmax else vmax
    wn = _water_row(land, 0)
    for f in range(1, nz):
        ws = wn
        wn = _water_row(land, f)
        if ws and wn:
            a = _max_speed_bits(vb, f, 0, nx)
            vmax = a if a > vmax else vmax
        else:
            for i in range(nx):
                if land[f - 1, i] == 0 and land[f, i] == 0:
                    a = _speed_bits(vb[f, i])
                    vmax = a if a > vmax else vmax
    if (open_bc & OPEN_NORTH) != 0:
        for i in range(nx):
            if land[nz - 1, i] == 0:
                a = _speed_bits(vb[nz, i])
                vmax = a if a > vmax else vmax
    wb = work.view(np.int64)
    wb[0] = umax
    u = work[0]
    wb[0] = vmax
    return u, work[0]


@hot_kernel(error_model="python")
def _expm_metzler(K, ns, t, work, o_e, o_a, o_b):
    """``exp(K t)`` for a Metzler ``K`` into ``work[o_e:o_e+ns*ns]`` (row-major), entries >= 0.

    Uses the shift ``exp(Kt) = exp(-mu t) exp((K + mu I) t)`` with ``K + mu I >= 0`` so every
    Taylor term is non-negative, then scaling and squaring.
    """
    mu = 0.0
    for a in range(ns):
        d = -K[a * ns + a]
        if d > mu:
            mu = d
    # M = (K + mu I) t / 2**m with max row sum <= 0.5
    norm = 0.0
    for a in range(ns):
        row = 0.0
        for b in range(ns):
            m = K[a * ns + b] * t
            if a == b:
                m += mu * t
            row += abs(m)
        if row > norm:
            norm = row
    m_sq = 0
    while norm > 0.5:
        norm *= 0.5
        m_sq += 1
    scale = 1.0 / (2.0 ** m_sq)
    # Taylor: E = I + M + M^2/2 + ... (18 terms, error < 0.5**19/19!)
    for a in range(ns):
        for b in range(ns):
            val = K[a * ns + b] * t * scale
            if a == b:
                val += mu * t * scale
            work[o_a + a * ns + b] = val  # A holds M
            work[o_e + a * ns + b] = 1.0 if a == b else 0.0
            work[o_b + a * ns + b] = 1.0 if a == b else 0.0  # B holds the running term
    for k in range(1, 19):
        # term_k = term_{k-1} @ M / k, row by row: row a of the new term only reads row a of
        # the old one, which is staged in the spare row right after B (see work_size)
        for a in range(ns):
            for b in range(ns):
                acc = 0.0
                for c in range(ns):
                    acc += work[o_b + a * ns + c] * work[o_a + c * ns + b]
                work[o_b + ns * ns + b] = acc / k
            for b in range(ns):
                work[o_b + a * ns + b] = work[o_b + ns * ns + b]
        for a in range(ns):
            for b in range(ns):
                work[o_e + a * ns + b] += work[o_b + a * ns + b]
    # squaring: E <- E @ E, m_sq times (A is free now)
    for _ in range(m_sq):
        for a in range(ns):
            for b in range(ns):
                acc = 0.0
                for c in range(ns):
                    acc += work[o_e + a * ns + c] * work[o_e + c * ns + b]
                work[o_a + a * ns + b] = acc
        for a in range(ns * ns):
            work[o_e + a] = work[o_a + a]
    damp = math.exp(-mu * t)
    for a in range(ns * ns):
        work[o_e + a] *= damp


@hot_kernel(error_model="python")
def _react(C, kind, params, dt, land, work):
    """Apply the kind's source/sink term over ``dt`` (exactly, cell by cell)."""
    ns = C.shape[0]
    nz = C.shape[1]
    nx = C.shape[2]
    if kind == KIND_TRACER:
        if params.shape[0] == 0:
            return
        lam = params[0]
        if lam == 0.0:
            return
        if lam < 0.0:
            raise ValueError("step_field: tracer decay rate params[0] must be >= 0")
        fac = math.exp(-lam * dt)
        for s in range(ns):
            for j in range(nz):
                for i in range(nx):
                    C[s, j, i] *= fac
    elif kind == KIND_REACTION:
        if params.shape[0] < ns * ns:
            raise ValueError("step_field: reaction kind needs n_species**2 params (K row-major)")
        for a in range(ns):
            for b in range(ns):
                if a != b and params[a * ns + b] < 0.0:
                    raise ValueError("step_field: reaction matrix K must have off-diagonals >= 0")
        base = work.shape[0] - (3 * ns * ns + ns)
        o_e = base
        o_a = base + ns * ns
        o_b = base + 2 * ns * ns  # B (ns*ns) followed by a spare row of ns
        _expm_metzler(params, ns, dt, work, o_e, o_a, o_b)
        # C_cell <- E @ C_cell ; A is reused as the per-cell scratch vector
        for j in range(nz):
            for i in range(nx):
                if land[j, i] != 0:
                    continue
                for a in range(ns):
                    acc = 0.0
                    for b in range(ns):
                        acc += work[o_e + a * ns + b] * C[b, j, i]
                    work[o_a + a] = acc
                for a in range(ns):
                    C[a, j, i] = work[o_a + a]
    else:
        raise ValueError("step_field: unknown field kind (valid: 0 tracer, 1 reaction)")


@hot_kernel(error_model="python")
def step_field(C, kind, params, u_face_x, v_face_z, land, h, dt, kappa, open_bc, work):
    """Advance the field by ``dt``: advection + diffusion (sub-stepped), then reaction/decay.

    Parameters
    ----------
    C : (n_species, nz, nx) float64, kg m-2
        Concentration, updated in place; stays >= 0.
    kind : int
        Field kind (:data:`KIND_TRACER` or :data:`KIND_REACTION`).
    params : (n_params,) float64
        Kind parameters (see module docstring and :func:`field_params`).
    u_face_x : (nz, nx + 1) float64, m s-1
        Eastward velocity on x-faces (NaN/inf read as 0).
    v_face_z : (nz + 1, nx) float64, m s-1
        Northward velocity on z-faces (NaN/inf read as 0).
    land : (nz, nx) uint8
        Nonzero = land: no flux crosses a land cell's faces and its concentration is frozen.
        (A bool mask works too but compiles a second specialisation, ~8 s once.)
    h : float, m
        Cell size.
    dt : float, s
        Time to advance (split internally into CFL-safe sub-steps).
    kappa : float, m2 s-1
        Horizontal diffusivity, same for every species (>= 0).
    open_bc : int
        Bitmask of open sides, a bitwise OR of :data:`OPEN_WEST`, :data:`OPEN_EAST`,
        :data:`OPEN_SOUTH` and :data:`OPEN_NORTH`; 0 (:data:`CLOSED`) closes the domain.
    work : (>= work_size(n_species, nz, nx),) float64
        Scratch space, contents irrelevant on entry (see :func:`make_work`).

    Returns
    -------
    float, kg
        Mass (summed over species) that left through open boundaries during ``dt``. Without
        sinks, ``total_mass`` before = ``total_mass`` after + the returned outflow (to round-off).

    Notes
    -----
    Sub-step ``dt_s`` satisfies ``dt_s * (2 (|u|max + |v|max) / h + 4 kappa / h**2) <= 0.9``,
    which keeps the limited scheme positive; the van Leer reconstruction carries the
    ``(1 - Courant)`` factor (second order in space and time for smooth 1-D flow).
    """
    ns = C.shape[0]
    nz = C.shape[1]
    nx = C.shape[2]
    if u_face_x.shape[0] != nz or u_face_x.shape[1] != nx + 1:
        raise ValueError("step_field: u_face_x must have shape (nz, nx + 1)")
    if v_face_z.shape[0] != nz + 1 or v_face_z.shape[1] != nx:
        raise ValueError("step_field: v_face_z must have shape (nz + 1, nx)")
    if land.shape[0] != nz or land.shape[1] != nx:
        raise ValueError("step_field: land must have shape (nz, nx)")
    if work.shape[0] < work_size(ns, nz, nx):
        raise ValueError("step_field: work is too short (see work_size)")
    if not (h > 0.0) or not (dt >= 0.0) or not (kappa >= 0.0):
        raise ValueError("step_field: need h > 0, dt >= 0 and kappa >= 0")
    if dt == 0.0:
        return 0.0
    umax, vmax = _max_face_speeds(u_face_x, v_face_z, land, open_bc, work)
    rate = 2.0 * (umax + vmax) / h + 4.0 * kappa / (h * h)
    n_sub = 1
    if rate * dt > _CFL_SAFETY:
        n_sub = int(math.ceil(rate * dt / _CFL_SAFETY))
    dts = dt / n_sub
    out = 0.0
    if rate > 0.0:
        for _ in range(n_sub):
            for s in range(ns):
                out += _transport_substep(C, s, u_face_x, v_face_z, land, h, dts, kappa,
                                          open_bc, work)
    _react(C, kind, params, dt, land, work)
    return out


# ------------------------------------------------------------------------------------------
# sources, sinks, probes
# ------------------------------------------------------------------------------------------

@hot_kernel(error_model="python")
def _axis_weights(x, x0, h, n):
    """Bilinear stencil along one axis: (i0, i1, w1) with weight 1-w1 on i0; i0 = -1 if outside.

    Inside the half cell between the extent's edge and the first/last centre the stencil
    clamps to that cell (weights renormalised so they always sum to 1).
    """
    f = (x - x0) / h
    if not (f >= -0.5 and f <= n - 0.5):
        return -1, -1, 0.0
    if f <= 0.0:
        return 0, 0, 0.0
    if f >= n - 1:
        return n - 1, n - 1, 0.0
    i0 = int(math.floor(f))
    if i0 > n - 2:
        i0 = n - 2
    return i0, i0 + 1, f - i0


@hot_kernel(error_model="python")
def emit(C, species, x, z, rate, dt, x0, z0, h):
    """Point source: add ``rate * dt`` kg of ``species`` at world ``(x, z)``, split bilinearly.

    Parameters
    ----------
    C : (n_species, nz, nx) float64, kg m-2
        Concentration, updated in place.
    species : int
        Species index.
    x, z : float, m
        Source position (world).
    rate : float, kg s-1
        Emission rate (>= 0).
    dt : float, s
        Duration.
    x0, z0 : float, m
        World centre of cell (0, 0).
    h : float, m
        Cell size.

    Returns
    -------
    float, kg
        Mass added: exactly ``rate * dt`` inside the field's extent, 0 outside it. The four
        weights are the bilinear ones between the surrounding cell centres (so the added mass
        is centred on ``(x, z)``), clamped at the edges. The caller keeps sources off land:
        mass put in a land cell stays there (frozen, still counted by :func:`total_mass`).
    """
    if rate < 0.0 or dt < 0.0:
        raise ValueError("emit: rate and dt must be >= 0")
    if species < 0 or species >= C.shape[0]:
        raise ValueError("emit: species index out of range")
    nz = C.shape[1]
    nx = C.shape[2]
    i0, i1, wx = _axis_weights(x, x0, h, nx)
    j0, j1, wz = _axis_weights(z, z0, h, nz)
    if i0 < 0 or j0 < 0:
        return 0.0
    dm = rate * dt
    c = dm / (h * h)
    C[species, j0, i0] += c * (1.0 - wx) * (1.0 - wz)
    C[species, j0, i1] += c * wx * (1.0 - wz)
    C[species, j1, i0] += c * (1.0 - wx) * wz
    C[species, j1, i1] += c * wx * wz
    return dm


@hot_kernel(error_model="python")
def probe(C, species, x, z, x0, z0, h):
    """Bilinear concentration of ``species`` at world ``(x, z)``; 0 outside the extent.

    Between the extent's edge and the outermost cell centres the value is held constant
    (nearest centre along that axis).

    Parameters
    ----------
    C : (n_species, nz, nx) float64
        Concentration, kg m-2.
    species : int
        Species index, ``0 <= species < n_species``.
    x, z : float
        Position (world x east, z north), m.
    x0, z0 : float
        World centre of cell (0, 0), m.
    h : float
        Cell size, m.

    Returns
    -------
    float
        Concentration, kg m-2.

    Raises
    ------
    ValueError
        If ``species`` is out of range.
    """
    if species < 0 or species >= C.shape[0]:
        raise ValueError("probe: species index out of range")
    nz = C.shape[1]
    nx = C.shape[2]
    i0, i1, wx = _axis_weights(x, x0, h, nx)
    j0, j1, wz = _axis_weights(z, z0, h, nz)
    if i0 < 0 or j0 < 0:
        return 0.0
    return ((1.0 - wz) * ((1.0 - wx) * C[species, j0, i0] + wx * C[species, j0, i1])
            + wz * ((1.0 - wx) * C[species, j1, i0] + wx * C[species, j1, i1]))


@hot_kernel(error_model="python")
def remove_in_radius(C, x, z, radius, efficiency, dt, x0, z0, h):
    """A vehicle at ``(x, z)`` removes a fraction of the mass (all species) near it.

    Every cell whose centre lies within ``radius`` of ``(x, z)`` loses the fraction
    ``min(efficiency * dt, 1)`` of its concentration. A radius below ``h / sqrt(2)`` may cover
    no centre at all.

    Parameters
    ----------
    C : (n_species, nz, nx) float64, kg m-2
        Concentration, updated in place (never made negative).
    x, z : float, m
        Vehicle position (world).
    radius : float, m
        Removal radius.
    efficiency : float, s-1
        Fraction removed per second (>= 0).
    dt : float, s
        Duration.
    x0, z0, h : float, m
        Grid origin (centre of cell (0, 0)) and cell size.

    Returns
    -------
    float, kg
        Mass removed (equals the drop of :func:`total_mass`).
    """
    if efficiency < 0.0 or dt < 0.0 or radius < 0.0:
        raise ValueError("remove_in_radius: radius, efficiency and dt must be >= 0")
    frac = efficiency * dt
    if frac > 1.0:
        frac = 1.0
    keep = 1.0 - frac
    ns = C.shape[0]
    nz = C.shape[1]
    nx = C.shape[2]
    if frac == 0.0 or not (math.isfinite(x) and math.isfinite(z)):
        return 0.0
    ilo = max(0, int(math.ceil((x - radius - x0) / h)))
    ihi = min(nx - 1, int(math.floor((x + radius - x0) / h)))
    jlo = max(0, int(math.ceil((z - radius - z0) / h)))
    jhi = min(nz - 1, int(math.floor((z + radius - z0) / h)))
    r2 = radius * radius
    removed = 0.0
    for j in range(jlo, jhi + 1):
        dz = z0 + j * h - z
        for i in range(ilo, ihi + 1):
            dx = x0 + i * h - x
            if dx * dx + dz * dz > r2:
                continue
            for s in range(ns):
                c = C[s, j, i]
                new = c * keep
                removed += c - new
                C[s, j, i] = new
    return removed * h * h


@hot_kernel(error_model="python")
def total_mass(C, h):
    """Total mass over all species and cells: ``sum(C) * h**2``.

    Parameters
    ----------
    C : (n_species, nz, nx) float64
        Concentration, kg m-2.
    h : float
        Cell size, m.

    Returns
    -------
    float
        Mass, kg.
    """
    acc = 0.0
    for s in range(C.shape[0]):
        for j in range(C.shape[1]):
            for i in range(C.shape[2]):
                acc += C[s, j, i]
    return acc * h * h


@hot_kernel(error_model="python")
def species_mass(C, species, h):
    """Mass of one species: ``sum(C[species]) * h**2``.

    Parameters
    ----------
    C : (n_species, nz, nx) float64
        Concentration, kg m-2.
    species : int
        Species index, ``0 <= species < n_species``.
    h : float
        Cell size, m.

    Returns
    -------
    float
        Mass, kg.

    Raises
    ------
    ValueError
        If ``species`` is out of range.
    """
    if species < 0 or species >= C.shape[0]:
        raise ValueError("species_mass: species index out of range")
    acc = 0.0
    for j in range(C.shape[1]):
        for i in range(C.shape[2]):
            acc += C[species, j, i]
    return acc * h * h


@hot_kernel(error_model="python")
def centroid(C, species, x0, z0, h):
    """Mass centroid of ``species``.

    Parameters
    ----------
    C : (n_species, nz, nx) float64
        Concentration, kg m-2.
    species : int
        Species index, ``0 <= species < n_species``.
    x0, z0 : float
        World centre of cell (0, 0), m.
    h : float
        Cell size, m.

    Returns
    -------
    tuple of float
        ``(x_c, z_c, mass)`` in m, m, kg; ``(NaN, NaN, 0)`` if the species holds no mass.

    Raises
    ------
    ValueError
        If ``species`` is out of range.
    """
    if species < 0 or species >= C.shape[0]:
        raise ValueError("centroid: species index out of range")
    m = 0.0
    mx = 0.0
    mz = 0.0
    for j in range(C.shape[1]):
        for i in range(C.shape[2]):
            c = C[species, j, i]
            m += c
            mx += c * (x0 + i * h)
            mz += c * (z0 + j * h)
    if m <= 0.0:
        return np.nan, np.nan, 0.0
    return mx / m, mz / m, m * h * h


@numba.njit(cache=True)
def faces_from_centers(uc, vc):
    """Average cell-centre velocities onto faces.

    Parameters
    ----------
    uc, vc : (nz, nx) float64, m s-1
        Eastward / northward velocity at cell centres (NaN read as 0).

    Returns
    -------
    u_face_x : (nz, nx + 1) float64, m s-1
        Mean of the two adjacent centres; boundary faces copy the adjacent centre.
    v_face_z : (nz + 1, nx) float64, m s-1
        Same along z.
    """
    nz = uc.shape[0]
    nx = uc.shape[1]
    uf = np.zeros((nz, nx + 1))
    vf = np.zeros((nz + 1, nx))
    for j in range(nz):
        for f in range(nx + 1):
            a = _clean(uc[j, f - 1]) if f > 0 else _clean(uc[j, 0])
            b = _clean(uc[j, f]) if f < nx else _clean(uc[j, nx - 1])
            uf[j, f] = 0.5 * (a + b)
    for f in range(nz + 1):
        for i in range(nx):
            a = _clean(vc[f - 1, i]) if f > 0 else _clean(vc[0, i])
            b = _clean(vc[f, i]) if f < nz else _clean(vc[nz - 1, i])
            vf[f, i] = 0.5 * (a + b)
    return uf, vf


# ------------------------------------------------------------------------------------------
# Python helpers (orchestration side)
# ------------------------------------------------------------------------------------------

def make_work(C: np.ndarray) -> np.ndarray:
    """A zeroed float64 work vector sized for :func:`step_field` on ``C``.

    Parameters
    ----------
    C : (n_species, nz, nx) ndarray
        The concentration array the work vector serves.

    Returns
    -------
    (work_size(n_species, nz, nx),) float64
        Zeros (:func:`work_size`).
    """
    ns, nz, nx = C.shape
    return np.zeros(work_size(ns, nz, nx), dtype=np.float64)


def field_params(kind: int | str = KIND_TRACER, n_species: int = 1, *, decay: float = 0.0,
                 reaction=None) -> tuple[int, np.ndarray]:
    """Build ``(kind, params)`` for :func:`step_field`.

    Parameters
    ----------
    kind : int or {"tracer", "reaction"}
        Field kind.
    n_species : int
        Number of species (must match ``C.shape[0]``).
    decay : float, s-1
        Tracer kind: first-order decay rate (>= 0).
    reaction : (n_species, n_species) array_like, s-1
        Reaction kind: ``K`` in ``dC/dt = K C`` (off-diagonals >= 0). Defaults to
        ``-decay * I``.

    Returns
    -------
    kind : int
        :data:`KIND_TRACER` or :data:`KIND_REACTION`.
    params : (n_params,) float64
        ``[decay]`` (tracer) or ``K.ravel()`` (reaction, row-major), s-1.

    Raises
    ------
    ConfigError
        An unknown kind, a negative decay, a reaction matrix for the tracer kind, or a matrix
        of the wrong shape, non-finite or with negative off-diagonals.
    """
    if isinstance(kind, str):
        if kind not in KINDS:
            opts = ", ".join(repr(k) for k in KINDS)
            raise ConfigError(f"pollution kind: invalid value {kind!r}. Valid options are ({opts}).")
        kind = KINDS[kind]
    if kind not in KINDS.values():
        raise ConfigError(f"pollution kind: invalid value {kind!r}. Valid options are (0, 1).")
    if not (decay >= 0.0):
        raise ConfigError(f"pollution decay: must be >= 0, got {decay!r}")
    if kind == KIND_TRACER:
        if reaction is not None:
            raise ConfigError("pollution reaction: only the 'reaction' kind takes a matrix")
        return KIND_TRACER, np.array([float(decay)], dtype=np.float64)
    K = -float(decay) * np.eye(n_species) if reaction is None else np.asarray(reaction, float)
    if K.shape != (n_species, n_species):
        raise ConfigError(f"pollution reaction: matrix shape {K.shape} != ({n_species}, {n_species})")
    off = K - np.diag(np.diag(K))
    if (off < 0).any() or not np.isfinite(K).all():
        raise ConfigError("pollution reaction: off-diagonal entries must be finite and >= 0")
    return KIND_REACTION, np.ascontiguousarray(K, dtype=np.float64).ravel()


def cell_centres(nx: int, nz: int, x0: float, z0: float, h: float):
    """World coordinates of the cell centres.

    Parameters
    ----------
    nx, nz : int
        Grid size (cells along x and z).
    x0, z0 : float
        World centre of cell (0, 0), m.
    h : float
        Cell size, m.

    Returns
    -------
    x : (nx,) float64
        Centres along x (east), m.
    z : (nz,) float64
        Centres along z (north), m.
    """
    return x0 + h * np.arange(nx, dtype=float), z0 + h * np.arange(nz, dtype=float)


def face_coordinates(nx: int, nz: int, x0: float, z0: float, h: float):
    """World coordinates where :func:`step_field` expects face velocities.

    Parameters
    ----------
    nx, nz : int
        Grid size (cells along x and z).
    x0, z0 : float
        World centre of cell (0, 0), m.
    h : float
        Cell size, m.

    Returns
    -------
    xu : (nx + 1,) float64
        x of the x-faces, m: ``u_face_x[j, i]`` lives at ``(xu[i], zu[j])``.
    zu : (nz,) float64
        z of the x-faces, m.
    xv : (nx,) float64
        x of the z-faces, m: ``v_face_z[j, i]`` lives at ``(xv[i], zv[j])``.
    zv : (nz + 1,) float64
        z of the z-faces, m.
    """
    xc, zc = cell_centres(nx, nz, x0, z0, h)
    xu = x0 + h * (np.arange(nx + 1, dtype=float) - 0.5)
    zv = z0 + h * (np.arange(nz + 1, dtype=float) - 0.5)
    return xu, zc, xc, zv


def make_spill(nx: int, nz: int, h: float, centre, radius: float, mass: float, rng=None, *,
               x0: float = 0.0, z0: float = 0.0, n_species: int = 1, species: int = 0,
               land=None) -> np.ndarray:
    """An initial Gaussian-ish blob of total mass ``mass`` (kg).

    Parameters
    ----------
    nx, nz : int
        Grid size.
    h : float, m
        Cell size.
    centre : (2,) float, m
        Blob centre ``(x, z)`` in world coordinates (same frame as ``x0, z0``).
    radius : float, m
        About 86 % of the mass lies within ``radius`` (Gaussian sigma = radius / 2, cut at
        2 radius).
    mass : float, kg
        Total mass (> 0), exact up to round-off.
    rng : numpy.random.Generator, optional
        If given, the blob is stretched (aspect 1..2) along a random direction; ``None`` gives
        the round Gaussian.
    x0, z0 : float, m
        World centre of cell (0, 0).
    n_species, species : int
        Shape of the returned array and the species that holds the spill.
    land : (nz, nx) array_like, optional
        Nonzero = land; the blob is zero there (and renormalised over water).

    Returns
    -------
    C : (n_species, nz, nx) float64, kg m-2
        Concentration, zero outside ``species``.

    Raises
    ------
    ConfigError
        If ``radius``, ``mass`` or ``h`` is not > 0.
    DataError
        If no water cell lies within ``2 radius`` of ``centre``.
    """
    if not (radius > 0 and mass > 0 and h > 0):
        raise ConfigError(f"make_spill: need radius, mass and h > 0 (got {radius}, {mass}, {h})")
    xc, zc = cell_centres(nx, nz, x0, z0, h)
    X, Z = np.meshgrid(xc - float(centre[0]), zc - float(centre[1]))
    sigma = 0.5 * radius
    if rng is None:
        a, b, th = sigma, sigma, 0.0
    else:
        stretch = rng.uniform(1.0, 2.0)
        th = rng.uniform(0.0, np.pi)
        a, b = sigma * np.sqrt(stretch), sigma / np.sqrt(stretch)
    ct, st = libm.cos(th), libm.sin(th)
    p = ct * X + st * Z
    q = -st * X + ct * Z
    w = libm.exp(-0.5 * ((p / a) ** 2 + (q / b) ** 2))
    w[X ** 2 + Z ** 2 > (2.0 * radius) ** 2] = 0.0
    if land is not None:
        w[np.asarray(land) != 0] = 0.0
    total = w.sum()
    if not total > 0:
        raise DataError(f"make_spill: no water cell near centre {tuple(centre)} within 2*radius")
    C = np.zeros((n_species, nz, nx), dtype=np.float64)
    C[species] = w * (mass / (total * h * h))
    return C


@hot_kernel(inline="always")
def _pairwise_leaf(a, lo, n):
    """NumPy's pairwise sum of at most 128 values (eight running sums)."""
    if n < 8:
        res = -0.0
        for i in range(n):
            res += a[lo + i]
        return res
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = 8
    while i < n - n % 8:
        k = lo + i
        r0 += a[k]
        r1 += a[k + 1]
        r2 += a[k + 2]
        r3 += a[k + 3]
        r4 += a[k + 4]
        r5 += a[k + 5]
        r6 += a[k + 6]
        r7 += a[k + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@hot_kernel
def pairwise_sum(a, lo, n, stack):
    """``a[lo:lo + n].sum()`` of a contiguous float64 array in NumPy's order: its pairwise
    summation (eight running sums over blocks of at most 128 values; above that the two
    halves, the first a multiple of 8 long, summed apart and added), without the identity
    ``0.0`` NumPy's reduction starts from (add it for ``np.sum``'s value). Iterative (numba's
    cache cannot load a recursive function): the halves wait on ``stack``.

    Parameters
    ----------
    a : (m,) float64
        Values.
    lo, n : int
        First index and count.
    stack : (64, 5) float64
        Work array (a half's start, length, state and the two partial sums per level).

    Returns
    -------
    float
    """
    if n <= 128:
        return _pairwise_leaf(a, lo, n)
    sp = 1
    stack[0, 0] = lo
    stack[0, 1] = n
    stack[0, 2] = 0.0
    out = 0.0
    while sp > 0:
        t = sp - 1
        s_lo = int(stack[t, 0])
        s_n = int(stack[t, 1])
        state = stack[t, 2]
        done = False
        v = 0.0
        if s_n <= 128:
            v = _pairwise_leaf(a, s_lo, s_n)
            done = True
        else:
            n2 = s_n // 2
            n2 -= n2 % 8
            if state == 0.0:
                stack[t, 2] = 1.0
                stack[sp, 0] = s_lo
                stack[sp, 1] = n2
                stack[sp, 2] = 0.0
                sp += 1
            elif state == 1.0:
                stack[t, 2] = 2.0
                stack[sp, 0] = s_lo + n2
                stack[sp, 1] = s_n - n2
                stack[sp, 2] = 0.0
                sp += 1
            else:
                v = stack[t, 3] + stack[t, 4]
                done = True
        if done:
            sp -= 1
            if sp == 0:
                out = v
            elif stack[sp - 1, 2] == 1.0:
                stack[sp - 1, 3] = v
            else:
                stack[sp - 1, 4] = v
    return out


@hot_kernel(inline="always")
def spill_box(n, h, x0, z0, cx, cz, radius, cut, mass, stretch, th, land, i0, i1, w, stack,
              out):
    """:func:`make_spill` of an ``n x n`` field (one species, ``rng`` drawing ``stretch``
    then ``th``), compiled, for a blob that lies in cells ``i0 .. i1 - 1`` along both axes
    (the caller's box holds every cell within ``2 radius`` of the centre): the same values.

    Parameters
    ----------
    n : int
        Cells per side.
    h, x0, z0 : float
        Cell size and world centre of cell (0, 0), m.
    cx, cz : float
        Blob centre, m.
    radius, mass : float
        As in :func:`make_spill`.
    cut : float
        ``(2.0 * radius) ** 2`` as Python computes it (the blob's cut, m2).
    stretch, th : float
        The two draws of :func:`make_spill`'s generator (aspect, direction).
    land : (n, n) uint8
        Nonzero = land (read inside the box only).
    i0, i1 : int
        The box.
    w : (n * n,) float64
        Work array (the field's weights, row-major; zero outside the box on return).
    stack : (64, 5) float64
        Work array of :func:`pairwise_sum`.
    out : (i1 - i0, i1 - i0) float64
        The box of the field, kg m-2, written.

    Returns
    -------
    float
        The weights' total; not > 0 where no water cell lies near the centre (``out`` is then
        not written; :func:`make_spill` raises).
    """
    sigma = 0.5 * radius
    a = sigma * math.sqrt(stretch)
    b = sigma / math.sqrt(stretch)
    ct = math.cos(th)
    st = math.sin(th)
    for k in range(n * n):
        w[k] = 0.0
    for j in range(i0, i1):
        Z = (z0 + h * j) - cz
        for i in range(i0, i1):
            X = (x0 + h * i) - cx
            p = ct * X + st * Z
            q = -st * X + ct * Z
            pa = p / a
            qb = q / b
            v = math.exp(-0.5 * (pa * pa + qb * qb))
            if X * X + Z * Z > cut or land[j, i] != 0:
                v = 0.0
            w[j * n + i] = v
    total = 0.0 + pairwise_sum(w, 0, n * n, stack)
    if not total > 0.0:
        return total
    scale = mass / (total * h * h)
    for j in range(i0, i1):
        for i in range(i0, i1):
            out[j - i0, i - i0] = w[j * n + i] * scale
    return total
