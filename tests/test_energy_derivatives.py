"""Central finite differences of every energy term's gradient and Hessian (rel. error <= 1e-6).

Each check perturbs x along random unit directions with h = 1e-7 m and compares
(E(x + h d) - E(x - h d)) / 2h with grad . d, and the same for the gradient and the Hessian.
"""
from __future__ import annotations

import numpy as np
import pytest

from soft_envs.sim import ContactParams, Simulator
from soft_envs.sim.cables import Q, d2Q, dQ, one_sided_quadratic
from soft_envs.sim.materials import element_energy, element_gradient_hessian, lame_parameters

from .conftest import small_robot

RTOL = 1e-6
H = 1e-7


def fd_check(f, grad, x, rng, n_dirs=4, h=H):
    """Max relative error of grad.d against central differences of f over random directions."""
    worst = 0.0
    for _ in range(n_dirs):
        d = rng.normal(size=x.shape)
        d /= np.linalg.norm(d)
        fd = (f(x + h * d) - f(x - h * d)) / (2 * h)
        an = np.tensordot(grad, d, axes=d.ndim) if np.ndim(grad) > d.ndim else np.sum(grad * d)
        worst = max(worst, np.linalg.norm(np.atleast_1d(fd - an)) / max(np.linalg.norm(np.atleast_1d(fd)), 1e-300))
    return worst


def test_one_sided_quadratic_is_c2():
    k, eps = 3.0, 0.1
    for s in [-0.05, 0.0, 0.03, 0.1, 0.25]:
        h = 1e-7
        assert abs((Q(s + h, k, eps) - Q(s - h, k, eps)) / (2 * h) - dQ(s, k, eps)) < 1e-6
        assert abs((dQ(s + h, k, eps) - dQ(s - h, k, eps)) / (2 * h) - d2Q(s, k, eps)) < 1e-5
    # continuity of Q'' at both ends of the blend
    assert d2Q(1e-12, k, eps) < 1e-9 and abs(d2Q(eps - 1e-12, k, eps) - k) < 1e-9
    q, dq, d2q = one_sided_quadratic(np.array([-1.0, 0.05, 0.2]), k, eps)
    assert q[0] == dq[0] == d2q[0] == 0.0
    assert np.allclose([q[1], dq[1], d2q[1]], [Q(0.05, k, eps), dQ(0.05, k, eps), d2Q(0.05, k, eps)])


def test_neo_hookean_element_derivatives():
    rng = np.random.default_rng(1)
    mu, lam = lame_parameters(1e5, 0.3)
    X = np.array([[0, 0, 0], [0.01, 0, 0], [0, 0.01, 0], [0, 0, 0.01]], float)
    dm = (X[1:] - X[0]).T
    dNe = np.zeros((4, 3))
    dNe[1:] = np.linalg.inv(dm)
    dNe[0] = -dNe[1:].sum(0)
    vol = np.linalg.det(dm) / 6
    tet = np.arange(4)
    x = X + rng.normal(scale=1e-3, size=X.shape)   # ~10 % strain
    g = np.empty(12)
    Hm = np.empty((12, 12))
    e = element_gradient_hessian(x, tet, dNe, vol, mu, lam, g, Hm)
    assert np.isclose(e, element_energy(x, tet, dNe, vol, mu, lam))
    assert np.allclose(Hm, Hm.T, rtol=1e-12, atol=1e-12 * np.abs(Hm).max())
    f = lambda y: element_energy(y, tet, dNe, vol, mu, lam)  # noqa: E731
    assert fd_check(f, g.reshape(4, 3), x, rng) < RTOL

    def grad(y):
        gg = np.empty(12)
        element_gradient_hessian(y, tet, dNe, vol, mu, lam, gg, np.empty((12, 12)))
        return gg
    for _ in range(4):
        d = rng.normal(size=x.shape)
        d /= np.linalg.norm(d)
        fd = (grad(x + H * d) - grad(x - H * d)) / (2 * H)
        assert np.linalg.norm(fd - Hm @ d.ravel()) / np.linalg.norm(fd) < RTOL


