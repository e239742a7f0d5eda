"""Wind: drag and lift on every triangle from the air's velocity relative to it.

The force on a triangle of area A and unit normal n, with u the air's
velocity relative to the triangle (its corners' mean velocity over the
substep) and u_n = |u·n|:

- drag ``½ ρ C_d A u_n² n̂`` along the normal, turned to face the air;
- lift ``½ ρ C_l A u_n |u_t| t̂``, with u_t the part of u across the
  triangle and t̂ the direction, in the plane of u and n, square to u.

Each corner takes a third. ρ is AIR_DENSITY in the simulation's own mass
unit: CS184's ``density`` of 150 is read as grams per square metre (a
typical cotton), so the mass unit is the gram. Gusts (``turbulence``) are
the same over the whole scene: the air's velocity plus ``turbulence`` x its
speed times a seeded sum of slow sines along and across it.

The control's ``wind`` row (float64): velocity (3), turbulence, drag, lift,
ρ, the frame's start time, the substep, the number of gust terms G, then G
terms of (angular frequency, phase, direction x amplitude (3)).
"""

from __future__ import annotations

import functools

import numpy as np
from numba import njit, types
from numba.extending import overload

from .shared import KERNEL_OPTIONS, divided_by_length, over_length
from .simd import has_compress

_inverse_length = over_length if has_compress() else divided_by_length
"""a triangle normal's 1/|n| (``_inverse_length(1.0, |n|²)``): the kernels'
estimate with AVX-512, else the divide on every core. The wind's loop
divides and takes a square root besides, so without AVX-512 the divide unit
is busy anyway and the estimate's multiplies cost more than they spare; with
AVX-512 the estimate was the faster (docs/performance.md, 'The estimate
on Intel cores without AVX-512')"""

AIR_DENSITY = 1200.0
"""[g/m³]: 1.2 kg/m³ in the simulation's mass unit (see the module)"""

GUSTS = 6
"""gust terms: two along the wind and two across it each way"""

HEAD = 10
"""the wind row's columns before its gust terms"""


def gust_terms(seed: int) -> np.ndarray:
    """(GUSTS, 2) seeded angular frequencies [rad/s] (periods of 0.5-4 s) and phases"""
    rng = np.random.default_rng(seed)
    return np.stack([2 * np.pi / rng.uniform(0.5, 4.0, GUSTS), rng.uniform(0, 2 * np.pi, GUSTS)], axis=1)


def pack_wind(wind, t0: float = 0.0, dt: float = 0.0) -> np.ndarray | None:
    """The wind row from an object with velocity, turbulence, drag, lift and seed,
    for a frame from ``t0`` in substeps of ``dt`` [s]; None for no wind, so that
    :func:`blow` is not compiled."""
    if wind is None:
        return None
    row = _still_row(tuple(map(float, wind.velocity)), float(wind.turbulence), float(wind.drag), float(wind.lift),
                     int(wind.seed)).copy()
    row[7], row[8] = t0, dt
    return row


@functools.lru_cache(maxsize=64)
def _still_row(velocity: tuple, turbulence: float, drag: float, lift: float, seed: int) -> np.ndarray:
    """the wind row less the frame's time, made once per setting (a frame's control is
    made anew every frame)"""
    v = np.asarray(velocity, dtype=np.float64)
    speed = float(np.linalg.norm(v))
    along = v / speed if speed > 0 else np.array([1.0, 0.0, 0.0])
    side = np.cross(along, [0.0, 1.0, 0.0] if abs(along[1]) < 0.9 else [1.0, 0.0, 0.0])
    side /= np.linalg.norm(side)
    up = np.cross(side, along)
    directions = np.array([along, along, side, side, up, up]) * np.array([[0.5], [0.5], [0.25], [0.25], [0.25], [0.25]])
    terms = np.concatenate([gust_terms(seed), directions], axis=1)
    head = [*v, turbulence, drag, lift, AIR_DENSITY, 0.0, 0.0, GUSTS]
    row = np.concatenate([np.array(head, dtype=np.float64), terms.ravel()])
    row.setflags(write=False)
    return row


