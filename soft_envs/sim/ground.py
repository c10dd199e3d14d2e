r"""The ground's surface as a height field ``y = h(x, z)`` (y is up): :class:`HeightField`.

.. math::
    h(x, z) = a_x x + a_z z + \sum_{i,j} c_{\bar i \bar j}\,
              \beta\big(\tfrac{x - x_0}{\Delta x} - i\big)\,\beta\big(\tfrac{z - z_0}{\Delta z} - j\big)

a plane of slope ``(a_x, a_z)`` [m/m] plus a relief: the uniform *quintic* B-spline ``beta``
(centred, support ``(-3, 3)``) over the grid ``x_0 + i dx``, ``z_0 + j dz`` whose coefficients
``c`` interpolate the ``heights`` [m] at the grid's nodes (computed once by
``scipy.linalg.solve_banded``). Outside the grid the coefficient indices are clamped,
``\bar i = clip(i, 0, n_x - 1)``: the relief continues as smoothly as inside and, three cells
beyond an edge, becomes constant along the outward direction (the edge's profile extended).

The relief is C4, so ``h``, its gradient, Hessian and third derivatives (:func:`height_derivatives`)
are continuous: the contact gap ``(y - h) / sqrt(1 + |grad h|^2)`` uses ``grad h`` and its
Hessian uses third derivatives of ``h`` (:mod:`soft_envs.sim.contact.surface`). A cubic
spline (C2) would leave that Hessian jumping across the grid lines.

Constructors (all lengths [m]): :meth:`HeightField.flat`, :meth:`~HeightField.incline`,
:meth:`~HeightField.step`, :meth:`~HeightField.trench`, :meth:`~HeightField.rough` and
:meth:`~HeightField.from_function`; :func:`ground_from_table` reads ``robot.toml``'s ``[ground]``
table. No field (``Robot.ground = None``) is the plane ``y = 0`` of the original contact laws.
"""
from __future__ import annotations

import inspect
import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numba import njit

__all__ = ["HeightField", "height_derivatives", "ground_from_table", "GROUND_TYPES"]

#: the quintic B-spline at the integers -2..2 (interpolation weights of a grid node)
_NODE_WEIGHTS = np.array([1.0, 26.0, 66.0, 26.0, 1.0]) / 120.0


#: the six pieces of the quintic B-spline on a cell, ``beta_a(t) = sum_p _PIECES[a, p] t^p``
#: (``t`` in [0, 1), piece a weights coefficient ``i0 - 2 + a``)
_PIECES = np.array([[1, -5, 10, -10, 5, -1], [26, -50, 20, 20, -20, 5], [66, 0, -60, 0, 30, -10],
                    [26, 50, 20, -20, -20, 10], [1, 5, 10, 10, 5, -5], [0, 0, 0, 0, 0, 1]], dtype=np.float64) / 120.0
#: their derivatives 0..3: ``_PIECE_DERIVATIVES[m, a, p]`` multiplies ``t^p``
_PIECE_DERIVATIVES = np.zeros((4, 6, 6))
for _m in range(4):
    for _p in range(_m, 6):
        _PIECE_DERIVATIVES[_m, :, _p - _m] = _PIECES[:, _p] * np.prod(np.arange(_p - _m + 1, _p + 1))


@njit(cache=True, inline="always")
def _basis(t, m):
    """The m-th derivative (m = 0..3) of the six pieces at ``t`` (unit spacing), a 6-tuple."""
    D = _PIECE_DERIVATIVES[m]
    return (((((D[0, 5] * t + D[0, 4]) * t + D[0, 3]) * t + D[0, 2]) * t + D[0, 1]) * t + D[0, 0],
            ((((D[1, 5] * t + D[1, 4]) * t + D[1, 3]) * t + D[1, 2]) * t + D[1, 1]) * t + D[1, 0],
            ((((D[2, 5] * t + D[2, 4]) * t + D[2, 3]) * t + D[2, 2]) * t + D[2, 1]) * t + D[2, 0],
            ((((D[3, 5] * t + D[3, 4]) * t + D[3, 3]) * t + D[3, 2]) * t + D[3, 1]) * t + D[3, 0],
            ((((D[4, 5] * t + D[4, 4]) * t + D[4, 3]) * t + D[4, 2]) * t + D[4, 1]) * t + D[4, 0],
            ((((D[5, 5] * t + D[5, 4]) * t + D[5, 3]) * t + D[5, 2]) * t + D[5, 1]) * t + D[5, 0])


