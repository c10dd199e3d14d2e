"""Physical magnitudes against independent expected values (not derivative consistency).

* the tangential friction force of a node that slid a known distance equals the contact
  law's documented formula, for both laws (``FRICTION_LAWS``: the paper's lagged friction and
  the Coulomb law with stick anchors; its anchors against hand values are in
  ``tests/test_coulomb_anchors.py``);
* with contact and friction, energy is dissipated, never created (both laws; what "energy"
  means with the Coulomb law's bristles is in :func:`test_sliding_tumbling_block_never_gains_energy`);
* lumped node masses of a two-tet mesh against hand values, and gravity acting on them;
* a clamped cantilever against Timoshenko beam theory (Poisson ratio 0.3), with a window that
  a 5 % stiffer or softer material fails.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import meshio
import numpy as np
import pytest

from soft_envs.sim import ContactParams, NewtonOptions, Robot, Simulator
from soft_envs.sim.meshgen import voxel_tet_mesh

from .conftest import small_robot

G = 9.81


# ----------------------------------------------------------------------------- contact laws
def documented_normal_force(depth: np.ndarray, contact: ContactParams) -> np.ndarray:
    """``N = Q_n'(depth)`` of the C2 one-sided quadratic (soft_envs.sim.contact, .cables):
    ``k s^2 / (2 eps)`` inside the blend (0 < s < eps), ``k (s - eps / 2)`` beyond, 0 above the
    ground."""
    k, eps = contact.stiffness, contact.blend
    s = np.asarray(depth, dtype=np.float64)
    return np.where(s <= 0, 0.0, np.where(s < eps, 0.5 * k * s**2 / eps, k * (s - 0.5 * eps)))


def paper_friction_force(N: np.ndarray, slide: np.ndarray, contact: ContactParams, dt: float) -> np.ndarray:
    """Paper II-C, lagged friction ``mu_f N_{k-1} |dx_t|^2``: force ``2 mu_f N dx_t`` opposing
    the slide (returned as dE/dx, i.e. along the slide)."""
    return 2.0 * contact.friction * N[:, None] * slide


def coulomb_friction_force(N: np.ndarray, slide: np.ndarray, contact: ContactParams, dt: float) -> np.ndarray:
    """Coulomb law with stick anchors (soft_envs.sim.coulomb), a node ``slide`` (n, 2) from its
    anchor, r = |slide|, rho = r / r_s: the force has magnitude ``mu N (2 rho - rho^2)`` for
    rho < 1 and exactly ``mu N`` beyond, against the slip (returned as dE/dx: along it)."""
    r = np.linalg.norm(slide, axis=1)
    rho = r / contact.slip_distance
    magnitude = contact.friction_coefficient * N * np.where(rho < 1.0, 2.0 * rho - rho**2, 1.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        direction = np.where(r[:, None] > 0, slide / r[:, None], 0.0)
    return magnitude[:, None] * direction


@dataclass(frozen=True)
class FrictionLaw:
    """A ground friction law as the tests see it: the ContactParams fields that select it and
    the tangential force (dE/dx_t, (n, 2) for x and z) on nodes with previous-step normal force
    N that slid ``slide`` (n, 2) metres in one step of ``dt`` (for the Coulomb law: from
    anchors where the nodes were at the previous step, the default history of a step)."""

    name: str
    contact: dict
    force: Callable[[np.ndarray, np.ndarray, ContactParams, float], np.ndarray]


#: one entry per law (the slide distances of the tests, up to 0.28 mm, straddle the 0.15 mm slip
#: distance: both regimes of the Coulomb law are exercised)
FRICTION_LAWS = [
    FrictionLaw("paper_lagged", {"friction": 800.0}, paper_friction_force),
    FrictionLaw("coulomb", {"model": "coulomb", "friction_coefficient": 0.8, "slip_distance": 1.5e-4},
                coulomb_friction_force),
]


def block(contact: dict | None = None) -> Robot:
    """The 6 x 2 x 2 cm foam bar of conftest without cables (so nothing pulls on it)."""
    kw = {} if contact is None else {"contact": ContactParams(**contact)}
    return small_robot(tendons=[], motors=[], **kw)


@pytest.mark.parametrize("law", FRICTION_LAWS, ids=lambda law: law.name)
@pytest.mark.parametrize("depth", [2e-4, 1.5e-3], ids=["in_blend", "beyond_blend"])
def test_friction_force_of_a_sliding_node_matches_the_law(law, depth):
    """The bar pressed ``depth`` into the ground (a rigid translation: no elastic force), each
    bottom node having slid a different known distance since the previous step. The friction
    force (the only force that depends on the previous state, isolated by comparing with a
    previous state high above the ground) equals the law's formula with the normal force N of
    the previous step; N itself is the documented penalty law and is what the ground pushes
    with (measured from the vertical force: weight minus N)."""
    seed = 2024
    robot = block(law.contact)
    sim = Simulator(robot)
    X = np.array(robot.mesh.points)
    x = X - [0.0, depth, 0.0]
    rng = np.random.default_rng(seed)
    slide = rng.uniform(-2e-4, 2e-4, size=(len(X), 2))          # (dx, dz) since the previous step
    x_prev = x.copy()
    x_prev[:, [0, 2]] -= slide
    u = np.zeros(0)
    no_friction = sim.gradient(x, x_prev + [0.0, 1.0, 0.0], u)     # previous state in the air: N_prev = 0
    friction = sim.gradient(x, x_prev, u) - no_friction
    N = documented_normal_force(-x_prev[:, 1], robot.contact)
    bottom = X[:, 1] < 1e-12
    assert bottom.sum() == 8 and np.all(N[bottom] > 0) and np.all(N[~bottom] == 0)
    # the normal force the ground exerts now (y-force = m g - N for a rigidly translated body)
    measured_N = robot.node_masses * G - no_friction[:, 1]
    np.testing.assert_allclose(measured_N, N, rtol=1e-10, atol=1e-12 * N.max(),
                               err_msg=f"normal force vs the penalty law (seed {seed})")
    expected = law.force(N, slide, robot.contact, sim.dt)
    if "slip_distance" in law.contact:                # both regimes of the Coulomb law occur
        rho = np.linalg.norm(slide[bottom], axis=1) / law.contact["slip_distance"]
        assert (rho < 1).any() and (rho > 1).any(), f"seed {seed}: slides / r_s = {rho}"
    scale = np.abs(expected).max()
    assert scale > 0
    np.testing.assert_allclose(friction[:, [0, 2]], expected, rtol=1e-9, atol=1e-12 * scale,
                               err_msg=f"tangential friction force, law {law.name}, seed {seed}")
    np.testing.assert_allclose(friction[:, 1], 0.0, atol=1e-12 * scale)


def test_paper_friction_equals_the_normal_force_after_sliding_one_over_two_mu():
    """The documented reading of mu_f (soft_envs.sim.contact): a node sliding 1 / (2 mu_f)
    metres in one step feels a tangential force equal to its normal force."""
    robot = block({"friction": 1000.0})
    sim = Simulator(robot)
    X = np.array(robot.mesh.points)
    x = X - [0.0, 1e-3, 0.0]
    node = int(np.flatnonzero(X[:, 1] < 1e-12)[0])
    x_prev = x.copy()
    x_prev[node, 0] -= 1.0 / (2.0 * 1000.0)
    u = np.zeros(0)
    no_friction = sim.gradient(x, x_prev + [0.0, 1.0, 0.0], u)
    f_t = (sim.gradient(x, x_prev, u) - no_friction)[node, 0]
    N = robot.node_masses[node] * G - no_friction[node, 1]
    assert N > 0 and f_t == pytest.approx(N, rel=1e-9)


def _kinetic(sim: Simulator, x: np.ndarray, x_prev: np.ndarray) -> float:
    """Kinetic energy with the velocity over the last step."""
    v = (x - x_prev) / sim.dt
    return 0.5 * float(np.sum(sim.robot.node_masses[:, None] * v * v))


def _without_friction(sim: Simulator, x: np.ndarray) -> float:
    """U(x): elastic, contact penalty and gravity energy, no friction (the previous state 1 m
    up: no node had a normal force, so neither law has friction)."""
    return sim.energy(x, x + [0.0, 1.0, 0.0], np.zeros(sim.n_motors))


@pytest.mark.parametrize("law", FRICTION_LAWS, ids=lambda law: law.name)
def test_sliding_tumbling_block_never_gains_energy(law):
    """A bar thrown onto the ground (5 mm up, 0.4 m/s forward, 0.2 m/s down, spinning about +y
    and pitching about +z) lands on an edge, rocks (nodes leave the ground and land again) and
    slides to rest; friction removes most of the kinetic energy.

    What is never created. Step k minimises ``|x - x_tilde|_M^2 / (2 h^2) + E_k(x)`` with
    ``E_k = E(.; x_{k-1}, history_k)``, the energy with the step's lagged normal forces and
    anchors. With E_k convex (penalty, friction; the elastic energy near rest), implicit Euler
    gives ``KE_k + E_k(x_k) <= KE_{k-1} + E_k(x_{k-1})``: *a step creates no energy when its
    friction element's energy is counted as the step sees it*. Checked at every step, to what
    the Newton tolerance allows (|dE| <= weight x 1e-9 m, tolerance 1e-12 m).

    The mechanical energy H = KE + U (U: elastic, penalty, gravity; no friction) follows:
    ``H_k <= H_{k-1} + S_{k-1}`` with ``S_{k-1} = E_k(x_{k-1}) - U(x_{k-1})`` the energy stored
    in the friction element when the step starts. The paper's law stores none (its friction
    energy vanishes at zero slide), so H never increases. The Coulomb law's bristles store
    ``mu N G(r) <= (2/3) mu N r_s`` per node (a stuck, loaded bristle can spring back), so H may
    rise by at most that, which is also checked; and its anchor update only releases bristle
    energy: a node's distance to its anchor never grows in the update (G is increasing)."""
    robot = block(law.contact)
    sim = Simulator(robot, dt=0.01, newton=NewtonOptions(tol=1e-12))
    X = np.array(robot.mesh.points)
    c = X.mean(axis=0)
    v = np.array([0.4, -0.2, 0.0]) + np.cross([0.0, 2.0, 8.0], X - c)      # [m/s], spin [rad/s]
    x0 = X + [0.0, 5e-3, 0.0]
    xs = np.concatenate([[x0 - v * sim.dt], sim.rollout(np.zeros((80, 0)), x0=x0, x_prev0=x0 - v * sim.dt).x])
    histories = [sim.initial_history(x0)]                   # the rollout's default start: at rest at x0
    for k in range(1, len(xs) - 1):
        histories.append(sim.next_history(xs[k + 1], xs[k], histories[-1]))
    u0, weight = np.zeros(0), robot.total_mass * G
    tol = weight * 1e-9
    H = np.array([_kinetic(sim, xs[k], xs[k - 1]) + _without_friction(sim, xs[k]) for k in range(1, len(xs))])
    for k in range(1, len(xs) - 1):                         # the step from xs[k] to xs[k + 1]
        step_energy = lambda x: sim.energy(x, xs[k], u0, history=histories[k - 1])  # noqa: E731
        before = _kinetic(sim, xs[k], xs[k - 1]) + step_energy(xs[k])
        after = _kinetic(sim, xs[k + 1], xs[k]) + step_energy(xs[k + 1])
        assert after - before <= tol, f"{law.name}: step {k} created {after - before:.3e} J"
        stored = step_energy(xs[k]) - _without_friction(sim, xs[k])
        assert H[k] - H[k - 1] <= stored + tol, f"{law.name}: step {k}: H rose {H[k] - H[k - 1]:.3e} J"
        if "slip_distance" in law.contact:
            N = documented_normal_force(-xs[k][:, 1], robot.contact)
            assert -tol <= stored <= 2 / 3 * law.contact["friction_coefficient"] * law.contact["slip_distance"] \
                * N.sum() + tol, f"step {k}: bristles store {stored:.3e} J"
            i = sim.system.terms.index(sim.system.contact)
            t = xs[k + 1][sim.system.contact.nodes][:, [0, 2]]
            r_old = np.linalg.norm(t - histories[k - 1][i], axis=1)
            r_new = np.linalg.norm(t - histories[k][i], axis=1)
            assert np.all(r_new <= r_old + 1e-15), f"step {k}: an anchor update stored bristle energy"
        else:
            assert abs(stored) <= tol, f"{law.name}: step {k}: the paper's friction stores {stored:.3e} J"
    below = xs[1:, :, 1] < 0
    assert not below[0].any() and below[-1].any()                # it landed ...
    assert (below[:-1] & ~below[1:]).any()                       # ... and nodes lost contact again
    kinetic0 = 0.5 * float(np.sum(robot.node_masses[:, None] * v * v))
    assert H[0] - H[-1] > 0.5 * kinetic0                          # most of the motion dissipated
    assert np.abs(xs[-1] - xs[-2]).max() / sim.dt < 0.05 * np.abs(v).max()   # nearly at rest