@njit(cache=True, inline="always")
def _air(wind, t):
    """the air's velocity at time t [s] (the wind plus its gusts) [m/s]"""
    ux, uy, uz = wind[0], wind[1], wind[2]
    gust = wind[3] * np.sqrt(ux * ux + uy * uy + uz * uz)
    if gust > 0.0:
        for g in range(int(wind[9])):
            c = HEAD + 5 * g
            f = gust * np.sin(wind[c] * t + wind[c + 1])
            ux += f * wind[c + 2]
            uy += f * wind[c + 3]
            uz += f * wind[c + 4]
    return ux, uy, uz


@njit(**KERNEL_OPTIONS, inline="always")
def _corner_force(e1, e2, u, drag, lift, scale):
    """The force [g m/s²] on each corner of the triangle with edges e1, e2 (tuples
    (x, y, z)) from its first corner [m], with u [m/s] the air's velocity relative to it and
    ``scale`` ½ρ/3; zero for a triangle of no area (or not finite). The forces
    of :func:`blow`, written without branches, so that :func:`blow_grid`'s
    loop vectorises (see the module's docstring for the physics)."""
    (e1x, e1y, e1z), (e2x, e2y, e2z), (ux, uy, uz) = e1, e2, u
    nx, ny, nz = e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x
    n2 = nx * nx + ny * ny + nz * nz
    ok = n2 > 0.0
    inv_n = _inverse_length(1.0, n2)
    area = 0.5 * n2 * inv_n
    nx, ny, nz = nx * inv_n, ny * inv_n, nz * inv_n
    un = ux * nx + uy * ny + uz * nz
    # the normal turned to face the air
    sign = -1.0 if un < 0.0 else 1.0
    nx, ny, nz, un = sign * nx, sign * ny, sign * nz, sign * un
    d = drag * un * un
    # lift: across u, in the plane of u and n: n less its part along u
    u2 = ux * ux + uy * uy + uz * uz
    # (each division's argument is guarded, not only its result: the selects
    # then never meet an infinity, which fastmath assumes away)
    along = un / (u2 if u2 > 0.0 else 1.0) if u2 > 0.0 else 0.0
    px, py, pz = nx - along * ux, ny - along * uy, nz - along * uz
    p2 = px * px + py * py + pz * pz
    tx, ty, tz = ux - un * nx, uy - un * ny, uz - un * nz
    k = lift * un * np.sqrt((tx * tx + ty * ty + tz * tz) / (p2 if p2 > 0.0 else 1.0)) if p2 > 0.0 else 0.0
    a = scale * area
    fx, fy, fz = a * (d * nx + k * px), a * (d * ny + k * py), a * (d * nz + k * pz)
    return (fx if ok else 0.0), (fy if ok else 0.0), (fz if ok else 0.0)


