r"""A hand that tracks a commanded planar path (pymunk): stiffly, or through an impedance.

The hand is a dynamic body that follows a kinematic "control" body, the commanded pose, in one
of two modes (`HandSpec.mode`):

* ``"stiff"``: a pivot joint and a gear joint whose force and torque are limited drag the hand
  onto the commanded pose, as a high-gain position controller does. The hand keeps within
  about 0.5 mm of its command until the force limit is reached; against an immovable obstacle
  it stalls instead of tunnelling or exploding.
* ``"compliant"``: a Cartesian impedance, as a torque-controlled arm (KUKA LWR / LBR iiwa,
  Franka Emika) runs at its flange. Every physics step the hand receives

  .. math::

      F = \operatorname{clip}_{F_{max}}\big(K (x_c - x) + D (\dot x_c - \dot x)
          + m \ddot x_c\big),

  a spring-damper between the command :math:`x_c` and the hand :math:`x` with the
  commanded acceleration fed forward, its magnitude limited as a real controller's is. The
  weight of the hand (and of any `compensated_mass` it carries) is compensated, as an arm's
  controller compensates its own and its gripper's gravity; a held load is not. Pushing a
  resisting object the hand lags its command by about ``F / K`` and deflects sideways;
  against a blocked one it stalls at the force limit while the command moves on. That
  deviation is the reaction chapter 6's backward component models. The hand's heading
  follows its command through the torque-limited gear joint in both modes (the hand body's
  small moment of inertia would make a rotational spring of useful stiffness unstable at the
  physics step).

Numbers (``worlds/tabletop.yaml`` and ``worlds/sideview.yaml``, section ``hand``). A Cartesian
impedance controller is typically set to a translational stiffness of a few hundred to about
2000 N/m: KUKA's LBR iiwa Cartesian impedance mode accepts 0-5000 N/m and starts from
2000 N/m (KUKA Sunrise.OS, ``CartesianImpedanceControlMode``); Franka Emika's example
Cartesian impedance controller uses 200 N/m, adjustable to 400 N/m (franka_ros,
``cartesian_impedance_example_controller``); the DLR/KUKA LWR's Cartesian impedance is set in
the same 100-5000 N/m band (Albu-Schaeffer et al., "The DLR lightweight robot", Industrial
Robot 34(5), 2007). Damping is set near critical, ``D = 2 zeta sqrt(K m)`` with zeta about
0.7 to 1. The force these controllers apply is limited to tens of newtons (the iiwa's
``setMaxControlForce`` and the Franka's contact thresholds are commonly set at 20-50 N, well
under the ISO/TS 15066 transient contact limits of the hand region, 140 N and more). The
worlds use K = 2000 N/m, zeta = 0.7 and the stiff mode's force limit (40 N on the tabletop,
80 N in the side view).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, fields, replace
from typing import Any, Self

import numpy as np
import pymunk

from probaff._checks import check_finite, check_positive, check_shape
from probaff.errors import ConfigError, InputError
from probaff.sim import world_files as wf

__all__ = [
    "HAND_MODES",
    "HAND_WORLDS",
    "HandSpec",
    "HandWorldSpec",
    "TrackedPusher",
    "check_hand_world",
    "read_hand",
]

HAND_MODES = ("stiff", "compliant")
"""How the hand follows its command: a stiff tracking constraint or a Cartesian impedance."""
HAND_WORLDS = ("tabletop", "sideview")
"""The world kinds whose arm carries a `TrackedPusher` hand, so that `HandSpec` applies."""


def check_hand_world(world_kind: str, setting: str = "hand") -> None:
    """Raise `InputError` unless a hand setting applies to worlds of kind `world_kind`.

    Args:
        world_kind: A registered world kind's name (``"tabletop"``, ``"warehouse"``, ...).
        setting: The setting's name, for the message.
    """
    if world_kind not in HAND_WORLDS:
        raise InputError(
            f"{setting} applies to the worlds with an arm's hand, {list(HAND_WORLDS)}; a "
            f"{world_kind} world has none (its robot moves boxes cell by cell): leave {setting} "
            "unset for it."
        )


@dataclass(frozen=True)
class HandSpec:
    """How the hand follows its commanded pose (the ``hand`` section of a world file).

    Attributes:
        mode: ``"stiff"`` (force-limited tracking constraint, the hand within about 0.5 mm of
            its command) or ``"compliant"`` (Cartesian impedance with the values below).
        stiffness_n_per_m: Translational stiffness K (N/m) of the compliant hand.
        damping_n_s_per_m: Translational damping D (N s/m).
        force_limit_n: Largest force (N) the compliant hand's controller applies.
        reaction_samples: Points at which a push records the hand's deviation from its
            command, evenly spaced in time over the push (an integer >= 2).

    Raises:
        InputError: Naming the field, for an unknown mode, a stiffness, damping or limit that
            is not a finite number > 0, or a sample count that is not an integer >= 2.
    """

    mode: str = "stiff"
    stiffness_n_per_m: float = 2000.0
    damping_n_s_per_m: float = 63.0
    force_limit_n: float = 40.0
    reaction_samples: int = 16

    def __post_init__(self) -> None:
        if not isinstance(self.mode, str) or self.mode not in HAND_MODES:
            raise InputError(
                f"hand.mode must be one of {list(HAND_MODES)}, got {self.mode!r}; set "
                "hand.mode in the world file (worlds/tabletop.yaml or worlds/sideview.yaml)."
            )
        for f in fields(self):
            if f.name in ("mode", "reaction_samples"):
                continue
            value = getattr(self, f.name)
            if isinstance(value, bool):
                raise InputError(f"hand.{f.name} must be a number, got {value!r}.")
            try:
                check_positive(f"hand.{f.name}", value)
            except InputError as exc:
                raise InputError(
                    f"{exc} Give the hand's {f.name.replace('_', ' ')} as a positive finite "
                    "number in the world file's hand section."
                ) from None
            object.__setattr__(self, f.name, float(value))
        n = self.reaction_samples
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 2:
            raise InputError(
                f"hand.reaction_samples must be an integer >= 2 (points along the push), got {n!r}."
            )
        object.__setattr__(self, "reaction_samples", int(n))

    @property
    def compliant(self) -> bool:
        """Whether the hand follows its command through the impedance."""
        return self.mode == "compliant"

    def with_mode(self, mode: str) -> HandSpec:
        """The same values with another `mode` (validated)."""
        return replace(self, mode=mode)

    def check_stable(self, where: str, mass: float, dt: float) -> None:
        """Raise `InputError` unless the compliant hand integrates stably at physics step `dt`.

        The impedance is integrated explicitly, one step of `dt` s on a hand of `mass` kg: it
        stays stable (with margin) while ``K dt^2 / m < 1`` and ``D dt / m < 1``.

        Args:
            where: The world file, for the message.
            mass: The hand's mass (kg).
            dt: The physics step (s).
        """
        if not self.compliant:
            return
        spring = self.stiffness_n_per_m * dt * dt / mass
        damper = self.damping_n_s_per_m * dt / mass
        if spring >= 1.0 or damper >= 1.0:
            raise InputError(
                f"{where}: hand.stiffness_n_per_m {self.stiffness_n_per_m:g} and "
                f"hand.damping_n_s_per_m {self.damping_n_s_per_m:g} are too stiff for a "
                f"{mass:g} kg hand at a {1000 * dt:.3g} ms physics step (K dt^2/m = "
                f"{spring:.2f}, D dt/m = {damper:.2f}; both must be < 1): lower them or raise "
                "physics.substeps."
            )

    def to_dict(self) -> dict[str, Any]:
        """Every field by name (what a dataset's ``meta["hand"]`` records)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


class HandWorldSpec:
    """What the world specs whose arm carries a `TrackedPusher` hand share: their ``hand``.

    A frozen dataclass that derives from it has a `HandSpec` field ``hand`` and calls
    `check_hand` from its ``__post_init__``.
    """

    hand: HandSpec

    def check_hand(self, world: str, hand_mass: float, control_rate: float, substeps: int) -> None:
        """Check that ``hand`` is a `HandSpec` that integrates stably at the physics step.

        Args:
            world: The world, for the message (e.g. ``"tabletop world"``).
            hand_mass: The mass (kg) the hand's controller moves.
            control_rate: The physics' control rate (Hz).
            substeps: Physics steps per control step.

        Raises:
            ConfigError: If ``hand`` is not a `HandSpec`.
            InputError: If the compliant hand would not integrate stably
                (`HandSpec.check_stable`).
        """
        if not isinstance(self.hand, HandSpec):
            raise ConfigError(
                f"{type(self).__name__}.hand must be a HandSpec, got {type(self.hand).__name__}."
            )
        dt = 1.0 / (control_rate * substeps)
        self.hand.check_stable(world, hand_mass, dt)

    def with_hand(self, mode: str) -> Self:
        """This world with its hand in `mode` (``"stiff"`` or ``"compliant"``).

        Raises:
            InputError: For an unknown mode.
        """
        return replace(self, hand=self.hand.with_mode(mode))  # type: ignore[type-var]


def read_hand(where: str, raw: Any) -> HandSpec:
    """The hand of a world file's ``hand`` section (`HandSpec`; stiff when it is absent).

    Args:
        where: The section's name, ``"FILE:hand"``.
        raw: The parsed section, or ``None``.

    Raises:
        ConfigError: If the section is not a mapping or has an unknown field.
        InputError: Naming `where` and the field, for a value `HandSpec` refuses.
    """
    if raw is None:
        return HandSpec()
    table = wf.mapping(where, raw)
    wf.no_extra(where, table, {f.name for f in fields(HandSpec)})
    try:
        return HandSpec(**table)
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None


def _clip(vec: tuple[float, float], limit: float) -> tuple[float, float]:
    norm = math.hypot(*vec)
    if norm <= limit:
        return vec
    return (vec[0] * limit / norm, vec[1] * limit / norm)


class TrackedPusher:
    """A hand body driven along commanded poses, stiffly or through an impedance.

    Args:
        space: The pymunk space.
        pose: Initial world ``(x, y, yaw)`` (in the side view, ``(x, z, phi)``).
        mass: Hand mass (kg).
        moment: Hand moment of inertia (kg m^2).
        make_shapes: ``make_shapes(body)`` creates the hand's collision shapes on its body.
        max_force: Force limit of the stiff tracking controller (N).
        max_torque: Torque limit of the heading controller, in both modes (N m).
        max_speed: Fastest correction of a tracking error by the stiff controller (m/s).
        max_spin: Fastest correction of a heading error (rad/s).
        hand: How the hand follows its command (``HandSpec()``, stiff, if ``None``).
        compensated_mass: Mass (kg) carried by the hand, besides its own, whose weight the
            compliant controller compensates (e.g. the fingers), >= 0.

    Raises:
        InputError: For a non-finite (3,) `pose`, a mass, moment, limit or speed that is not
            a finite number > 0, a `hand` that is not a `HandSpec` or a negative
            `compensated_mass`, before anything is added to `space`.
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
        *,
        hand: HandSpec | None = None,
        compensated_mass: float = 0.0,
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
        check_positive("compensated_mass", compensated_mass, allow_zero=True)
        if hand is None:
            hand = HandSpec()
        if not isinstance(hand, HandSpec):
            raise InputError(
                f"hand must be a probaff.sim.pusher.HandSpec, got {type(hand).__name__}; build "
                "one with HandSpec(mode='compliant', ...) or load it from a world file."
            )
        self.hand = hand
        self.control = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        self.control.position = (float(pose[0]), float(pose[1]))
        self.control.angle = float(pose[2])
        self.body = pymunk.Body(mass, moment)
        self.body.position, self.body.angle = self.control.position, self.control.angle
        self.shapes = make_shapes(self.body)
        self._feedforward = (0.0, 0.0)
        self._weight_share = (float(mass) + float(compensated_mass)) / float(mass)
        gear = pymunk.GearJoint(self.control, self.body, 0.0, 1.0)
        gear.max_force, gear.max_bias = max_torque, max_spin
        if hand.compliant:
            self.body.velocity_func = self._impedance
            space.add(self.control, self.body, *self.shapes, gear)
            return
        pivot = pymunk.PivotJoint(self.control, self.body, (0.0, 0.0), (0.0, 0.0))
        pivot.max_force, pivot.max_bias = max_force, max_speed
        space.add(self.control, self.body, *self.shapes, pivot, gear)

    def _impedance(
        self, body: pymunk.Body, gravity: tuple[float, float], damping: float, dt: float
    ) -> None:
        """The compliant hand's pymunk ``velocity_func``: the impedance force, then Euler."""
        h, c = self.hand, self.control
        ex, ey = c.position.x - body.position.x, c.position.y - body.position.y
        dvx, dvy = c.velocity.x - body.velocity.x, c.velocity.y - body.velocity.y
        m = body.mass
        # the controller compensates the weight of the hand and what it carries; gravity
        # itself is integrated by pymunk below, so the compensation is an opposing force
        fx = h.stiffness_n_per_m * ex + h.damping_n_s_per_m * dvx + m * self._feedforward[0]
        fy = h.stiffness_n_per_m * ey + h.damping_n_s_per_m * dvy + m * self._feedforward[1]
        fx, fy = _clip((fx, fy), h.force_limit_n)
        gx, gy = gravity
        share = self._weight_share
        body.force = (fx - share * m * gx, fy - share * m * gy)
        pymunk.Body.update_velocity(body, gravity, damping, dt)

    def command(self, now: np.ndarray, nxt: np.ndarray, rate: float) -> None:
        """Command a move from pose `now` to pose `nxt` over one control tick of 1/`rate` s.

        Args:
            now: (3,) world ``(x, y, yaw)`` at the start of the tick.
            nxt: (3,) world ``(x, y, yaw)`` at its end.
            rate: Control rate (Hz).
        """
        old = self.control.velocity
        self.control.position = (float(now[0]), float(now[1]))
        self.control.angle = float(now[2])
        vx, vy = float(nxt[0] - now[0]) * rate, float(nxt[1] - now[1]) * rate
        self.control.velocity = (vx, vy)
        self.control.angular_velocity = float(nxt[2] - now[2]) * rate
        self._feedforward = ((vx - old.x) * rate, (vy - old.y) * rate)

    def lag(self, target: np.ndarray) -> float:
        """Distance (m) between the hand and a commanded position (2,)."""
        return float(np.hypot(self.body.position.x - target[0], self.body.position.y - target[1]))

    def deviation(self) -> tuple[float, float, float]:
        """The hand's pose minus its commanded pose now: world ``(dx, dy, dyaw)``."""
        b, c = self.body, self.control
        return (b.position.x - c.position.x, b.position.y - c.position.y, b.angle - c.angle)