# ----------------------------------------------------------------------------- masses
def two_tet_robot(**kw) -> Robot:
    """Tet A = origin + the three unit axes (scaled by 0.1 m): volume 1/6 dm^3; tet B = the
    face x + y + z = 1 with apex (1, 1, 1): volume 1/3 dm^3. Nodes 1, 2, 3 are shared."""
    p = 0.1 * np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], dtype=float)
    t = np.array([[0, 1, 2, 3], [1, 2, 3, 4]])
    return Robot.from_mesh(meshio.Mesh(p, [("tetra", t)]), youngs_modulus=1e5, poisson_ratio=0.3,
                           density=300.0, **kw)


def test_lumped_masses_of_two_tets_by_hand():
    """rho V / 4 per node of each tet: tet A 300 * 1e-3 / 6 = 50 g, tet B 100 g; the origin gets
    12.5 g, the shared nodes 12.5 + 25 g, the apex 25 g; a 40 g payload on nodes 0 and 4 adds
    20 g to each."""
    robot = two_tet_robot()
    np.testing.assert_allclose(robot.node_masses, [0.0125, 0.0375, 0.0375, 0.0375, 0.025], rtol=1e-12)
    assert robot.body_mass == pytest.approx(0.150, rel=1e-12) == robot.total_mass
    loaded = two_tet_robot(payload_mass=0.04, payload_nodes=[0, 4])
    np.testing.assert_allclose(loaded.node_masses, [0.0325, 0.0375, 0.0375, 0.0375, 0.045], rtol=1e-12)
    assert loaded.total_mass == pytest.approx(0.190, rel=1e-12)
    # gravity acts on these masses: in the air and undeformed, the only force is m_i g
    sim = Simulator(loaded)
    x = np.array(loaded.mesh.points) + [0.0, 1.0, 0.0]
    np.testing.assert_allclose(sim.gradient(x, x, np.zeros(0)),
                               np.outer(loaded.node_masses, [0.0, G, 0.0]), rtol=1e-12, atol=1e-15)
    com = loaded.com(x)
    np.testing.assert_allclose(com, (loaded.node_masses @ x) / 0.190, rtol=1e-12)