@njit(cache=True)
def height_derivatives(coef, x0, z0, dx, dz, ax, az, x, z):
    """``(h, h_x, h_z, h_xx, h_xz, h_zz, h_xxx, h_xxz, h_xzz, h_zzz)`` of the field (module
    docstring) at ``(x, z)`` [m]: the spline coefficients ``coef (n_x, n_z)``, grid origin
    ``(x0, z0)``, spacing ``(dx, dz)`` and plane slope ``(ax, az)``."""
    nx, nz = coef.shape
    if nx == 1 and nz == 1:              # a plane
        return coef[0, 0] + ax * x + az * z, ax, az, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    xi = (x - x0) / dx
    zj = (z - z0) / dz
    i0 = int(math.floor(xi))
    j0 = int(math.floor(zj))
    tx = xi - i0
    tz = zj - j0
    bx0, bx1, bx2, bx3 = _basis(tx, 0), _basis(tx, 1), _basis(tx, 2), _basis(tx, 3)
    bz0, bz1, bz2, bz3 = _basis(tz, 0), _basis(tz, 1), _basis(tz, 2), _basis(tz, 3)
    h = hx = hz = hxx = hxz = hzz = hxxx = hxxz = hxzz = hzzz = 0.0
    for b in range(6):
        j = min(max(j0 - 2 + b, 0), nz - 1)
        # sums over the x pieces of column b, then weighted by the z pieces
        s0 = s1 = s2 = s3 = 0.0
        for a in range(6):
            c = coef[min(max(i0 - 2 + a, 0), nx - 1), j]
            s0 += c * bx0[a]
            s1 += c * bx1[a]
            s2 += c * bx2[a]
            s3 += c * bx3[a]
        h += s0 * bz0[b]
        hx += s1 * bz0[b]
        hz += s0 * bz1[b]
        hxx += s2 * bz0[b]
        hxz += s1 * bz1[b]
        hzz += s0 * bz2[b]
        hxxx += s3 * bz0[b]
        hxxz += s2 * bz1[b]
        hxzz += s1 * bz2[b]
        hzzz += s0 * bz3[b]
    sx, sz = 1.0 / dx, 1.0 / dz
    return (h + ax * x + az * z, hx * sx + ax, hz * sz + az, hxx * sx * sx, hxz * sx * sz, hzz * sz * sz,
            hxxx * sx * sx * sx, hxxz * sx * sx * sz, hxzz * sx * sz * sz, hzzz * sz * sz * sz)


def _interpolation_solve(values: np.ndarray) -> np.ndarray:
    """Coefficients ``c`` along axis 0 with ``sum_k c_clip(k) beta(i - k) = values_i``."""
    n = values.shape[0]
    ab = np.zeros((5, n))                       # banded storage: ab[2 + i - j, j] = A[i, j]
    for i in range(n):
        for off, w in zip(range(-2, 3), _NODE_WEIGHTS):
            j = min(max(i + off, 0), n - 1)
            ab[2 + i - j, j] += w
    return scipy.linalg.solve_banded((2, 2), ab, values)


def _check(name: str, value, positive: bool = False, minimum: float | None = None) -> None:
    """ValueError ``ground.<name> must be ..., got <value>`` unless ``value`` is a finite number
    (``positive``: > 0; ``minimum``: >= it)."""
    ok = isinstance(value, (int, float, np.floating, np.integer)) and not isinstance(value, bool) \
        and math.isfinite(value)
    if ok and positive:
        ok = value > 0
    if ok and minimum is not None:
        ok = value >= minimum
    if not ok:
        need = "positive" if positive else (f">= {minimum:g}" if minimum is not None else "finite")
        raise ValueError(f"ground.{name} must be a {need} number, got {value!r}")