def test_neo_hookean_small_strain_is_linear_elasticity():
    """Small strains reproduce Hooke's law with E and nu: uniaxial stress test on one tet's
    stress: sigma_xx / eps_xx = E when the lateral stresses vanish."""
    E, nu = 2e5, 0.3
    mu, lam = lame_parameters(E, nu)
    eps = 1e-7
    F = np.diag([1 + eps, 1 - nu * eps, 1 - nu * eps])
    J = np.linalg.det(F)
    P = mu * F + (lam * np.log(J) - mu) * np.linalg.inv(F).T
    assert abs(P[0, 0] / eps - E) / E < 1e-5
    assert abs(P[1, 1]) / (E * eps) < 1e-5


def test_inverted_element_has_infinite_energy():
    mu, lam = lame_parameters(1e5, 0.3)
    X = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    dNe = np.zeros((4, 3))
    dNe[1:] = np.linalg.inv((X[1:] - X[0]).T)
    dNe[0] = -dNe[1:].sum(0)
    x = X.copy()
    x[3, 2] = -0.5                      # pushed through the opposite face
    assert element_energy(x, np.arange(4), dNe, 1 / 6, mu, lam) == np.inf


CASES = ["taut_cable_contact_friction", "cable_in_blend", "slack_cable", "contact_in_blend",
         "tension_control", "fixed_nodes", "incline", "coulomb_stick_and_slip", "coulomb_half_quadratic",
         "half_quadratic_cable"]


def perturbed_state(case: str, **robot_kw):
    """``(sim, x, x_prev, u, rng)`` for one regime of the energy terms (see CASES); ``robot_kw``
    overrides the small robot's fields (another contact law: ``contact=ContactParams(...)``)."""
    rng = np.random.default_rng(CASES.index(case))
    kw, control, gravity = {}, "length", (0.0, -9.81, 0.0)
    if case == "fixed_nodes":
        kw["fixed_nodes"] = np.arange(3)
    if case.startswith("coulomb"):
        # a slip distance of 0.33 mm so that central differences resolve the stick regime
        kw["contact"] = ContactParams(model="coulomb", friction_coefficient=0.7, slip_distance=3.3e-4,
                                      blend=0.0 if case == "coulomb_half_quadratic" else 5e-4)
    if case == "half_quadratic_cable":
        kw["cable_blend"] = 0.0
    robot = small_robot(**{**kw, **robot_kw})
    if case == "tension_control":
        control = "tension"
    if case == "incline":
        gravity = (-3.0, -9.3, 0.5)
    sim = Simulator(robot, control=control, gravity=gravity)
    X = robot.mesh.points
    x = X + rng.normal(scale=5e-4, size=X.shape)
    x_prev = X + rng.normal(scale=5e-4, size=X.shape)
    L0 = sim.system.cables.alpha0[0]
    L = sim.system.cables.lengths(x)[0]
    u = {"taut_cable_contact_friction": np.array([L0 - L + 2e-3]),   # Gamma = 2 mm
         "cable_in_blend": np.array([L0 - L + 1e-4]),                 # inside the C2 blend
         "slack_cable": np.array([L0 - L - 1e-3]),
         "tension_control": np.array([3.0])}.get(case, np.array([L0 - L + 1e-3]))
    # put nodes into the ground: in the contact blend (s < 5e-4) or the quadratic part
    depth = 2e-4 if case == "contact_in_blend" else 8e-4
    x[:, 1] -= depth
    x_prev[:, 1] -= depth * rng.uniform(0.2, 2.0, size=len(x))
    return sim, x, x_prev, u, rng


def _rel(a, b, floor=1e-300):
    return np.linalg.norm(np.asarray(a) - np.asarray(b)) / max(np.linalg.norm(b), floor)


@pytest.mark.parametrize("case", CASES)
def test_every_term_derivatives_match_finite_differences(case):
    """Each energy term on its own (the list in EnergySystem.terms, so a new term is checked
    without a new test): gradient vs central differences of its energy, Hessian vs differences
    of its gradient, the control Jacobian d(grad)/du vs differences in u, the lagged product
    d(grad)/dx_prev @ S (and its transpose) vs differences in x_prev, and for terms with a
    history (stick anchors) d(grad)/dhist @ P and d(next history)/dz vs differences, with
    their transposes. Relative error <= RTOL = 1e-6 with h = 1e-7 (m or the control's unit)."""
    sim, x, x_prev, u, rng = perturbed_state(case)
    system = sim.system
    history = system.initial_history(x_prev)
    if case == "coulomb_stick_and_slip":        # anchors 0-0.6 mm from the nodes: both regimes
        c = system.contact
        history = list(history)
        history[system.terms.index(c)] = x[c.nodes][:, [0, 2]] + rng.normal(scale=2.5e-4, size=(len(c.nodes), 2))
        history = tuple(history)
    check_every_term(sim, x, x_prev, u, rng, history)