# ----------------------------------------------------------------------------- cantilever
BEAM = dict(L=0.1, a=0.01, E=1e6, nu=0.3, rho=100.0)    # 10 cm x 1 cm x 1 cm, tip sag 1.5 % of L


def timoshenko_tip_deflection(L, a, E, nu, rho) -> float:
    """Tip deflection of a clamped beam of square section a x a under its own weight q = rho g A:
    ``q L^4 / (8 E I) + q L^2 / (2 kappa G A)``, Cowper's kappa = 10 (1 + nu) / (12 + 11 nu)."""
    A, I = a * a, a**4 / 12.0
    q = rho * G * A
    shear = E / (2.0 * (1.0 + nu))
    kappa = 10.0 * (1.0 + nu) / (12.0 + 11.0 * nu)
    return q * L**4 / (8.0 * E * I) + q * L**2 / (2.0 * kappa * shear * A)


def fem_tip_deflection(n_side: int, L, a, E, nu, rho) -> float:
    """Static tip deflection (mean over the tip face) of the clamped beam meshed with cubes of
    side a / n_side (6 tets each), one static Newton solve (a step of 1e4 s from rest)."""
    n_len = int(round(n_side * L / a))
    p, t = voxel_tet_mesh(np.linspace(0, L, n_len + 1), 0.05 + np.linspace(0, a, n_side + 1),
                          np.linspace(0, a, n_side + 1), np.ones((n_len, n_side, n_side), bool))
    robot = Robot.from_mesh(meshio.Mesh(p, [("tetra", t)]), youngs_modulus=E, poisson_ratio=nu, density=rho,
                            fixed_nodes=np.flatnonzero(p[:, 0] < 1e-12))
    sim = Simulator(robot, dt=1e4, newton=NewtonOptions(tol=1e-13))
    x = sim.step(sim.state_at_rest(p).replace(x_prev2=None), np.zeros(0)).x
    tip = p[:, 0] > L - 1e-12
    return float((p[tip, 1] - x[tip, 1]).mean())


