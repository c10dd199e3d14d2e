r"""A co-design problem whose answer is known in sign (issue #29): a cable along a clamped beam.

A foam beam (length L, clamped at x = 0, no gravity) carries a cable from an anchor at x = a
back to the clamp, at a height e above the neutral axis. Contracting the cable by u bends the
part [0, a] and compresses it. With the cable much stiffer than the beam, beam theory gives the
tension T = EI theta / (a e) for a rotation theta of the anchor's section, a contraction
``u = e theta + T a / (EA) = theta (e + r^2 / e)`` (r^2 = I/A, the radius of gyration) and a tip
deflection ``delta = theta (L - a/2)``, so

.. math::
    \frac{\delta}{u} = \frac{L - a/2}{e + r^2/e} .

Lever-arm reasoning: moving the via points away from the neutral axis (larger e) helps while
e < r (the moment arm wins over the lost axial contraction) and hurts beyond, at the relative
rate ``d ln(delta/u)/de = (r^2/e^2 - 1) / (e + r^2/e)``; moving the anchor toward the tip
(larger a) lowers the deflection per unit contraction, at the relative rate ``-1 / (2L - a)``.
The design derivatives (static equilibrium under contraction u, differentiated through the rest
relaxation, :meth:`~soft_envs.sim.Simulator.rest_sensitivity`) must have the sign of the beam
model on both sides of r and its rate within 30 % (shear, finite rotation and the coarse tets'
locking are not in the beam model).
"""
from __future__ import annotations

import meshio
import numpy as np
import pytest

from soft_envs.sim import NewtonOptions, Robot, Simulator
from soft_envs.sim.design import DesignParameters, TendonRouting
from soft_envs.sim.meshgen import voxel_tet_mesh

from .gradcheck import relative_error

L, SIDE, Y0 = 0.08, 0.016, 0.05            # beam length, square section, its bottom
AXIS = Y0 + SIDE / 2                        # neutral axis height
U = 2e-4                                    # contraction [m]


def beam_with_cable(e: float, a: float = 0.061) -> Robot:
    xs = np.linspace(0, L, 13)
    ys = Y0 + np.linspace(0, SIDE, 5)
    zs = np.linspace(0, SIDE, 5)
    p, t = voxel_tet_mesh(xs, ys, zs, np.ones((12, 4, 4), bool))
    y, z = AXIS + e, 0.0083
    return Robot.from_mesh(meshio.Mesh(p, [("tetra", t)]), youngs_modulus=1e5, poisson_ratio=0.3, density=100.0,
                           fixed_nodes=np.flatnonzero(p[:, 0] < 1e-12),
                           tendons=[dict(name="c", points=[[a, y + 3e-4, z], [0.031, y, z], [0.0035, y, z]])],
                           motors=[dict(name="m", tendons=["c"], u_max=0.01)])


def deflection_per_contraction(robot, design=None):
    """``delta/u`` at contraction U (tip: mean y displacement of the end face) and, with a
    ``design``, its derivative."""
    sim = Simulator(robot, gravity=(0.0, 0.0, 0.0), newton=NewtonOptions(tol=1e-12))
    tip = np.flatnonzero(robot.mesh.points[:, 0] > L - 1e-12)
    if design is None:
        x = sim.rest_positions(u=[U], tol=1e-13)
        return (x[tip, 1] - robot.mesh.points[tip, 1]).mean() / U
    x, _, dx, _ = sim.rest_sensitivity(design, u=[U], tol=1e-13)
    delta = (x[tip, 1] - robot.mesh.points[tip, 1]).mean()
    ddelta = dx.reshape(robot.mesh.n_nodes, 3, -1)[tip, 1].mean(axis=0)
    return delta / U, ddelta / U


@pytest.mark.parametrize("arm", [0.3, 1.5])
def test_deflection_per_contraction_follows_the_lever_arm(arm):
    """Via points moved away from the neutral axis: d(delta/u)/de > 0 below the radius of
    gyration, < 0 above it, with the relative rate of beam theory within 30 %; the derivative
    itself against central differences of the static solutions."""
    r = SIDE / np.sqrt(12.0)                        # radius of gyration of the square section
    e = arm * r
    robot = beam_with_cable(e)
    design = DesignParameters(robot, [TendonRouting(robot, fixed=())])
    ratio, grad = deflection_per_contraction(robot, design)
    assert ratio > 1.0, f"the beam bends up under contraction: delta/u = {ratio:.3f}"
    up = np.zeros(len(design))
    up[1::3] = 1.0                                  # every point up: a larger lever arm e
    rate, expected = (grad @ up) / ratio, -(1 - r**2 / e**2) / (e + r**2 / e)
    assert np.sign(rate) == np.sign(expected) and abs(rate / expected - 1) < 0.3, \
        f"e = {e:.4f} m, r = {r:.4f} m: d ln(delta/u)/de = {rate:.4g} /m, beam theory {expected:.4g} /m"
    h = 1e-7
    fd = (deflection_per_contraction(design.robot_at(design.values + h * up))
          - deflection_per_contraction(design.robot_at(design.values - h * up))) / (2 * h)
    err = relative_error(np.array([grad @ up]), np.array([fd]))
    assert err <= 1e-6, f"d(delta/u)/de: analytic {grad @ up:.8g}, FD {fd:.8g}, relative error {err:.2e}"


def test_anchor_along_the_beam_follows_beam_theory_across_elements():
    """Moving the anchor toward the tip lowers delta/u at the rate of beam theory, over
    distances of a few elements (a secant across 4.5 cells). Inside one tet the derivative
    differs (it may even have the other sign): the embedding is piecewise affine, so delta/u
    zigzags around the macroscopic trend with kinks on the tets' faces (docs/codesign.md)."""
    r = SIDE / np.sqrt(12.0)
    e, a0, a1 = 0.3 * r, 0.045, 0.075
    rate = (np.log(deflection_per_contraction(beam_with_cable(e, a1)))
            - np.log(deflection_per_contraction(beam_with_cable(e, a0)))) / (a1 - a0)
    expected = -1.0 / (2 * L - 0.5 * (a0 + a1))
    assert rate < 0 and abs(rate / expected - 1) < 0.3, \
        f"d ln(delta/u)/da over [{a0}, {a1}] m: {rate:.4g} /m, beam theory {expected:.4g} /m"
