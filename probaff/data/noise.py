"""Measurement noise on the object poses a dataset records, as a depth camera would see them.

The simulator knows every pose exactly, so an object that did not move has an effect of exactly
zero. A real robot measures poses, for example by fitting object models to depth images, and
each measurement carries an error. `PoseNoise` models that error as independent Gaussian noise
on each object's observed planar pose ``(x, y, theta)`` in the world frame, drawn once for the
measurement before the push and once, independently, for the measurement after it. The observed
effect is the difference of the two noisy measurements expressed in the pushing frame, so its
position components carry noise of standard deviation ``sqrt(2) * position_std`` and its angle
``sqrt(2) * yaw_std``. The pushing frame itself (the commanded hand start and push direction) is
known exactly and is not perturbed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from probaff._checks import (
    as_float_array,
    check_count,
    check_finite,
    check_positive,
    check_shape,
)
from probaff.errors import InputError
from probaff.sim.geometry import push_frame_effect
from probaff.sim.inputs import check_rng

__all__ = ["PoseNoise", "observe_poses", "parse_pose_noise"]


@dataclass(frozen=True)
class PoseNoise:
    """Gaussian measurement noise on observed planar object poses.

    Attributes:
        position_std: Standard deviation of each of the world x and y coordinates of an
            observed object centre (m); default 3 mm.
        yaw_std: Standard deviation of an observed object yaw (rad); default 1 degree.

    Raises:
        InputError: If either value is not a finite number >= 0.
    """

    position_std: float = 0.003
    yaw_std: float = math.radians(1.0)

    def __post_init__(self) -> None:
        for name in ("position_std", "yaw_std"):
            value = getattr(self, name)
            if isinstance(value, (bool, str, bytes)):
                raise InputError(f"pose noise {name} must be a finite number >= 0, got {value!r}.")
            check_positive(f"pose noise {name}", value, allow_zero=True)
            object.__setattr__(self, name, float(value))

    def effect_std(self, n_objects: int = 1) -> list[float]:
        """Noise standard deviation of an observed effect, per effect dimension.

        An effect is the difference of two independent measurements, so each component has
        sqrt(2) times the pose noise: ``(dy_p, dz_p, dth_p)`` per object, objects stacked
        in order. This is the noise floor a push model of such data should use.

        Args:
            n_objects: Objects whose effects are stacked.

        Returns:
            Standard deviations `(3 * n_objects,)`, metres and radians.
        """
        position = math.sqrt(2.0) * self.position_std
        return [position, position, math.sqrt(2.0) * self.yaw_std] * check_count(
            "n_objects", n_objects
        )

    def to_dict(self) -> dict[str, float]:
        """The parameters as a manifest stores them: ``position_std`` (m), ``yaw_std`` (rad)."""
        return {"position_std": self.position_std, "yaw_std": self.yaw_std}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PoseNoise:
        """Rebuild the noise model from `to_dict`'s output (e.g. read from a manifest)."""
        return cls(position_std=data["position_std"], yaw_std=data["yaw_std"])


def parse_pose_noise(text: str) -> PoseNoise:
    """Parse the command line's ``POS_M,YAW_DEG`` form, e.g. ``"0.003,1"``.

    Args:
        text: Position standard deviation in metres and yaw standard deviation in degrees,
            separated by a comma.

    Returns:
        The noise model (yaw converted to radians).

    Raises:
        InputError: Naming ``--pose-noise`` and the expected form.
    """
    if not isinstance(text, str):
        raise InputError(f"--pose-noise must be POS_M,YAW_DEG text (e.g. '0.003,1'), got {text!r}.")
    parts = text.split(",")
    try:
        if len(parts) != 2:
            raise ValueError
        position, yaw_deg = (float(p) for p in parts)
    except ValueError:
        raise InputError(
            f"--pose-noise must be POS_M,YAW_DEG (e.g. 0.003,1), got {text!r}."
        ) from None
    if not (math.isfinite(position) and math.isfinite(yaw_deg)) or position < 0 or yaw_deg < 0:
        raise InputError(
            f"--pose-noise needs two finite numbers >= 0 (metres, degrees), got {text!r}."
        )
    return PoseNoise(position_std=position, yaw_std=math.radians(yaw_deg))


def observe_poses(
    noise: PoseNoise,
    before: np.ndarray,
    after: np.ndarray,
    push_yaw: np.ndarray,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Measure the poses before and after N pushes with independent noise, and their effects.

    The draws take one ``(N, 2, K, 3)`` block of standard normals from `rng`, so the result
    depends only on `rng`'s state and the shapes, never on the poses.

    Args:
        noise: The measurement noise.
        before: (N, K, 3) true world ``(x, y, theta)`` before each push (m, m, rad).
        after: (N, K, 3) true world ``(x, y, theta)`` after each push (theta unwrapped).
        push_yaw: (N,) world yaw of each push's z_p axis (rad).
        rng: Source of the noise, separate from the physics'.

    Returns:
        ``(observed_before, observed_after, observed_effect)``: the noisy (N, K, 3) world poses
        and the (N, K, 3) ``(Delta y_p, Delta z_p, Delta theta_p)`` between them in each push's
        pushing frame (m, m, rad).

    Raises:
        InputError: For a `noise` that is not a `PoseNoise`, poses or yaws that are not finite
            numbers of these shapes, or an `rng` that is not a `numpy.random.Generator`.
    """
    if not isinstance(noise, PoseNoise):
        raise InputError(
            f"noise must be a PoseNoise (e.g. parse_pose_noise('0.003,1')), got "
            f"{type(noise).__name__}."
        )
    before = as_float_array("before", before)
    check_shape("before", before, (None, None, 3))
    check_finite("before", before)
    after = as_float_array("after", after)
    check_shape("after", after, before.shape)
    check_finite("after", after)
    yaws = as_float_array("push_yaw", push_yaw)
    check_shape("push_yaw", yaws, (len(before),))
    check_finite("push_yaw", yaws)
    rng = check_rng(rng)
    scale = np.array([noise.position_std, noise.position_std, noise.yaw_std])
    eps = rng.standard_normal((len(before), 2, *before.shape[1:])) * scale
    obs_before, obs_after = before + eps[:, 0], after + eps[:, 1]
    effect = np.array(
        [
            push_frame_effect(b, a, float(y))
            for b, a, y in zip(obs_before, obs_after, yaws, strict=True)
        ]
    )
    return obs_before, obs_after, effect.reshape(before.shape)