@njit(**KERNEL_OPTIONS)
def blow(P, L, points, inv_mass, dt2, wind, W, s):
    """Move the free points of the (3, N) positions P by the wind's forces over
    substep ``s``: each triangle's velocity is its corners' (P - L) over the
    substep, the forces gather in the (3, N) scratch W, and a point moves by
    ``dt² F / m``, with ``inv_mass`` (N,) the knobs' and ``dt2`` the substep
    squared [s²]. ``wind``: the control's row; None: nothing (numba prunes a
    branch on an argument that is None, not on a field).

    Any triangle list: the general path. The grid path's cloth takes
    :func:`blow_grid`, whose branch-free form of the same forces
    (:func:`_corner_force`) vectorises there; in this loop, whose corners are
    indexed, it does not, and ran slower than these branches (111 against 80
    µs a call on a 50×50 cloth with lift; docs/performance.md, 'Wind as stencils')."""
    if wind is None:
        return
    tris, free = points.triangles, points.free
    dt = wind[8]
    ax, ay, az = _air(wind, wind[7] + (s + 1) * dt)
    half_rho = 0.5 * wind[6]
    drag, lift = wind[4], wind[5]
    inv_dt = 1.0 / dt
    W[:, :] = 0.0
    for t in range(tris.shape[0]):
        a, b, c = tris[t, 0], tris[t, 1], tris[t, 2]
        e1x, e1y, e1z = P[0, b] - P[0, a], P[1, b] - P[1, a], P[2, b] - P[2, a]
        e2x, e2y, e2z = P[0, c] - P[0, a], P[1, c] - P[1, a], P[2, c] - P[2, a]
        nx, ny, nz = e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x
        n2 = nx * nx + ny * ny + nz * nz
        if not n2 > 0.0:
            continue
        inv_n = 1.0 / np.sqrt(n2)
        area = 0.5 * n2 * inv_n
        nx, ny, nz = nx * inv_n, ny * inv_n, nz * inv_n
        third = inv_dt / 3.0
        ux = ax - (P[0, a] - L[0, a] + P[0, b] - L[0, b] + P[0, c] - L[0, c]) * third
        uy = ay - (P[1, a] - L[1, a] + P[1, b] - L[1, b] + P[1, c] - L[1, c]) * third
        uz = az - (P[2, a] - L[2, a] + P[2, b] - L[2, b] + P[2, c] - L[2, c]) * third
        un = ux * nx + uy * ny + uz * nz
        if un < 0.0:
            nx, ny, nz, un = -nx, -ny, -nz, -un
        scale = half_rho * area / 3.0
        fx, fy, fz = drag * un * un * nx, drag * un * un * ny, drag * un * un * nz
        if lift != 0.0:
            # across u, in the plane of u and n: n less its part along u
            u2 = ux * ux + uy * uy + uz * uz
            along = un / u2 if u2 > 0.0 else 0.0
            px, py, pz = nx - along * ux, ny - along * uy, nz - along * uz
            p2 = px * px + py * py + pz * pz
            if p2 > 0.0:
                tx, ty, tz = ux - un * nx, uy - un * ny, uz - un * nz
                k = lift * un * np.sqrt((tx * tx + ty * ty + tz * tz) / p2)
                fx += k * px
                fy += k * py
                fz += k * pz
        fx, fy, fz = fx * scale, fy * scale, fz * scale
        W[0, a] += fx
        W[1, a] += fy
        W[2, a] += fz
        W[0, b] += fx
        W[1, b] += fy
        W[2, b] += fz
        W[0, c] += fx
        W[1, c] += fy
        W[2, c] += fz
    for p in range(P.shape[1]):
        k = free[p] * dt2 * inv_mass[p]
        P[0, p] += k * W[0, p]
        P[1, p] += k * W[1, p]
        P[2, p] += k * W[2, p]


def frame_row(rows, f):
    """The wind's row for frame f of a call from a control's rows (F, R), one a
    frame (see :func:`~.control.stack_frames`), or None where there is no
    wind. In compiled code an overload for each of the two types: a function
    with both branches returned an optional array, which the wind's kernels
    then took as a type of its own."""
    if rows is None:
        return None
    return rows[min(f, rows.shape[0] - 1)]


@overload(frame_row)
def _frame_row(rows, f):
    if isinstance(rows, types.NoneType):
        return lambda rows, f: None
    return lambda rows, f: rows[min(f, rows.shape[0] - 1)]


def wind_buffer(num_points: int, cols: int) -> np.ndarray:
    """Scratch for :func:`blow_grid`: each kind of triangle's corner forces, zero-padded
    in front so that every index the gathering reads stays inside, (2, 3, pad + N)."""
    return np.zeros((2, 3, cols + 2 + num_points))


