"""The locomotion task of the environments: reward and health (in the spirit of dm_control's
Task, kept apart from the physics).

``reward = forward_reward + healthy_reward - ctrl_cost``; the terms are documented in the
Rewards section of :class:`~soft_envs.envs.tripod.SoftTripodEnv`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .arguments import is_number
from .measure import heading_vector

__all__ = ["LocomotionTask"]


def _finite(name: str, value) -> float:
    if not (is_number(value) and np.isfinite(value)):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class LocomotionTask:
    """Walk along ``target_heading_deg`` (``task="walk"``) or turn (``task="turn"``) to the
    ``turn_direction`` side; the keywords are the environments' (see their Arguments table)."""

    task: str = "walk"
    target_heading_deg: float = 0.0
    turn_direction: str = "right"
    turn_radius: float | None = None
    forward_reward_weight: float = 10.0
    ctrl_cost_weight: float = 0.01
    healthy_reward: float = 0.1
    terminate_when_unhealthy: bool = True
    healthy_tilt_deg: float = 60.0
    healthy_height_fraction: float = 0.5

    def __post_init__(self):
        """Every keyword checked: a ValueError names the first bad one."""
        if self.task not in ("walk", "turn"):
            raise ValueError(f"task must be 'walk' or 'turn', got {self.task!r}")
        if self.turn_direction not in ("right", "left"):
            raise ValueError(f"turn_direction must be 'right' or 'left', got {self.turn_direction!r}")
        for name in ("target_heading_deg", "forward_reward_weight", "healthy_reward"):
            _finite(name, getattr(self, name))
        if _finite("ctrl_cost_weight", self.ctrl_cost_weight) < 0:
            raise ValueError(f"ctrl_cost_weight must be >= 0, got {self.ctrl_cost_weight!r}")
        if self.turn_radius is not None and not _finite("turn_radius", self.turn_radius) > 0:
            raise ValueError(f"turn_radius must be positive [m] or None (one body length), got {self.turn_radius!r}")
        if not isinstance(self.terminate_when_unhealthy, (bool, np.bool_)):
            raise ValueError(f"terminate_when_unhealthy must be True or False, got {self.terminate_when_unhealthy!r}")
        if not 0 < _finite("healthy_tilt_deg", self.healthy_tilt_deg) <= 180:
            raise ValueError(f"healthy_tilt_deg must be in (0, 180], got {self.healthy_tilt_deg!r}")
        if not 0 <= _finite("healthy_height_fraction", self.healthy_height_fraction) < 1:
            raise ValueError(f"healthy_height_fraction must be in [0, 1), got {self.healthy_height_fraction!r}")

    @property
    def heading(self) -> np.ndarray:
        """Unit vector (3,) of the target heading in the ground plane."""
        return heading_vector(self.target_heading_deg)

    def is_healthy(self, tilt_deg: float, com: np.ndarray, rest_com_height: float, ground_height: float = 0.0) -> bool:
        """Upright (tilt of the up vector from the ground's normal at most ``healthy_tilt_deg``),
        COM at least ``healthy_height_fraction`` of its rest height, and finite. The heights are
        above the ground: ``com[1] - ground_height`` against ``rest_com_height`` (measured the
        same way at rest; ``ground_height`` 0 on the plane y = 0)."""
        return bool(tilt_deg <= self.healthy_tilt_deg
                    and com[1] - ground_height >= self.healthy_height_fraction * rest_com_height
                    and np.isfinite(com).all())

    def reward(self, forward_velocity: float, yaw_rate: float, action: np.ndarray, healthy: bool,
               body_length: float) -> tuple[float, dict[str, float]]:
        """``(reward, {"reward_forward", "reward_ctrl", "reward_survive"})`` of a step:
        ``forward_velocity`` in body lengths per second along the heading, ``yaw_rate`` [rad/s]
        (> 0 turning right), ``action`` the clipped action."""
        if self.task == "walk":
            progress = forward_velocity
        else:
            sign = 1.0 if self.turn_direction == "right" else -1.0        # +yaw: from +x towards +z
            radius = body_length if self.turn_radius is None else self.turn_radius
            progress = sign * yaw_rate * radius / body_length
        forward = float(self.forward_reward_weight) * progress
        ctrl_cost = float(self.ctrl_cost_weight) * float(np.sum(np.square(0.5 * (action + 1.0))))
        survive = float(self.healthy_reward) if healthy else 0.0
        info = {"reward_forward": forward, "reward_ctrl": -ctrl_cost, "reward_survive": survive}
        return forward + survive - ctrl_cost, info

