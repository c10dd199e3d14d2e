"""Control trajectories from a few keyframes (paper III-B, eq. 12).

``u = (u_prep, u_cycle, u_cycle)`` (the shape is a :class:`~trajopt.optim.gait.GaitSpec`): each motor's
cycle is a periodic zero-tangent cubic Hermite spline through ``n_keyframes`` equally spaced
keyframes (or, with ``GaitSpec(interpolation="linear")``, straight lines between them:
:func:`linear_cycle_basis`); the preparatory phase eases from the rest contraction ``u_rest`` (``robot.u_rest``:
where the environments' rollouts start) into the cycle's first value. With zero tangents the
spline (and the straight lines) never leave the range of its keyframes, and the prep blends two in-range values, so
bounds on the keyframes z are bounds on u.

Tendon pairs share a motor (that is what a motor is in :class:`soft_envs.envs.Robot`).
Bilateral symmetry: a motor's mirror motor plays the same signal shifted by half a period,
which for an even number of keyframes is a rotation of its keyframes by ``n_keyframes / 2``;
only one motor of each mirror pair then carries parameters.

Everything here is affine in z: ``u = u_offset + dudz . z`` (:meth:`GaitParameterization.offset`
is zero except in the prep phase of a motor whose range excludes 0), and ``dudz`` is exact and
constant.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .gait import GaitSpec

__all__ = ["GaitParameterization", "hermite_cycle_basis", "linear_cycle_basis", "cycle_basis", "prep_ease"]


def _smoothstep(s: np.ndarray) -> np.ndarray:
    """Zero-tangent cubic Hermite blend 3 s^2 - 2 s^3 on [0, 1]."""
    return s * s * (3.0 - 2.0 * s)


def _periodic_basis(n_steps: int, n_keyframes: int, blend) -> np.ndarray:
    """(n_steps, n_keyframes) matrix B: step i sits at spline time ``t = i * n_keyframes / n_steps``;
    between keyframes j and j+1 (periodic) its value is ``z_j + (z_{j+1} - z_j) blend(t - j)``."""
    if n_keyframes < 1 or n_steps < n_keyframes:
        raise ValueError(f"need 1 <= n_keyframes <= n_steps, got {n_keyframes}, {n_steps}")
    t = np.arange(n_steps) * n_keyframes / n_steps
    j = np.floor(t).astype(int)
    s = blend(t - j)
    B = np.zeros((n_steps, n_keyframes))
    B[np.arange(n_steps), j % n_keyframes] += 1.0 - s
    B[np.arange(n_steps), (j + 1) % n_keyframes] += s
    return B


def hermite_cycle_basis(n_steps: int, n_keyframes: int) -> np.ndarray:
    """(n_steps, n_keyframes) matrix B with ``u_cycle = B @ keyframes``: step i sits at spline
    time ``i * n_keyframes / n_steps``; between keyframes j and j+1 (periodic) the value is
    ``z_j + (z_{j+1} - z_j) (3 s^2 - 2 s^3)`` (paper eq. 12, zero tangents)."""
    return _periodic_basis(n_steps, n_keyframes, _smoothstep)


def linear_cycle_basis(n_steps: int, n_keyframes: int) -> np.ndarray:
    """(n_steps, n_keyframes) matrix B with ``u_cycle = B @ keyframes`` for straight lines between
    the keyframes (periodic): ``z_j + (z_{j+1} - z_j) s`` at spline time ``j + s``. The slope
    between two keyframes is constant, so a motor can use its whole speed limit (the
    zero-tangent spline's slope peaks at 1.5 times its mean)."""
    return _periodic_basis(n_steps, n_keyframes, lambda s: s)


def cycle_basis(gait: GaitSpec) -> np.ndarray:
    """(n_cycle, n_keyframes) basis of ``gait``'s cycle, as its ``interpolation`` says
    (:data:`trajopt.optim.gait.INTERPOLATIONS`)."""
    make = linear_cycle_basis if gait.interpolation == "linear" else hermite_cycle_basis
    return make(gait.n_cycle, gait.n_keyframes)


def prep_ease(n_prep: int) -> np.ndarray:
    """(n_prep,) weights easing from 0 to 1 (smoothstep), ending exactly at 1."""
    return _smoothstep(np.arange(1, n_prep + 1) / n_prep) if n_prep > 0 else np.zeros(0)


@dataclass
class GaitParameterization:
    """Maps parameters z to controls u (K, n_motors) for prep + ``n_cycles`` cycles.

    Parameters
    ----------
    u_bounds : (n_motors, 2) lower/upper contraction of each motor [m].
    mirror_map : (n_motors,) index of each motor's mirror motor (itself if none).
    u_rest : (n_motors,) contraction at rest [m], where the prep phase starts (``robot.u_rest``).
    gait : the phase lengths, cycles, keyframes and symmetry (default: the paper's).

    :meth:`for_robot` takes the first three from a robot.
    """

    u_bounds: np.ndarray
    mirror_map: np.ndarray
    u_rest: np.ndarray
    gait: GaitSpec = GaitSpec()
    free_motors: np.ndarray = field(init=False)

    @classmethod
    def for_robot(cls, robot, gait: GaitSpec = GaitSpec()) -> "GaitParameterization":
        """The parameterisation of ``robot``'s motors (bounds, mirror pairs, rest contraction)."""
        return cls(robot.u_bounds, robot.mirror_map, robot.u_rest, gait)

    def __post_init__(self):
        self.u_bounds = np.asarray(self.u_bounds, dtype=np.float64).reshape(-1, 2)
        self.mirror_map = np.asarray(self.mirror_map, dtype=np.int64)
        self.u_rest = np.asarray(self.u_rest, dtype=np.float64)
        n = len(self.u_bounds)
        if self.mirror_map.shape != (n,):
            raise ValueError(f"mirror_map must have {n} entries")
        if self.u_rest.shape != (n,):
            raise ValueError(f"u_rest must have {n} entries, got shape {self.u_rest.shape}")
        if not isinstance(self.gait, GaitSpec):
            raise TypeError(f"gait must be a GaitSpec, got {type(self.gait).__name__}")
        has_pairs = np.any(self.mirror_map != np.arange(n))
        if self.symmetry and has_pairs and self.n_keyframes % 2:
            raise ValueError("bilateral symmetry needs an even number of keyframes "
                             f"(half-period shift), got {self.n_keyframes}")
        if self.symmetry:
            self.free_motors = np.array([m for m in range(n) if self.mirror_map[m] >= m], dtype=np.int64)
        else:
            self.free_motors = np.arange(n, dtype=np.int64)
        # keyframe matrix: keyframes (n_motors, K) = P @ z, built as a dense (n*K, nz) map
        K = self.n_keyframes
        P = np.zeros((n, K, len(self.free_motors), K))
        for p, m in enumerate(self.free_motors):
            P[m, :, p, :] = np.eye(K)
            mm = self.mirror_map[m]
            if self.symmetry and mm != m:
                P[mm, :, p, :] = np.roll(np.eye(K), K // 2, axis=1)   # z_{m'}[j] = z_m[j + K/2]
        self._P = P.reshape(n * K, -1)
        # a free motor's keyframes also drive its mirror motor: bound them by both motors' ranges
        zb = self.u_bounds[self.free_motors].copy()
        if self.symmetry:
            mm = self.mirror_map[self.free_motors]
            zb[:, 0] = np.maximum(zb[:, 0], self.u_bounds[mm, 0])
            zb[:, 1] = np.minimum(zb[:, 1], self.u_bounds[mm, 1])
            if (zb[:, 0] > zb[:, 1]).any():
                raise ValueError("mirror motors have disjoint contraction ranges")
        self._zbounds = zb

    # ------------------------------------------------------------------ sizes
    @property
    def n_prep(self) -> int:
        return self.gait.n_prep

    @property
    def n_cycle(self) -> int:
        return self.gait.n_cycle

    @property
    def n_keyframes(self) -> int:
        return self.gait.n_keyframes

    @property
    def symmetry(self) -> bool:
        return self.gait.symmetry

    @property
    def n_motors(self) -> int:
        return len(self.u_bounds)

    @property
    def nz(self) -> int:
        return len(self.free_motors) * self.n_keyframes

    def n_steps(self, n_cycles: int | None = None) -> int:
        """Steps of the prep phase and ``n_cycles`` cycles (default: the gait's)."""
        return self.gait.n_steps(n_cycles)

    # ------------------------------------------------------------------ maps
    def keyframes(self, z: np.ndarray) -> np.ndarray:
        """(n_motors, n_keyframes) keyframes of every motor."""
        z = self._check_z(z)
        return (self._P @ z).reshape(self.n_motors, self.n_keyframes)

    def dudz(self, n_cycles: int | None = None) -> np.ndarray:
        """Exact, constant (K, n_motors, nz) Jacobian of :meth:`controls`."""
        n_cycles = self.gait.n_cycles if n_cycles is None else n_cycles
        B = cycle_basis(self.gait)                                          # (C, Kf)
        ease = prep_ease(self.n_prep)[:, None] * B[0][None, :]             # prep eases to cycle[0]
        steps = np.concatenate([ease] + [B] * n_cycles)                     # (K, Kf)
        P = self._P.reshape(self.n_motors, self.n_keyframes, self.nz)
        return np.einsum("kj,mjz->kmz", steps, P)

    def offset(self, n_cycles: int | None = None) -> np.ndarray:
        """(K, n_motors) part of the controls that does not depend on z: the prep phase's
        ``(1 - ease) u_rest`` (zero for motors whose range contains 0), zero in the cycles."""
        out = np.zeros((self.n_steps(n_cycles), self.n_motors))
        out[: self.n_prep] = (1.0 - prep_ease(self.n_prep))[:, None] * self.u_rest[None, :]
        return out

    def controls(self, z: np.ndarray, n_cycles: int | None = None) -> np.ndarray:
        """(n_prep + n_cycles n_cycle, n_motors) controls ``offset + dudz . z`` for parameters z."""
        return self.offset(n_cycles) + self.dudz(n_cycles) @ self._check_z(z)

    # ------------------------------------------------------------------ bounds and starts
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds on z (= bounds on u in the cycles thanks to the zero tangents; with symmetry,
        the intersection of a motor's and its mirror's ranges). The prep phase blends
        ``u_rest`` and the cycle's first value, both in range, so it respects them too."""
        lo = np.repeat(self._zbounds[:, 0], self.n_keyframes)
        hi = np.repeat(self._zbounds[:, 1], self.n_keyframes)
        return lo, hi

    def keyframes_from(self, keyframes: np.ndarray) -> np.ndarray:
        """Another gait's keyframes (n_motors, k) as this gait's (n_motors, n_keyframes): the same
        when k equals ``n_keyframes``; when ``n_keyframes`` is a multiple of k, the cycle is
        repeated ``n_keyframes / k`` times (that many strides per cycle: the paper's 4-keyframe
        walk warm-starts the 12-keyframe turn as three quicker strides)."""
        kf = np.asarray(keyframes, dtype=np.float64)
        if kf.ndim != 2 or kf.shape[0] != self.n_motors or kf.shape[1] < 1 or self.n_keyframes % kf.shape[1]:
            raise ValueError(f"keyframes of shape {kf.shape} do not fit a gait of ({self.n_motors}, "
                             f"{self.n_keyframes}): need {self.n_motors} motors and a number of keyframes "
                             f"that divides {self.n_keyframes}")
        return np.tile(kf, (1, self.n_keyframes // kf.shape[1]))

    def one_side_reversed(self, keyframes: np.ndarray, side: int) -> np.ndarray:
        """Keyframes (n_motors, n_keyframes) with one side's motors playing their cycle backwards
        in time (``k_j -> k_{-j}``): ``side`` 0 is the first motor of each mirror pair (the
        Puppy's left), 1 the other. A walk with one side stepping backwards turns on the spot
        towards that side (a tank turn): a start for the turn."""
        if side not in (0, 1):
            raise ValueError(f"side must be 0 or 1, got {side!r}")
        kf = np.array(keyframes, dtype=np.float64).reshape(self.n_motors, self.n_keyframes)
        m = np.arange(self.n_motors)
        motors = m[(self.mirror_map > m) if side == 0 else (self.mirror_map < m)]
        kf[motors] = kf[motors][:, (-np.arange(self.n_keyframes)) % self.n_keyframes]
        return kf

    def z_from_keyframes(self, keyframes: np.ndarray) -> np.ndarray:
        """Parameters from full keyframes (n_motors, n_keyframes) (mirror motors are dropped)."""
        kf = np.asarray(keyframes, dtype=np.float64).reshape(self.n_motors, self.n_keyframes)
        return kf[self.free_motors].ravel()

    def initial_z(self, fraction: float = 0.3, rng: np.random.Generator | None = None,
                  noise: float = 0.0) -> np.ndarray:
        """A start: every keyframe at ``fraction`` of the way from u_min to u_max, plus optional
        uniform noise of ``noise`` times the range."""
        lo, hi = self.bounds()
        z = lo + fraction * (hi - lo)
        if rng is not None and noise > 0:
            z = z + noise * (hi - lo) * rng.uniform(-1, 1, size=z.shape)
        return np.clip(z, lo, hi)

    def seeds(self, n_random: int = 12, rng: np.random.Generator | None = None) -> list[np.ndarray]:
        """Candidate starting points: the constant mid-range start, the square waves
        ``[1, 1, 0, 0]``-like (half the keyframes at u_max, half at u_min) with every motor's
        pattern rotated in turn, and ``n_random`` random rotations (seeded). Gauss-Newton is
        local; :func:`trajopt.optimize_gait` starts from the best of these."""
        rng = np.random.default_rng(0) if rng is None else rng
        K = self.n_keyframes
        lo, hi = self.u_bounds[:, 0], self.u_bounds[:, 1]
        square = (np.arange(K) < (K + 1) // 2).astype(float)
        nf = len(self.free_motors)
        rots = [np.zeros(nf, dtype=int), np.arange(nf) % K, (-np.arange(nf)) % K]
        rots += [rng.integers(0, K, size=nf) for _ in range(n_random)]
        out = [self.initial_z(0.5)]
        seen = set()
        for rot in rots:
            key = tuple(int(r) for r in rot)
            if key in seen:
                continue
            seen.add(key)
            kf = np.zeros((self.n_motors, K))
            for p, m in enumerate(self.free_motors):
                kf[m] = lo[m] + (hi[m] - lo[m]) * np.roll(square, rot[p])
            out.append(np.clip(self.z_from_keyframes(kf), *self.bounds()))
        return out

    def _check_z(self, z) -> np.ndarray:
        z = np.asarray(z, dtype=np.float64)
        if z.shape != (self.nz,):
            raise ValueError(f"z must have shape ({self.nz},), got {z.shape}")
        if not np.isfinite(z).all():
            raise ValueError("z contains NaN or inf")
        return z