def check_every_term(sim, x, x_prev, u, rng, history) -> None:
    """The checks of :func:`test_every_term_derivatives_match_finite_differences` for every term
    of ``sim.system`` at one state (``history`` aligned with the terms)."""
    system = sim.system
    n3 = system.n_dof
    pat = system.pattern
    free = system.free
    for term, hist in zip(system.terms, history):
        def term_grad(y, yp=x_prev, uu=u, hh=hist):
            g = np.zeros(n3)
            h = np.zeros(pat.nnz + 1)
            term.assemble(y, yp, uu, hh, g, h, True)
            return g, h

        g, h = term_grad(x)
        E = lambda y: term.energy(y, x_prev, u, hist)                         # noqa: E731
        assert np.isclose(term.assemble(x, x_prev, u, hist, np.zeros(n3), np.zeros(pat.nnz + 1), False),
                          E(x), rtol=1e-13, atol=1e-300), term.name
        assert fd_check(E, g.reshape(x.shape), x, rng) < RTOL, term.name
        Hm = pat.full(h)                                                       # free dofs only
        for _ in range(3):
            d = np.zeros(x.shape)
            d.reshape(-1)[free] = rng.normal(size=len(free))
            d /= np.linalg.norm(d)
            fd = (term_grad(x + H * d)[0] - term_grad(x - H * d)[0])[free] / (2 * H)
            an = Hm @ d.reshape(-1)[free]
            scale = max(np.linalg.norm(fd), 1e-12 * np.abs(h).max() + 1e-300)
            assert np.linalg.norm(fd - an) / scale < RTOL, f"{term.name}: Hessian"
        G = np.zeros((n3, len(u)))
        term.add_control_jacobian(x, x_prev, u, hist, G)
        du = 1e-7 if sim.control == "length" else 1e-4
        fd = (term_grad(x, uu=u + du)[0] - term_grad(x, uu=u - du)[0]) / (2 * du)
        assert np.linalg.norm(fd - G[:, 0]) <= RTOL * max(np.linalg.norm(fd), 1e-300) + 1e-9, \
            f"{term.name}: control Jacobian"
        S = rng.normal(size=(n3, 2))
        out = np.zeros_like(S)
        term.add_prev_product(x, x_prev, u, hist, S, out)
        for j in range(2):
            d = S[:, j].reshape(x.shape)
            fd = (term_grad(x, yp=x_prev + H * d)[0] - term_grad(x, yp=x_prev - H * d)[0]) / (2 * H)
            assert np.linalg.norm(fd - out[:, j]) <= RTOL * max(np.linalg.norm(fd), 1e-300) + 1e-9, \
                f"{term.name}: d(grad)/dx_prev"
        lam = rng.normal(size=n3)
        outT = np.zeros(n3)
        term.add_prev_product_T(x, x_prev, u, hist, lam, outT)
        assert np.isclose(lam @ out[:, 0], outT @ S[:, 0], rtol=1e-12, atol=1e-300), f"{term.name}: transpose"
        if not term.has_history:
            continue
        P = rng.normal(size=(hist.size, 2))
        outP = np.zeros((n3, 2))
        term.add_history_product(x, x_prev, u, hist, P, outP)
        for j in range(2):
            dp = P[:, j].reshape(hist.shape)
            fd = (term_grad(x, hh=hist + H * dp)[0] - term_grad(x, hh=hist - H * dp)[0]) / (2 * H)
            assert _rel(outP[:, j], fd) < RTOL, f"{term.name}: d(grad)/dhist"
        outPT = np.zeros(hist.size)
        term.add_history_product_T(x, x_prev, u, hist, lam, outPT)
        assert np.isclose(lam @ outP[:, 0], outPT @ P[:, 0], rtol=1e-12), f"{term.name}: d(grad)/dhist transpose"
        # the history update: d next / dz from dx/dz = S and dhist/dz = P
        T = term.history_tangent(x, x_prev, hist, S, P)
        for j in range(2):
            dx_, dp = S[:, j].reshape(x.shape), P[:, j].reshape(hist.shape)
            fd = (term.next_history(x + H * dx_, x_prev, hist + H * dp)
                  - term.next_history(x - H * dx_, x_prev, hist - H * dp)).ravel() / (2 * H)
            assert _rel(T[:, j], fd) < RTOL, f"{term.name}: history tangent"
        m = rng.normal(size=hist.size)
        ox, oh = np.zeros(n3), np.zeros(hist.size)
        term.history_tangent_T(x, x_prev, hist, m, ox, oh)
        assert np.isclose(m @ T[:, 0], ox @ S[:, 0] + oh @ P[:, 0], rtol=1e-12), f"{term.name}: tangent transpose"


