"""Rendering for the environments: offscreen RGB frames and a matplotlib "human" window.

Frames come from :class:`soft_envs.render.Renderer` (matplotlib Agg, no OpenGL). The window is
created at the first ``"human"`` render only, so importing or constructing an environment never
touches a display; on a headless machine (non-interactive backend) the frames are drawn but not
shown and a notice is logged once per process.
"""
from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from ..sim import Robot
from .measure import cable_points

__all__ = ["EnvViewer", "RenderingMixin", "cable_polylines"]

#: a box's colour (:mod:`soft_envs.sim.box`); the robot keeps the renderer's
BOX_COLOUR = (0.85, 0.62, 0.35)
_NON_INTERACTIVE = {"agg", "pdf", "ps", "svg", "pgf", "cairo", "template"}
_warned_headless = False


def cable_polylines(robot: Robot, x: np.ndarray, tension: np.ndarray) -> list[tuple[np.ndarray, float]]:
    """``[(points (p, 3), tension [N])]`` per tendon at node positions ``x`` (n, 3): what
    :meth:`soft_envs.render.Renderer.render` draws."""
    return [(pts, float(t)) for pts, t in zip(cable_points(robot, x), tension)]


class EnvViewer:
    """Renders states of one robot; holds matplotlib objects (not picklable: recreate)."""

    def __init__(self, surface: np.ndarray, *, width: int, height: int, body_length: float,
                 fps: float, camera_config: Mapping[str, Any] | None = None):
        from ..render import Renderer
        self.renderer = Renderer(surface, width=width, height=height, body_length=body_length,
                                 **dict(camera_config or {}))
        self.size = (width, height)
        self.fps = fps
        self._window = None

    def frame(self, x: np.ndarray, *, cables: Sequence[tuple[np.ndarray, float]],
              com_trail: np.ndarray, gravity: np.ndarray, title: str, **scene: Any) -> np.ndarray:
        """A uint8 (height, width, 3) RGB frame; ``scene``: the ground and goal keywords of
        :meth:`soft_envs.render.Renderer.render` (``ground``, ``ground_height``, ``goal``,
        ``goal_radius``)."""
        return self.renderer.render(x, cables=cables, com_trail=com_trail, gravity=gravity, title=title, **scene)

    def show(self, frame: np.ndarray) -> None:
        """Show ``frame`` in a matplotlib window (created on first use) and let it refresh."""
        global _warned_headless
        try:
            import matplotlib
            import matplotlib.pyplot as plt
        except Exception as err:  # pragma: no cover - broken GUI toolkits
            gym.logger.warn(f"render_mode='human' needs matplotlib.pyplot ({err}); nothing shown")
            return
        interactive = matplotlib.get_backend().lower() not in _NON_INTERACTIVE
        if self._window is None:
            w, h = self.size
            fig = plt.figure(figsize=(w / 100, h / 100), dpi=100)
            ax = fig.add_axes((0, 0, 1, 1))
            ax.set_axis_off()
            self._window = (fig, ax.imshow(frame))
            if not interactive and not _warned_headless:
                _warned_headless = True
                gym.logger.warn(f"render_mode='human': matplotlib backend {matplotlib.get_backend()!r} "
                                "cannot open a window (headless?); frames are drawn but not shown")
        fig, img = self._window
        img.set_data(frame)
        if interactive:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)
                plt.pause(1.0 / self.fps)

    def close(self) -> None:
        if self._window is not None:
            import matplotlib.pyplot as plt
            plt.close(self._window[0])
            self._window = None


class RenderingMixin:
    """``render`` and ``close`` of :class:`soft_envs.envs.base.SoftRobotEnv` (Gymnasium API).

    Uses the environment's ``render_mode``, ``metadata``, ``robot``, ``_viewer`` (None until
    the first frame), ``_base_robot``, ``_width``, ``_height``, ``_body_length``,
    ``_camera_config``, ``_sim``, ``_x``, ``_u``, ``_trail``, ``_gravity``, ``_n_sub`` and
    ``timestep``."""

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' "
                            "or 'human' to gymnasium.make")
            return None
        frame = self._render_frame()
        if self.render_mode == "rgb_array":
            return frame
        self._viewer.show(frame)
        return None

    def _render_frame(self) -> np.ndarray:
        if self._viewer is None:
            surface = self._base_robot.mesh.surface
            config = dict(self._camera_config or {})
            if len(self._base_robot.box_nodes) and "color" not in config:      # a box: wood-coloured
                from ..render import BODY_COLOUR          # (matplotlib: imported with the first frame only)
                on_box = np.isin(surface, self._base_robot.box_nodes).all(axis=1)
                config["color"] = np.where(on_box[:, None], BOX_COLOUR, BODY_COLOUR)
            self._viewer = EnvViewer(surface, width=self._width, height=self._height,
                                     body_length=self._body_length, fps=self.metadata["render_fps"],
                                     camera_config=config)
        cables = cable_polylines(self.robot, self._x, self._sim.cable_tension(self._x, self._u))
        return self._viewer.frame(self._x, cables=cables, com_trail=np.array(self._trail),
                                  gravity=self._gravity,
                                  title=f"{self.robot.name}  t = {self._n_sub * self.timestep:.2f} s",
                                  **self._render_scene())

    def _render_scene(self) -> dict[str, Any]:
        """The ground and the task's marks drawn under the robot: the robot's ground (a
        relief, or the height of a flat one) and whatever the task adds (a goal: its override)."""
        ground = self._base_robot.ground
        if ground is None:
            return {}
        if ground.is_flat:
            return {"ground_height": float(ground.heights.flat[0])}
        return {"ground": ground}

    def close(self) -> None:
        if self._viewer is not None:
            self._viewer.close()
        self._viewer = None