def richardson_limit(h: np.ndarray, d: np.ndarray) -> tuple[float, float]:
    """``(d_0, p)`` with ``d(h) = d_0 - C h^p`` through three (h, d) points (h decreasing)."""
    target = (d[2] - d[1]) / (d[1] - d[0])
    lo, hi = 0.2, 6.0
    for _ in range(200):                              # bisection on the observed order p
        p = 0.5 * (lo + hi)
        ratio = (h[1] ** p - h[2] ** p) / (h[0] ** p - h[1] ** p)
        lo, hi = (p, hi) if ratio > target else (lo, p)
    C = (d[1] - d[0]) / (h[0] ** p - h[1] ** p)
    return float(d[2] + C * h[2] ** p), float(p)


#: accepted ratio of the mesh-converged FEM deflection to Timoshenko theory
BEAM_WINDOW = (0.97, 1.03)


def beam_check(E: float) -> tuple[bool, str]:
    """Is the FEM beam made of a material with modulus ``E`` consistent with beam theory for
    the nominal modulus? Linear tets lock in bending (ratios 0.79, 0.88, 0.93 on 4, 6, 8 cubes
    across), so the deflection is extrapolated to zero mesh size (Richardson, observed order
    ~1.4-1.6; 1.010 from 4/6/8 cubes, 0.996 from 6/8/10) before comparing with
    ``BEAM_WINDOW``: +-3 %, which a 5 % stiffer or softer material misses."""
    params = {**BEAM, "E": E}
    n = np.array([4, 6, 8])
    d = np.array([fem_tip_deflection(k, **params) for k in n])
    assert np.all(np.diff(d) > 0), f"not converging monotonically from below: {d}"
    limit, order = richardson_limit(1.0 / n, d)
    ratio = limit / timoshenko_tip_deflection(**BEAM)
    msg = (f"E = {E:.4g} Pa: FEM tip deflections {np.round(d * 1e3, 5)} mm (4, 6, 8 cubes across), "
           f"extrapolated {limit * 1e3:.5f} mm (order {order:.2f}) = {ratio:.4f} x Timoshenko")
    return bool(BEAM_WINDOW[0] <= ratio <= BEAM_WINDOW[1]) and 1.0 < order < 2.5, msg


def test_cantilever_matches_timoshenko_beam_theory():
    ok, msg = beam_check(BEAM["E"])
    assert ok, msg


@pytest.mark.slow
@pytest.mark.parametrize("factor", [1.05, 0.95])
def test_cantilever_window_rejects_a_five_percent_stiffer_or_softer_material(factor):
    ok, msg = beam_check(BEAM["E"] * factor)
    assert not ok, "the beam-theory window accepts the wrong material: " + msg