@pytest.mark.parametrize("case", CASES)
def test_total_energy_gradient_and_hessian(case):
    """Gradient and Hessian of the whole potential E(x; u, x_prev) for each term and regime."""
    check_total_energy(*perturbed_state(case))


def check_total_energy(sim, x, x_prev, u, rng) -> None:
    """The checks of :func:`test_total_energy_gradient_and_hessian` at one state."""
    robot = sim.robot
    case = "fixed_nodes" if robot.fixed_nodes.size else ""
    E = lambda y: sim.energy(y, x_prev, u)            # noqa: E731
    G = lambda y: sim.gradient(y, x_prev, u)          # noqa: E731
    g = G(x)
    Hm = sim.hessian(x, x_prev, u)
    if case == "fixed_nodes":
        mask = np.ones_like(x, bool)
        mask[robot.fixed_nodes] = False
        g = g * mask
        E0 = E
        E = lambda y: E0(np.where(mask, y, x))        # noqa: E731
        G0 = G
        G = lambda y: G0(np.where(mask, y, x)) * mask  # noqa: E731
    assert fd_check(E, g, x, rng) < RTOL
    for _ in range(4):
        d = rng.normal(size=x.shape)
        d /= np.linalg.norm(d)
        fd = (G(x + H * d) - G(x - H * d)).ravel() / (2 * H)
        err = np.linalg.norm(fd - Hm @ d.ravel()) / np.linalg.norm(fd)
        assert err < RTOL, f"{case}: Hessian relative error {err:.2e}"
    assert abs(Hm - Hm.T).max() <= 1e-9 * abs(Hm).max()
    # the gradient-only kernels (line searches, chord iterations) give the same E and gradient
    e_h, g_h, _ = sim.system.assemble(x, x_prev, u, want_hess=True)
    e_g, g_g, h_g = sim.system.assemble(x, x_prev, u, want_hess=False)
    assert h_g is None and np.isclose(e_g, e_h, rtol=1e-13, atol=0)
    np.testing.assert_allclose(g_g, g_h, rtol=0, atol=1e-12 * np.abs(g_h).max())


def test_friction_cross_derivative_matches_fd():
    """d(grad E)/d x_prev (the friction term's dependence on the previous state, through the
    displacement and through the normal force N_{k-1}) against central differences."""
    rng = np.random.default_rng(7)
    robot = small_robot()
    sim = Simulator(robot)
    s = sim.system
    X = robot.mesh.points
    x = X + rng.normal(scale=5e-4, size=X.shape)
    x[:, 1] -= 6e-4
    x_prev = X + rng.normal(scale=5e-4, size=X.shape)
    x_prev[:, 1] -= rng.uniform(0, 1e-3, size=len(X))      # some in the blend, some beyond
    u = np.zeros(1)
    S = rng.normal(size=(s.n_dof, 3))
    out = s.prev_product(x, x_prev, u, S)
    for j in range(3):
        d = S[:, j].reshape(-1, 3)
        fd = (sim.gradient(x, x_prev + H * d, u) - sim.gradient(x, x_prev - H * d, u)).ravel() / (2 * H)
        assert np.linalg.norm(fd - out[:, j]) / np.linalg.norm(fd) < RTOL
    # the transpose product is the adjoint of the forward product
    lam = rng.normal(size=s.n_dof)
    outT = np.zeros(s.n_dof)
    s.prev_product_T(x, x_prev, u, lam, outT)
    assert np.allclose(lam @ out, outT @ S, rtol=1e-12)


