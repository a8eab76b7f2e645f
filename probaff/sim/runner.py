"""Run batches of pushes: draw scenes, solve the arm's IK for all of them at once, simulate."""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import torch

from probaff._checks import check_count, check_finite, check_positive, check_shape
from probaff.errors import ConfigError, InputError, UnreachablePoseError
from probaff.sim.arm import Arm, load_arm
from probaff.sim.inputs import check_items, check_rng, check_type, floats
from probaff.sim.sampling import sample_scene
from probaff.sim.specs import load_catalogue
from probaff.sim.tabletop import PushOutcome, SceneInstance, simulate_push
from probaff.sim.tabletop_config import (
    SceneSpec,
    TabletopSpec,
    list_scenes,
    load_scene,
    load_tabletop,
)

__all__ = ["PushSample", "PushSimulator", "straight_path", "trapezoid_progress"]

_MAX_DRAWS_PER_SAMPLE = 200


def _check_number(name: str, value: object) -> None:
    """Raise `InputError` unless `value` is a finite number > 0 (not a string or a bool)."""
    if isinstance(value, (bool, str, bytes)):
        raise InputError(f"{name} must be a finite number > 0, got {value!r}.")
    check_positive(name, value)  # type: ignore[arg-type]


def trapezoid_progress(
    distance: float, speed: float, acceleration: float, rate: float
) -> np.ndarray:
    """Fraction of a straight move covered at each control tick, with a trapezoidal speed.

    The speed ramps up at constant acceleration, cruises and ramps down, as an arm's
    controller moves; a push thus ends smoothly.

    Args:
        distance: Path length (m).
        speed: Cruising speed (m/s).
        acceleration: Acceleration and deceleration (m/s^2).
        rate: Control rate (Hz).

    Returns:
        (T,) progress in [0, 1], 0 at the first tick and 1 at the last.

    Raises:
        InputError: If any argument is not a finite number > 0.
    """
    for name, value in (
        ("distance", distance),
        ("speed", speed),
        ("acceleration", acceleration),
        ("rate", rate),
    ):
        _check_number(name, value)
    distance, speed, acceleration, rate = (
        float(distance),
        float(speed),
        float(acceleration),
        float(rate),
    )
    t_ramp = speed / acceleration
    if acceleration * t_ramp**2 > distance:  # too short to reach cruising speed
        t_ramp = math.sqrt(distance / acceleration)
        speed = acceleration * t_ramp
    d_ramp = 0.5 * acceleration * t_ramp**2
    total = 2 * t_ramp + (distance - 2 * d_ramp) / speed
    t = np.linspace(0.0, total, max(2, math.ceil(total * rate) + 1))
    s = np.where(
        t < t_ramp,
        0.5 * acceleration * t**2,
        np.where(
            t < total - t_ramp,
            d_ramp + speed * (t - t_ramp),
            distance - 0.5 * acceleration * (total - t) ** 2,
        ),
    )
    return s / distance


def straight_path(
    world: TabletopSpec, start_xy: np.ndarray, yaw: float, distance: float
) -> np.ndarray:
    """An ideal straight hand path with the world's speed profile, without the arm.

    `PushSimulator` commands the FK of the arm's joint trajectory instead; this ideal path
    isolates the physics (for analytic checks) and serves hands not mounted on this arm.

    Args:
        world: The tabletop world (speed, acceleration, control rate).
        start_xy: (2,) world start of the hand (m).
        yaw: World yaw of the push direction z_p (rad).
        distance: Push length d_p (m).

    Returns:
        (T_c, 3) world ``(x, y, yaw)`` of the hand per control tick.

    Raises:
        InputError: For a world that is not a `TabletopSpec`, a start that is not a finite
            (2,) point, a yaw that is not finite or a distance that is not > 0.
    """
    check_type("world", world, TabletopSpec, "load_tabletop()")
    start_xy = floats("start_xy", start_xy)
    check_shape("start_xy", start_xy, (2,))
    check_finite("start_xy", start_xy)
    yaw_arr = floats("yaw", yaw)
    check_shape("yaw", yaw_arr, ())
    check_finite("yaw", yaw_arr)
    yaw = float(yaw_arr)
    _check_number("distance", distance)
    distance = float(distance)
    s = distance * trapezoid_progress(
        distance, world.push_speed, world.push_acceleration, world.physics.control_rate
    )
    return np.stack(
        [start_xy[0] + s * math.cos(yaw), start_xy[1] + s * math.sin(yaw), np.full_like(s, yaw)],
        axis=-1,
    )


@dataclass(frozen=True)
class PushSample:
    """One simulated push.

    Attributes:
        scene: The drawn scene and push.
        outcome: What happened.
        q_waypoints: (K, dof) the arm's joint waypoints along the push (rad).
    """

    scene: SceneInstance
    outcome: PushOutcome
    q_waypoints: np.ndarray


