"""A force-limited pusher that tracks a commanded planar path (pymunk).

The pusher is a dynamic body dragged towards a kinematic "control" body by a pivot joint and a
gear joint whose force and torque are limited, as a robot's tracking controller is. Against an
immovable obstacle it stalls instead of tunnelling or exploding.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pymunk

from probaff._checks import check_finite, check_positive, check_shape

__all__ = ["TrackedPusher"]


class TrackedPusher:
    """A pusher body driven along commanded poses.

    Args:
        space: The pymunk space.
        pose: Initial world ``(x, y, yaw)``.
        mass: Pusher mass (kg).
        moment: Pusher moment of inertia (kg m^2).
        make_shapes: ``make_shapes(body)`` creates the pusher's collision shapes on its body.
        max_force: Force limit of the tracking controller (N).
        max_torque: Torque limit (N m).
        max_speed: Fastest correction of a tracking error (m/s).
        max_spin: Fastest correction of a heading error (rad/s).

    Raises:
        InputError: For a non-finite (3,) `pose` or a mass, moment, limit or speed that is not
            a finite number > 0, before anything is added to `space`.
    """

    def __init__(
        self,
        space: pymunk.Space,
        pose: np.ndarray,
        mass: float,
        moment: float,
        make_shapes: Callable[[pymunk.Body], list[pymunk.Shape]],
        max_force: float,
        max_torque: float,
        max_speed: float,
        max_spin: float = 4.0,
    ) -> None:
        check_shape("pose", np.asarray(pose, dtype=float), (3,))
        check_finite("pose", np.asarray(pose, dtype=float))
        for name, value in (
            ("mass", mass),
            ("moment", moment),
            ("max_force", max_force),
            ("max_torque", max_torque),
            ("max_speed", max_speed),
            ("max_spin", max_spin),
        ):
            check_positive(name, value)
        self.control = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        self.control.position = (float(pose[0]), float(pose[1]))
        self.control.angle = float(pose[2])
        self.body = pymunk.Body(mass, moment)
        self.body.position, self.body.angle = self.control.position, self.control.angle
        self.shapes = make_shapes(self.body)
        pivot = pymunk.PivotJoint(self.control, self.body, (0.0, 0.0), (0.0, 0.0))
        pivot.max_force, pivot.max_bias = max_force, max_speed
        gear = pymunk.GearJoint(self.control, self.body, 0.0, 1.0)
        gear.max_force, gear.max_bias = max_torque, max_spin
        space.add(self.control, self.body, *self.shapes, pivot, gear)

    def command(self, now: np.ndarray, nxt: np.ndarray, rate: float) -> None:
        """Command a move from pose `now` to pose `nxt` over one control tick of 1/`rate` s.

        Args:
            now: (3,) world ``(x, y, yaw)`` at the start of the tick.
            nxt: (3,) world ``(x, y, yaw)`` at its end.
            rate: Control rate (Hz).
        """
        self.control.position = (float(now[0]), float(now[1]))
        self.control.angle = float(now[2])
        self.control.velocity = (float(nxt[0] - now[0]) * rate, float(nxt[1] - now[1]) * rate)
        self.control.angular_velocity = float(nxt[2] - now[2]) * rate

    def lag(self, target: np.ndarray) -> float:
        """Distance (m) between the pusher and a commanded position (2,)."""
        return float(np.hypot(self.body.position.x - target[0], self.body.position.y - target[1]))