def test_projected_element_hessian_is_the_psd_part_of_d2psi_df2():
    """``element_hessian_projected`` (analytic eigensystem of d2Psi/dF2) equals
    ``V B^T [d2Psi/dF2]_+ B`` computed with a numerical 9x9 eigen-decomposition, is positive
    semi-definite, and equals the exact Hessian where d2Psi/dF2 already is."""
    from soft_envs.sim.psd_projection import element_hessian_projected
    rng = np.random.default_rng(3)
    X = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]]) * 0.01
    Dm_inv = np.linalg.inv((X[1:] - X[0]).T)
    dN = np.vstack([-Dm_inv.sum(0), Dm_inv])
    vol = 0.01**3 / 6
    mu, lam = lame_parameters(1e5, 0.3)
    B = np.zeros((9, 12))                      # vec(F) = B x_e
    for a in range(4):
        for i in range(3):
            B[3 * i:3 * i + 3, 3 * a + i] = dN[a]
    def rotation():
        R = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        return R * np.sign(np.linalg.det(R))

    seen_indefinite = seen_definite = 0
    nearly_flat = [rotation() @ np.diag([1.0, 1.0, s]) @ rotation() for s in (1e-3, 1e-6, 1e-8)]
    for trial in range(63):
        A = nearly_flat[trial - 60] if trial >= 60 else np.eye(3) + rng.normal(scale=0.35, size=(3, 3))
        if np.linalg.det(A) <= 0.05 and trial < 60:
            continue
        x = X @ A.T + rng.normal(size=3)
        g, Hx = np.zeros(12), np.zeros((12, 12))
        element_gradient_hessian(x, np.arange(4), dN, vol, mu, lam, g, Hx)
        Hp = np.zeros((12, 12))
        assert element_hessian_projected(x, np.arange(4), dN, vol, mu, lam, Hp)
        # d2Psi/dF2 from the exact element Hessian: H = vol B^T D B with B of full row rank
        Bp = np.linalg.pinv(B.T)
        D = Bp @ Hx @ Bp.T / vol
        w, V = np.linalg.eigh(0.5 * (D + D.T))
        ref = vol * B.T @ (V * np.maximum(w, 0.0)) @ V.T @ B
        scale = np.abs(Hx).max()
        assert np.abs(Hp - ref).max() <= 1e-9 * scale
        assert np.linalg.eigvalsh(Hp).min() >= -1e-9 * scale
        if w.min() >= 0:
            seen_definite += 1
            assert np.abs(Hp - Hx).max() <= 1e-9 * scale
        else:
            seen_indefinite += 1
    assert seen_indefinite > 5 and seen_definite > 5
    inverted = X.copy()
    inverted[3, 2] = -0.01
    assert not element_hessian_projected(inverted, np.arange(4), dN, vol, mu, lam, np.zeros((12, 12)))


def test_projected_assembly_adds_only_the_negative_parts():
    """``assemble(project=True)``: same energy and gradient, and a Hessian that exceeds the exact
    one by a positive semi-definite matrix (per element, [A]_+ - A = [-A]_+)."""
    rng = np.random.default_rng(11)
    robot = small_robot()
    sim = Simulator(robot)
    X = robot.mesh.points
    x = X + rng.normal(scale=2e-3, size=X.shape)        # strongly distorted: indefinite elements
    u = np.array([0.002])
    e0, g0, h0 = sim.system.assemble(x, X, u)
    e1, g1, h1 = sim.system.assemble(x, X, u, project=True)
    assert np.isclose(e0, e1, rtol=1e-13, atol=0)
    np.testing.assert_allclose(g1, g0, rtol=0, atol=1e-12 * np.abs(g0).max())
    pat = sim.system.pattern
    diff = (pat.full(h1) - pat.full(h0)).toarray()
    w = np.linalg.eigvalsh(diff)
    assert w.min() >= -1e-9 * np.abs(w).max() and w.max() > 0     # something was projected