def _smoothstep(u):
    """The C2 quintic smoothstep ``6u^5 - 15u^4 + 10u^3`` on [0, 1] (0 below, 1 above)."""
    u = np.clip(u, 0.0, 1.0)
    return u * u * u * (u * (6.0 * u - 15.0) + 10.0)


@dataclass(frozen=True, eq=False)
class HeightField:
    """The ground ``y = h(x, z)`` (module docstring): ``heights (n_x, n_z)`` [m] at the grid nodes
    ``(origin[0] + i spacing[0], origin[1] + j spacing[1])`` [m], on the plane of slope ``slope``
    ``(dh/dx, dh/dz)`` [m/m]; ``description`` says what it is (messages, examples)."""

    heights: np.ndarray
    origin: tuple[float, float] = (0.0, 0.0)
    spacing: tuple[float, float] = (1.0, 1.0)
    slope: tuple[float, float] = (0.0, 0.0)
    description: str = "height field"

    def __post_init__(self):
        h = np.array(self.heights, dtype=np.float64)
        if h.ndim != 2 or h.size == 0 or not np.isfinite(h).all():
            raise ValueError(f"ground.heights must be a non-empty 2-D table of finite heights [m], got shape {h.shape}")
        for name, n, positive in (("origin", 2, False), ("spacing", 2, True), ("slope", 2, False)):
            v = tuple(float(q) for q in np.asarray(getattr(self, name), dtype=np.float64).ravel())
            if len(v) != n or not all(math.isfinite(q) and (q > 0 or not positive) for q in v):
                raise ValueError(f"ground.{name} must be {n} finite{' positive' if positive else ''} numbers "
                                 f"[m], got {getattr(self, name)!r}")
            object.__setattr__(self, name, v)
        h.setflags(write=False)
        object.__setattr__(self, "heights", h)
        coef = _interpolation_solve(_interpolation_solve(h).T).T
        coef = np.ascontiguousarray(coef if h.any() else np.zeros_like(h))     # flat: exactly 0
        coef.setflags(write=False)
        object.__setattr__(self, "coefficients", coef)

    @property
    def args(self) -> tuple:
        """``(coef, x0, z0, dx, dz, ax, az, top)``: the field as the contact kernels take it
        (the first seven are :func:`height_derivatives`'s); ``top = max(coef)`` bounds the relief
        (``h <= ax x + az z + top``: B-spline weights are >= 0 and sum to 1)."""
        return (self.coefficients, self.origin[0], self.origin[1], self.spacing[0], self.spacing[1],
                self.slope[0], self.slope[1], float(self.coefficients.max()))

    @property
    def is_flat(self) -> bool:
        """Whether the field is a horizontal plane (no slope, all heights equal)."""
        return self.slope == (0.0, 0.0) and bool(np.all(self.heights == self.heights.flat[0]))

    def derivatives(self, x: float, z: float) -> tuple:
        """``(h, h_x, h_z, h_xx, h_xz, h_zz, h_xxx, h_xxz, h_xzz, h_zzz)`` at ``(x, z)`` [m]."""
        return height_derivatives(*self.args[:7], float(x), float(z))

    def height(self, x, z) -> np.ndarray:
        """``h`` [m] at the points ``(x, z)`` (arrays of one shape)."""
        x, z = np.broadcast_arrays(np.asarray(x, dtype=np.float64), np.asarray(z, dtype=np.float64))
        return np.array([self.derivatives(a, b)[0] for a, b in zip(x.ravel(), z.ravel())]).reshape(x.shape)

    # ------------------------------------------------------------------ constructors
    @classmethod
    def flat(cls, height: float = 0.0) -> "HeightField":
        """The plane ``y = height`` [m]."""
        return cls(np.full((1, 1), float(height)), description=f"flat ground at {height:g} m")

    @classmethod
    def incline(cls, angle_deg: float, uphill: tuple[float, float] = (1.0, 0.0)) -> "HeightField":
        """The plane through the origin rising at ``angle_deg`` along the horizontal direction
        ``uphill`` (x, z): ``h = tan(angle) (e . (x, z))``, ``e = uphill / |uphill|`` (the ground
        that :func:`~soft_envs.sim.gravity.incline_gravity` with the same arguments imitates)."""
        e = np.asarray(uphill, dtype=np.float64)
        if e.shape != (2,) or not np.linalg.norm(e) > 0:
            raise ValueError(f"ground.uphill must be a non-zero (x, z) direction, got {uphill!r}")
        _check("angle_deg", angle_deg)
        if not abs(angle_deg) < 80.0:
            raise ValueError(f"ground.angle_deg must be within (-80, 80) degrees, got {angle_deg!r}")
        t = math.tan(math.radians(angle_deg)) * e / np.linalg.norm(e)
        return cls(np.zeros((1, 1)), slope=(t[0], t[1]), description=f"{angle_deg:g} degree slope")

    @classmethod
    def from_function(cls, f, x_range: tuple[float, float], z_range: tuple[float, float], spacing: float,
                      description: str = "height field") -> "HeightField":
        """``f(x, z) -> heights`` [m] (vectorised) sampled every ``spacing`` [m] over ``x_range`` x
        ``z_range`` [m] (a range of equal ends: one node, the field constant along that axis)."""
        _check("spacing", spacing, positive=True)
        axes = [lo + spacing * np.arange(int(round((hi - lo) / spacing)) + 1) for lo, hi in (x_range, z_range)]
        X, Z = np.meshgrid(*axes, indexing="ij")
        return cls(f(X, Z), origin=(x_range[0], z_range[0]), spacing=(spacing, spacing), description=description)

    @classmethod
    def step(cls, height: float, position: float, width: float = 0.01, spacing: float | None = None) -> "HeightField":
        """A step up by ``height`` [m] (negative: down) along +x at ``x = position`` [m], smoothed
        over ``width`` [m]: ``h = height S((x - position) / width + 1/2)`` with the C2 smoothstep
        ``S(u) = 6u^5 - 15u^4 + 10u^3`` on [0, 1]; constant along z. Sampled every ``spacing``
        (default ``width / 8``)."""
        _check("height", height)
        _check("position", position)
        _check("width", width, positive=True)
        sp = width / 8.0 if spacing is None else float(spacing)
        return cls.from_function(lambda x, z: height * _smoothstep((x - position) / width + 0.5),
                                 (position - 4.0 * width, position + 4.0 * width), (0.0, 0.0), sp,
                                 f"step of {height:g} m at x = {position:g} m")

    @classmethod
    def trench(cls, depth: float, start: float, length: float, width: float = 0.01,
               spacing: float | None = None) -> "HeightField":
        """A trench (gap) of ``depth`` [m] across the x axis from ``x = start`` to ``start +
        length`` [m], its edges smoothed over ``width`` [m] like :meth:`step`:
        ``h = -depth S((x - start) / width + 1/2) (1 - S((x - start - length) / width + 1/2))``."""
        _check("depth", depth, minimum=0.0)
        _check("start", start)
        _check("length", length, positive=True)
        _check("width", width, positive=True)
        sp = width / 8.0 if spacing is None else float(spacing)

        def f(x, z):
            return -depth * _smoothstep((x - start) / width + 0.5) * (1.0 - _smoothstep((x - start - length) / width
                                                                                        + 0.5))
        return cls.from_function(f, (start - 4.0 * width, start + length + 4.0 * width), (0.0, 0.0), sp,
                                 f"trench {depth:g} m deep, {length:g} m long at x = {start:g} m")

    @classmethod
    def rough(cls, amplitude: float, wavelength: float, seed: int = 0,
              x_range: tuple[float, float] = (-0.5, 1.5), z_range: tuple[float, float] = (-0.5, 0.5),
              waves: int = 16) -> "HeightField":
        """Random rough ground: ``h = amplitude sqrt(2 / M) sum_m cos(k_m . (x, z) + phi_m)``, M =
        ``waves`` plane waves of wavelength ``wavelength`` [m] (``|k_m| = 2 pi / wavelength``) in
        directions and with phases drawn from ``numpy.random.default_rng(seed)``: its RMS height is
        ``amplitude`` [m]. Sampled every ``wavelength / 8`` over ``x_range`` x ``z_range`` [m]."""
        _check("amplitude", amplitude, minimum=0.0)
        _check("wavelength", wavelength, positive=True)
        if int(waves) != waves or waves < 1:
            raise ValueError(f"ground.waves must be a positive integer, got {waves!r}")
        rng = np.random.default_rng(seed)
        theta = rng.uniform(0.0, 2.0 * np.pi, waves)
        phase = rng.uniform(0.0, 2.0 * np.pi, waves)
        k = 2.0 * np.pi / wavelength

        def f(x, z):
            arg = k * (np.cos(theta) * x[..., None] + np.sin(theta) * z[..., None]) + phase
            return amplitude * math.sqrt(2.0 / waves) * np.cos(arg).sum(axis=-1)
        return cls.from_function(f, x_range, z_range, wavelength / 8.0,
                                 f"rough ground, RMS {amplitude:g} m, wavelength {wavelength:g} m, seed {seed}")