@njit(**KERNEL_OPTIONS)
def blow_grid(P, L, free, weight, inv_mass, dt2, wind, T, s, cols):
    """:func:`blow` for a grid cloth of ``cols`` columns, as stencils (see
    :mod:`.springs`): the cell whose first corner is point p has the triangles
    (p, p + cols, p + 1) and (p + 1, p + cols, p + cols + 1), as the model lays
    them out, so each kind is one loop over contiguous memory that LLVM
    vectorises, where a loop over a triangle list with indexed corners does
    not. ``weight`` (N,) is 1 where p is a cell's first corner (not in the last
    column; the springs' set 0 validity), and the loop stops before the last
    row. The corner forces go to ``T`` (2, 3, pad + N) (see :func:`wind_buffer`),
    and each point then gathers its six triangles' (three of each kind):
    ``W[q] = T0[q] + T0[q - 1] + T0[q - cols] + T1[q - 1] + T1[q - cols] + T1[q - cols - 1]``.
    Entries outside the cells are never written and stay zero."""
    if wind is None:
        return
    dt = wind[8]
    air = _air(wind, wind[7] + (s + 1) * dt)
    drag, lift, scale, third = wind[4], wind[5], 0.5 * wind[6] / 3.0, 1.0 / (3.0 * dt)
    for kind in range(2):
        # lift 0 (the default) is a loop of its own: with a literal 0 LLVM drops
        # the lift's square root and divisions
        if lift == 0.0:
            _grid_triangles(P, L, weight, T, kind, cols, air, (drag, 0.0, scale, third))
        else:
            _grid_triangles(P, L, weight, T, kind, cols, air, (drag, lift, scale, third))
    _gather_corners(P, free, inv_mass, dt2, T, cols)


@njit(**KERNEL_OPTIONS, inline="always")
def _grid_triangles(P, L, weight, T, kind, cols, air, coefficients):
    """The corner forces of every triangle of one kind into ``T[kind]`` (see
    :func:`blow_grid`); ``air`` the air's velocity (3,) [m/s], ``coefficients``
    (drag, lift, ½ρ/3, 1/(3 dt))."""
    drag, lift, scale, third = coefficients
    ax, ay, az = air
    n = P.shape[1]
    pad = T.shape[2] - n
    cells = max(n - cols - 1, 0)
    oa, ob, oc = (0, cols, 1) if kind == 0 else (1, cols, cols + 1)
    x, y, z, lx, ly, lz = P[0], P[1], P[2], L[0], L[1], L[2]
    xa, ya, za, xb, yb, zb = x[oa:], y[oa:], z[oa:], x[ob:], y[ob:], z[ob:]
    xc, yc, zc = x[oc:], y[oc:], z[oc:]
    la, ma, na = lx[oa:], ly[oa:], lz[oa:]
    lb, mb, nb = lx[ob:], ly[ob:], lz[ob:]
    lc, mc, nc = lx[oc:], ly[oc:], lz[oc:]
    tx, ty, tz = T[kind, 0, pad:], T[kind, 1, pad:], T[kind, 2, pad:]
    for p in range(cells):
        ux = ax - ((xa[p] - la[p]) + (xb[p] - lb[p]) + (xc[p] - lc[p])) * third
        uy = ay - ((ya[p] - ma[p]) + (yb[p] - mb[p]) + (yc[p] - mc[p])) * third
        uz = az - ((za[p] - na[p]) + (zb[p] - nb[p]) + (zc[p] - nc[p])) * third
        fx, fy, fz = _corner_force((xb[p] - xa[p], yb[p] - ya[p], zb[p] - za[p]),
                                   (xc[p] - xa[p], yc[p] - ya[p], zc[p] - za[p]),
                                   (ux, uy, uz), drag, lift, scale)
        w = weight[p]
        tx[p] = w * fx
        ty[p] = w * fy
        tz[p] = w * fz


@njit(**KERNEL_OPTIONS, inline="always")
def _gather_corners(P, free, inv_mass, dt2, T, cols):
    """each point's six triangles' corner forces, and its move by them (see :func:`blow_grid`)"""
    n = P.shape[1]
    pad = T.shape[2] - n
    for c in range(3):
        xq = P[c]
        t0, t0l, t0u = T[0, c, pad:], T[0, c, pad - 1:], T[0, c, pad - cols:]
        t1l, t1u, t1d = T[1, c, pad - 1:], T[1, c, pad - cols:], T[1, c, pad - cols - 1:]
        for q in range(n):
            k = free[q] * dt2 * inv_mass[q]
            xq[q] += k * ((t0[q] + t0l[q] + t0u[q]) + (t1l[q] + t1u[q] + t1d[q]))
