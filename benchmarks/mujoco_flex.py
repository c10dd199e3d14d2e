"""A shipped robot's tet mesh as a MuJoCo 3-D flex, for side-by-side benchmarks.

The flex has the same nodes and tets as ``robot.mesh``, the same Young's modulus and Poisson
ratio (MuJoCo's 3-D flex elasticity is Saint Venant-Kirchhoff with the same Lame parameters,
ours neo-Hookean: they agree to first order in the strain), the same lumped node masses
(density * volume / 4 per tet node plus the payload on the top nodes: ``robot.node_masses``),
the same time step, and a ground plane. Each node is a body with three slide joints along the
world axes (what MuJoCo's ``flexcomp`` generates, written out so that every node keeps its own
mass). There are no cables: MuJoCo cannot attach tendons to a flex.

Settings (MuJoCo >= 4.0): ``integrator="discrete"``, MuJoCo's implicit integrator for flex
elasticity (one solve per step in the metric ``M + h D + h^2 K``, linearised at the start of
the step); ``solver="Newton"``; no self-collision (our simulator has none); and, by default,
the ``diagexact`` flag. Without it MuJoCo's soft contact rows use a body-based approximation of
the constraint-space inertia, which for light surface vertices coupled to a heavy body makes
the contact far too soft at h = 0.033 s: the Puppy sinks 16 mm into the ground and the Tripod
sinks 17 mm and tips over (``exact_contact_diagonal=False`` builds that model, for reference).

Frames: ours is +y up (ground y = 0); MuJoCo's is +z up. A point (x, y, z) of ours is
(x, -z, y) in MuJoCo (a rotation, so tets keep their orientation).
"""
from __future__ import annotations

import numpy as np

__all__ = ["flex_mjcf", "FlexModel", "to_mujoco_frame", "from_mujoco_frame"]


def to_mujoco_frame(x: np.ndarray) -> np.ndarray:
    """(..., 3) points from our frame (+y up) to MuJoCo's (+z up)."""
    x = np.asarray(x, dtype=np.float64)
    return np.stack([x[..., 0], -x[..., 2], x[..., 1]], axis=-1)


def from_mujoco_frame(p: np.ndarray) -> np.ndarray:
    """Inverse of :func:`to_mujoco_frame`."""
    p = np.asarray(p, dtype=np.float64)
    return np.stack([p[..., 0], p[..., 2], -p[..., 1]], axis=-1)


def flex_mjcf(robot, dt: float = 0.033, friction: float = 0.8, exact_contact_diagonal: bool = True,
              iterations: int = 100, placement: np.ndarray | None = None) -> str:
    """MJCF text of ``robot``'s tet mesh as a 3-D flex standing on a ground plane.

    ``placement`` (n, 3), in our frame, is where the node bodies sit at ``qpos = 0`` (default:
    the rest mesh lowered onto the ground, like ``Simulator.initial_placement``). ``friction``
    is the Coulomb coefficient of the flex-ground contact (MuJoCo's law: a pyramidal cone).
    ``iterations`` caps MuJoCo's solver iterations (its default, 100); the same cap applies to
    the iterative solve of the flex's ``M + h^2 K`` system, which on these meshes at h = 0.033 s
    does not converge within 100 iterations (a warning, ``mjWARN_INERTIA``, every step).
    """
    pts = np.array(robot.mesh.points, dtype=np.float64) if placement is None else np.asarray(placement, float)
    if placement is None:
        pts[:, 1] -= pts[:, 1].min()
    if pts.shape != (robot.mesh.n_nodes, 3):
        raise ValueError(f"placement must have shape ({robot.mesh.n_nodes}, 3), got {pts.shape}")
    masses = np.asarray(robot.node_masses, dtype=np.float64)
    if not (masses > 0).all():
        raise ValueError(f"{robot.name}: every node needs a positive mass for a MuJoCo body")
    bodies = []
    for i, (p, m) in enumerate(zip(to_mujoco_frame(pts), masses)):
        inertia = m * 1e-6        # slide joints only: the rotational inertia is never used
        bodies.append(
            f'    <body name="n{i}" pos="{p[0]:.17g} {p[1]:.17g} {p[2]:.17g}">'
            f'<inertial pos="0 0 0" mass="{m:.17g}" diaginertia="{inertia:.6g} {inertia:.6g} {inertia:.6g}"/>'
            '<joint type="slide" axis="1 0 0"/><joint type="slide" axis="0 1 0"/>'
            '<joint type="slide" axis="0 0 1"/></body>')
    names = " ".join(f"n{i}" for i in range(len(pts)))
    elements = " ".join(str(int(v)) for v in np.asarray(robot.mesh.tets).ravel())
    flags = '<flag diagexact="enable"/>' if exact_contact_diagonal else ""
    fr = f"{friction:.17g} 0.005 0.0001"
    body_text = "\n".join(bodies)
    return f"""<mujoco model="{robot.name}_flex">
  <option timestep="{dt:.17g}" integrator="discrete" solver="Newton" iterations="{int(iterations)}"
          gravity="0 0 -9.81">{flags}</option>
  <worldbody>
    <geom name="ground" type="plane" size="0 0 1" friction="{fr}"/>
{body_text}
  </worldbody>
  <deformable>
    <flex name="{robot.name}" dim="3" radius="0" body="{names}" element="{elements}">
      <elasticity young="{robot.youngs_modulus:.17g}" poisson="{robot.poisson_ratio:.17g}"/>
      <contact selfcollide="none" condim="3" friction="{fr}"/>
    </flex>
  </deformable>
</mujoco>
"""