#: ``[ground] type`` -> (constructor, its keys). ``grid``: ``heights`` (rows along x, columns
#: along z) [m], ``origin`` and ``spacing`` (x, z) [m], ``slope`` (dh/dx, dh/dz).
GROUND_TYPES = {
    "flat": (HeightField.flat, ("height",)),
    "incline": (HeightField.incline, ("angle_deg", "uphill")),
    "step": (HeightField.step, ("height", "position", "width", "spacing")),
    "trench": (HeightField.trench, ("depth", "start", "length", "width", "spacing")),
    "rough": (HeightField.rough, ("amplitude", "wavelength", "seed", "x_range", "z_range", "waves")),
    "grid": (HeightField, ("heights", "origin", "spacing", "slope")),
}
_PAIRS = ("uphill", "x_range", "z_range", "origin", "slope")


def ground_from_table(table, src: str) -> HeightField:
    """The :class:`HeightField` of ``robot.toml``'s ``[ground]`` table: ``type`` (a key of
    :data:`GROUND_TYPES`) and that constructor's keyword arguments, e.g.::

        [ground]
        type = "rough"          # flat, incline, step, trench, rough or grid
        amplitude = 0.002       # [m] RMS height
        wavelength = 0.05       # [m]
        seed = 1

    Every bad value is a ValueError naming the file ``src`` and the field."""
    if not isinstance(table, dict):
        raise ValueError(f"{src}: [ground] must be a table")
    kind = table.get("type")
    if kind not in GROUND_TYPES:
        raise ValueError(f"{src}: [ground].type must be one of {', '.join(map(repr, GROUND_TYPES))}, got {kind!r}")
    make, keys = GROUND_TYPES[kind]
    kwargs = {}
    for key, value in table.items():
        if key == "type":
            continue
        if key not in keys:
            raise ValueError(f"{src}: unknown key [ground].{key} for type {kind!r} (allowed: {', '.join(keys)})")
        if key == "seed":
            ok = isinstance(value, int) and not isinstance(value, bool) and value >= 0
        elif key == "heights":
            ok = (isinstance(value, list) and value and all(isinstance(r, list) and len(r) == len(value[0]) and r
                                                             and all(_is_number(q) for q in r) for r in value))
        elif key in _PAIRS or (key == "spacing" and kind == "grid"):
            ok = isinstance(value, list) and len(value) == 2 and all(_is_number(q) for q in value)
        else:
            ok = _is_number(value)
        if not ok:
            need = {"seed": "an integer >= 0", "heights": "a non-empty list of equally long lists of numbers"}.get(
                key, "a list of 2 numbers" if key in _PAIRS or (key == "spacing" and kind == "grid") else "a number")
            raise ValueError(f"{src}: [ground].{key} must be {need}, got {value!r}")
        kwargs[key] = tuple(value) if key in _PAIRS else value
    required = [p.name for p in inspect.signature(make).parameters.values()
                if p.default is inspect.Parameter.empty and p.name in keys]
    for key in required:
        if key not in kwargs:
            raise ValueError(f"{src}: [ground].{key} is missing (type {kind!r})")
    try:
        return make(**kwargs)
    except ValueError as exc:
        raise ValueError(f"{src}: [{str(exc).replace('ground.', 'ground].', 1)}" if str(exc).startswith("ground.")
                         else f"{src}: [ground] {exc}") from None


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