class PushSimulator:
    """Draws and simulates pushes of one scene template.

    Args:
        scene: A scene name (``worlds/scenes/NAME.yaml``) or a loaded template.
        world: The tabletop world; defaults to ``worlds/tabletop.yaml``.

    Example:
        Two pushes of chapter 5's two-object scene, in memory:

        >>> import numpy as np
        >>> from probaff.sim import PushSimulator
        >>> sim = PushSimulator("two_objects")
        >>> samples = list(sim.run(2, np.random.default_rng(0)))  # drawn, then simulated
        >>> [o.name for o in samples[0].scene.objects]
        ['wood_block', 'nut_container']
        >>> samples[0].outcome.effect.shape  # per object: pushing-frame (y_p, z_p, theta)
        (2, 3)
    """

    def __init__(self, scene: str | SceneSpec, world: TabletopSpec | None = None) -> None:
        if not isinstance(scene, (str, SceneSpec)):
            raise InputError(
                f"scene must be a scene name (one of {list_scenes()}) or a SceneSpec, got "
                f"{type(scene).__name__}."
            )
        if world is not None and not isinstance(world, TabletopSpec):
            raise InputError(
                f"world must be a TabletopSpec (load_tabletop()) or None, got "
                f"{type(world).__name__}."
            )
        self.scene = load_scene(scene) if isinstance(scene, str) else scene
        self.world = world or load_tabletop()
        self.catalogue = load_catalogue()
        self.arm: Arm = load_arm(self.world.arm)
        self.progress = torch.as_tensor(
            trapezoid_progress(
                self.scene.push.distance,
                self.world.push_speed,
                self.world.push_acceleration,
                self.world.physics.control_rate,
            )
        )

    def hand_paths(self, scenes: list[SceneInstance]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Solve IK for a batch of pushes and trace the hand along each.

        Args:
            scenes: B drawn scenes.

        Returns:
            ``(ok, q, path)``: ok (B,) bool reachability; q (B, K, dof) joint waypoints;
            path (B, T_c, 3) commanded world ``(x, y, yaw)`` of the hand per control tick.
        """
        xy = torch.tensor(np.array([s.push_origin for s in scenes]), dtype=torch.float64)
        yaw = torch.tensor([s.push_yaw for s in scenes], dtype=torch.float64)
        sol = self.arm.solve_pushes(xy, yaw, self.scene.push.distance)
        path = self.arm.trace(sol.q, self.progress)
        return sol.ok.numpy(), sol.q.numpy(), path.numpy()

    def execute(self, scenes: list[SceneInstance]) -> list[PushSample]:
        """Simulate given pushes (e.g. chosen by a planner) with the arm.

        Args:
            scenes: Pushes to run; each push's start and path must be reachable.

        Returns:
            One sample per scene, in order.

        Raises:
            InputError: If `scenes` is not a non-empty list of `SceneInstance`, or one holds
                an invalid push start, yaw or physical parameter (named by its index).
            UnreachablePoseError: Naming the first push the arm cannot execute.
        """
        how = "see sample_scene or SceneInstance.nominal"
        for i, s in enumerate(check_items("scenes", scenes, SceneInstance, how)):
            check_shape(f"scenes[{i}].push_origin", s.push_origin, (2,))
            check_finite(f"scenes[{i}].push_origin (the push start)", s.push_origin)
            check_finite(f"scenes[{i}].push_yaw", s.push_yaw)
            s.validate()
            try:
                s.check_on_table(self.world)
            except InputError as exc:
                raise InputError(f"scenes[{i}]: {exc}") from None
        ok, q, path = self.hand_paths(list(scenes))
        if not ok.all():
            i = int(np.flatnonzero(~ok)[0])
            x, y = scenes[i].push_origin
            raise UnreachablePoseError(
                f"push {i} (start x={x:.3f}, y={y:.3f}, yaw={scenes[i].push_yaw:.3f}, "
                f"d_p={self.scene.push.distance} m) leaves the arm's reachable workspace; "
                "start it closer to the arm or push towards it (see Arm.reachable_mask())."
            )
        return [
            PushSample(s, simulate_push(self.world, s, path[i]), q[i]) for i, s in enumerate(scenes)
        ]

    def run(self, n: int, rng: np.random.Generator) -> Iterator[PushSample]:
        """Draw and simulate `n` valid, reachable pushes.

        Candidates are drawn in batches; those that are physically invalid or unreachable by
        the arm are discarded, so the result depends only on `rng`'s state.

        Args:
            n: Number of pushes (an integer >= 0).
            rng: Source of randomness.

        Returns:
            An iterator over `n` samples, in order; `n` and `rng` are checked at once, the
            pushes are drawn and simulated as it is consumed.

        Raises:
            InputError: At the call, if `n` is not an integer >= 0 or `rng` is not a
                `numpy.random.Generator`.
            ConfigError: If valid, reachable pushes are too rare to draw.
        """
        n = check_count("n", n, minimum=0)  # here, not when the first sample is asked for
        return self._run(n, check_rng(rng))

    def _run(self, n: int, rng: np.random.Generator) -> Iterator[PushSample]:
        """The generator behind `run`, for a validated `n`."""
        done, draws = 0, 0
        while done < n:
            want = n - done
            batch: list[SceneInstance] = []
            while len(batch) < math.ceil(1.3 * want) + 2:
                draws += 1
                if draws > _MAX_DRAWS_PER_SAMPLE * (n + 1):
                    raise ConfigError(
                        f"scene {self.scene.name!r}: fewer than 1 in {_MAX_DRAWS_PER_SAMPLE} draws "
                        "gives a valid, reachable push; widen its ranges or move its objects "
                        "towards the arm."
                    )
                s = sample_scene(self.scene, self.catalogue, self.world, rng)
                if s is not None:
                    batch.append(s)
            ok, q, path = self.hand_paths(batch)
            for i in np.flatnonzero(ok)[:want]:
                yield PushSample(batch[i], simulate_push(self.world, batch[i], path[i]), q[i])
                done += 1