class FlexModel:
    """A compiled :func:`flex_mjcf` model and its data, read and written in our frame."""

    def __init__(self, robot, dt: float = 0.033, friction: float = 0.8, exact_contact_diagonal: bool = True,
                 iterations: int = 100):
        import mujoco

        self.mujoco = mujoco
        self.robot = robot
        placement = np.array(robot.mesh.points, dtype=np.float64)
        placement[:, 1] -= placement[:, 1].min()
        self.placement = placement
        self.model = mujoco.MjModel.from_xml_string(
            flex_mjcf(robot, dt, friction, exact_contact_diagonal, iterations, placement))
        self.data = mujoco.MjData(self.model)
        mujoco.mj_forward(self.model, self.data)
        n = robot.mesh.n_nodes
        if self.model.nq != 3 * n or self.model.nflexvert != n or self.model.nflexelem != robot.mesh.n_tets:
            raise RuntimeError(f"MuJoCo built {self.model.nq} dofs, {self.model.nflexvert} vertices and "
                               f"{self.model.nflexelem} elements for {n} nodes and {robot.mesh.n_tets} tets")
        self.masses = np.array(self.model.body_mass[1:])
        self._p0 = to_mujoco_frame(placement)

    @property
    def total_mass(self) -> float:
        return float(self.masses.sum())

    def positions(self) -> np.ndarray:
        """Node positions (n, 3) in our frame, from ``qpos`` (current after ``mj_step``)."""
        return from_mujoco_frame(self._p0 + self.data.qpos.reshape(-1, 3))

    def set_state(self, x: np.ndarray, v: np.ndarray | None = None) -> None:
        """Node positions ``x`` (n, 3) and velocities ``v`` (default 0), in our frame."""
        self.mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[:] = (to_mujoco_frame(x) - self._p0).ravel()
        if v is not None:
            self.data.qvel[:] = to_mujoco_frame(v).ravel()
        self.mujoco.mj_forward(self.model, self.data)

    def com(self) -> np.ndarray:
        return self.masses @ self.positions() / self.total_mass

    def step(self, n: int = 1) -> None:
        for _ in range(n):
            self.mujoco.mj_step(self.model, self.data)

    def snapshot(self):
        """The full simulation state (positions, velocities, warm start), for :meth:`restore`."""
        m = self.mujoco
        spec = m.mjtState.mjSTATE_INTEGRATION
        state = np.empty(m.mj_stateSize(self.model, spec))
        m.mj_getState(self.model, self.data, state, spec)
        return state

    def restore(self, state) -> None:
        m = self.mujoco
        m.mj_setState(self.model, self.data, state, m.mjtState.mjSTATE_INTEGRATION)

    def warnings(self) -> dict[str, int]:
        """MuJoCo's warning counters that are non-zero, by name."""
        m = self.mujoco
        return {m.mjtWarning(i).name: int(w.number) for i, w in enumerate(self.data.warning) if w.number}
