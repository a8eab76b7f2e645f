"""The robot arm: a URDF chain in pytorch-kinematics with batched inverse kinematics.

Every gripper pose the simulator commands is reached through IK on this chain; the physics then
tracks the forward kinematics of the resulting joint trajectory. Poses outside the reachable
workspace are refused with `UnreachablePoseError`.

Frames: ``world`` (table centre on its surface, z up), ``base`` (the arm's base link) and ``tcp``
(tool centre point between the fingertips; z out of the gripper, y joining the fingers). For a
push, the tcp points straight down and its x axis is the push direction z_p.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
import torch

from probaff._checks import as_real_tensor, check_count, check_finite, check_number, check_shape
from probaff.errors import ConfigError, InputError, UnreachablePoseError
from probaff.sim.specs import ArmSpec

__all__ = [
    "Arm",
    "IKResult",
    "PathIK",
    "PushPathIK",
    "load_arm",
    "sideview_pose",
    "topdown_pose",
]

_DTYPE = torch.float64
# Elbow/wrist postures that hold the tool vertical over the table; the pan joint of each seed is
# aimed at the target, so three seeds per pose suffice.
_POSTURES = ((-1.5, 1.8, -1.9), (-1.0, 1.5, -2.1), (-2.0, 2.0, -1.6))
_MAX_JOINT_STEP = 0.6  # rad between consecutive waypoints; more means an IK branch flip


def _interval(name: str, value: Any) -> tuple[float, float]:
    """`value` as a ``(low, high)`` pair of finite numbers, low < high, or `InputError`."""
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence) or len(value) != 2:
        raise InputError(f"{name} must be a (low, high) pair of numbers (m), got {value!r}.")
    low, high = (check_number(name, v, unit="m") for v in value)
    if not low < high:
        raise InputError(f"{name} must rise from low to high, got {value!r}.")
    return low, high


def topdown_pose(xy: torch.Tensor, yaw: torch.Tensor, height: float) -> torch.Tensor:
    """Tool poses pointing straight down with the tool x axis at `yaw`.

    Args:
        xy: (B, 2) tcp positions in the world frame (m).
        yaw: (B,) world yaw of the tool x axis (the push direction z_p), rad.
        height: tcp height above the table (m).

    Returns:
        T_world_tcp: (B, 4, 4).
    """
    c, s = torch.cos(yaw), torch.sin(yaw)
    T = torch.zeros(xy.shape[0], 4, 4, dtype=_DTYPE)
    T[:, 0, 0], T[:, 1, 0] = c, s
    T[:, 0, 1], T[:, 1, 1] = s, -c
    T[:, 2, 2] = -1.0
    T[:, 0, 3], T[:, 1, 3], T[:, 2, 3] = xy[:, 0], xy[:, 1], height
    T[:, 3, 3] = 1.0
    return T


def sideview_pose(xz: torch.Tensor, phi: torch.Tensor, plane_y: float) -> torch.Tensor:
    """Tool poses in the side-view plane: tool z down (at phi = 0), fingers closing along x.

    The plane is world x-z at ``y = plane_y``; phi is the counter-clockwise rotation in it as
    seen from -y. At phi = 0 the tool z axis is world -z, its y axis (joining the fingers) is
    world +x and its x axis world +y; phi turns tool y to ``(cos phi, 0, sin phi)``.

    Args:
        xz: (B, 2) world ``(x, z)`` of the tcp (m).
        phi: (B,) rotation about the viewing axis (rad).
        plane_y: World y of the plane (m).

    Returns:
        T_world_tcp: (B, 4, 4).
    """
    c, s = torch.cos(phi), torch.sin(phi)
    T = torch.zeros(xz.shape[0], 4, 4, dtype=_DTYPE)
    T[:, 1, 0] = 1.0
    T[:, 0, 1], T[:, 2, 1] = c, s
    T[:, 0, 2], T[:, 2, 2] = s, -c
    T[:, 0, 3], T[:, 1, 3], T[:, 2, 3] = xz[:, 0], plane_y, xz[:, 1]
    T[:, 3, 3] = 1.0
    return T


@dataclass(frozen=True)
class IKResult:
    """Batched IK solutions.

    Attributes:
        q: (B, dof) joint angles (rad); meaningful only where `converged`.
        converged: (B,) whether position and orientation met the tolerances.
        pos_error: (B,) position error of `q` (m).
        rot_error: (B,) orientation error of `q` (rad).
    """

    q: torch.Tensor
    converged: torch.Tensor
    pos_error: torch.Tensor
    rot_error: torch.Tensor


@dataclass(frozen=True)
class PushPathIK:
    """Joint waypoints of straight top-down pushes.

    Attributes:
        q: (B, K, dof) joint angles at K waypoints evenly spaced along each push.
        ok: (B,) every waypoint converged and the joint path is continuous.
    """

    q: torch.Tensor
    ok: torch.Tensor


@dataclass(frozen=True)
class PathIK:
    """Joint waypoints of tcp paths in the side-view plane.

    Attributes:
        q: (B, K, dof) joint angles at the K waypoints of each path.
        ok: (B,) every waypoint converged and the joint path is continuous.
        first_bad: (B,) index of the first waypoint that failed, -1 where `ok`.
    """

    q: torch.Tensor
    ok: torch.Tensor
    first_bad: torch.Tensor


class Arm:
    """A serial arm from a URDF, mounted in the world at T_world_base.

    Args:
        spec: URDF path, tcp link, mounting and IK tolerances (from ``worlds/tabletop.yaml``).
    """

    def __init__(self, spec: ArmSpec) -> None:
        self.spec = spec
        try:
            data = spec.urdf.read_bytes()
        except OSError as exc:
            raise ConfigError(
                f"cannot read the arm URDF {spec.urdf} ({exc.strerror or exc}); make arm.urdf in "
                "the world file name an existing URDF file."
            ) from exc
        # imported with the first arm: a second of start-up that a process without one skips
        import pytorch_kinematics as pk

        try:
            chain = pk.build_serial_chain_from_urdf(data, spec.tcp_link)
        except Exception as exc:  # the URDF parser raises many unrelated types
            raise ConfigError(
                f"{spec.urdf.name} is not a valid URDF with a link {spec.tcp_link!r}: {exc}"
            ) from exc
        self.chain = chain.to(dtype=_DTYPE)
        self.dof = len(self.chain.get_joint_parameter_names())
        if self.dof < 6:
            raise ConfigError(f"{spec.urdf.name}: the arm needs >= 6 joints, found {self.dof}.")
        c, s = math.cos(spec.base_yaw), math.sin(spec.base_yaw)
        T = torch.eye(4, dtype=_DTYPE)
        T[:2, :2] = torch.tensor([[c, -s], [s, c]], dtype=_DTYPE)
        T[:3, 3] = torch.tensor(spec.base_xyz, dtype=_DTYPE)
        self.T_world_base = T
        self.T_base_world = torch.linalg.inv(T)

    # -- kinematics -------------------------------------------------------------------------
    def _joints(self, name: str, q: Any, leading: int) -> torch.Tensor:
        """`q` as finite float64 joint angles `(*leading dims, dof)`, or `InputError`."""
        t = as_real_tensor(name, q).to(_DTYPE)
        check_shape(name, t, (*(None,) * leading, self.dof))
        check_finite(name, t)
        return t

    def fk(self, q: torch.Tensor) -> torch.Tensor:
        """Forward kinematics.

        Args:
            q: (B, dof) joint angles.

        Returns:
            T_world_tcp: (B, 4, 4).

        Raises:
            InputError: For `q` that is not finite (B, dof) numbers.
        """
        q = self._joints("q", q, 1)
        T_base_tcp = self.chain.forward_kinematics(q).get_matrix()
        return self.T_world_base @ T_base_tcp

    def planar_fk(self, q: torch.Tensor) -> torch.Tensor:
        """Top-down pose of the tcp, as the planar physics uses it.

        Args:
            q: (B, dof) joint angles.

        Returns:
            (B, 3) world ``(x, y, yaw)`` of the tcp, yaw being that of the tool x axis.
        """
        T = self.fk(q)
        return torch.stack([T[:, 0, 3], T[:, 1, 3], torch.atan2(T[:, 1, 0], T[:, 0, 0])], dim=-1)

    def _seeds(self, T_world_tcp: torch.Tensor) -> torch.Tensor:
        p = (self.T_base_world @ T_world_tcp)[:, :3, 3]
        pan = torch.atan2(p[:, 1], p[:, 0])
        seeds = torch.zeros(p.shape[0], len(_POSTURES), self.dof, dtype=_DTYPE)
        for r, (a, b, c) in enumerate(_POSTURES):
            seeds[:, r, 0] = pan
            seeds[:, r, 1:4] = torch.tensor([a, b, c], dtype=_DTYPE)
            seeds[:, r, 4] = -math.pi / 2
        return seeds

    def ik(self, T_world_tcp: torch.Tensor, seeds: torch.Tensor | None = None) -> IKResult:
        """Batched inverse kinematics (damped least squares, pytorch-kinematics).

        Args:
            T_world_tcp: (B, 4, 4) target tool poses.
            seeds: (B, R, dof) initial joint configurations to try per target; by default three
                tool-down postures aimed at each target.

        Returns:
            The best converged solution per target (the first converged retry).
        """
        check_shape("T_world_tcp", T_world_tcp, (None, 4, 4))
        check_finite("T_world_tcp", T_world_tcp)
        B = T_world_tcp.shape[0]
        if seeds is None:
            seeds = self._seeds(T_world_tcp)
        R = seeds.shape[1]
        import pytorch_kinematics as pk  # already imported by __init__

        solver = pk.PseudoInverseIK(
            self.chain,
            retry_configs=seeds[0],
            max_iterations=self.spec.max_iterations,
            pos_tolerance=self.spec.pos_tolerance,
            rot_tolerance=self.spec.rot_tolerance,
            early_stopping_any_converged=True,
            early_stopping_no_improvement="all",
            enforce_joint_limits=False,
        )
        solver.initial_config = seeds.reshape(B * R, self.dof)
        target = pk.Transform3d(matrix=self.T_base_world @ T_world_tcp, dtype=_DTYPE)
        sol = solver.solve(target)
        q_all = self._wrap_to_limits(sol.solutions)  # (B, R, dof)
        in_limits = ((q_all >= self.chain.low) & (q_all <= self.chain.high)).all(-1)
        conv = sol.converged & in_limits  # (B, R)
        first = torch.where(conv.any(1), conv.to(torch.int8).argmax(1), sol.err_pos.argmin(1))
        idx = torch.arange(B)
        return IKResult(
            q=q_all[idx, first],
            converged=conv.any(1),
            pos_error=sol.err_pos[idx, first],
            rot_error=sol.err_rot[idx, first],
        )

    def _wrap_to_limits(self, q: torch.Tensor) -> torch.Tensor:
        """Shift each joint by a multiple of 2 pi towards the middle of its limits."""
        mid = 0.5 * (self.chain.low + self.chain.high)
        return q - 2 * math.pi * torch.round((q - mid) / (2 * math.pi))

    # -- pushes -----------------------------------------------------------------------------
    def waypoint_count(self, distance: float) -> int:
        """Number of IK waypoints (ends included) along a push of `distance` metres."""
        return max(2, math.ceil(distance / self.spec.waypoint_spacing) + 1)

    def solve_pushes(
        self, start_xy: torch.Tensor, yaw: torch.Tensor, distance: float
    ) -> PushPathIK:
        """IK for straight top-down pushes, batched over pushes.

        The start poses are solved from the default seeds; each later waypoint is solved for all
        pushes at once, seeded with the previous waypoint's solution, which keeps a push on one
        IK branch and converges in a few iterations.

        Args:
            start_xy: (B, 2) world tcp positions where the pushes start (m).
            yaw: (B,) world yaw of each push direction z_p (rad).
            distance: Push length d_p along z_p (m).

        Returns:
            Joint waypoints (B, K, dof) and a per-push success flag.
        """
        check_shape("start_xy", start_xy, (None, 2))
        check_shape("yaw", yaw, (start_xy.shape[0],))
        start_xy, yaw = start_xy.to(_DTYPE), yaw.to(_DTYPE)
        B, K, h = start_xy.shape[0], self.waypoint_count(distance), self.spec.push_height
        if B == 0:
            return PushPathIK(
                torch.zeros(0, K, self.dof, dtype=_DTYPE), torch.zeros(0, dtype=torch.bool)
            )
        start = self.ik(topdown_pose(start_xy, yaw, h))
        s = torch.linspace(0.0, distance, K, dtype=_DTYPE)
        d = torch.stack([torch.cos(yaw), torch.sin(yaw)], dim=-1)  # (B, 2)
        q = start.q[:, None, :].repeat(1, K, 1)
        ok = start.converged.clone()
        for k in range(1, K):
            rows = ok.nonzero()[:, 0]
            if rows.numel() == 0:
                break
            nxt = self.ik(
                topdown_pose(start_xy[rows] + s[k] * d[rows], yaw[rows], h),
                q[rows, k - 1][:, None, :],
            )
            q[rows, k] = nxt.q
            ok[rows] = nxt.converged
        jump = (q[:, 1:] - q[:, :-1]).abs().amax(dim=(1, 2))
        return PushPathIK(q=q, ok=ok & (jump < _MAX_JOINT_STEP))

    def _waypoints(self, q_waypoints: Any) -> torch.Tensor:
        """`q_waypoints` as finite (B, K >= 2, dof) joint angles, or `InputError`."""
        q = self._joints("q_waypoints", q_waypoints, 2)
        if q.shape[1] < 2:
            raise InputError(
                f"q_waypoints holds {q.shape[1]} waypoint(s) per path; give 2 or more."
            )
        return q

    def trace(self, q_waypoints: torch.Tensor, progress: torch.Tensor) -> torch.Tensor:
        """Map a joint-space linear interpolation of waypoints through FK.

        Args:
            q_waypoints: (B, K, dof) waypoints, evenly spaced along each push.
            progress: (T,) fraction of the path covered at each control tick, from 0 to 1.

        Returns:
            (B, T, 3) world ``(x, y, yaw)`` of the tcp at each control tick.

        Raises:
            InputError: For waypoints that are not finite (B, K >= 2, dof) numbers, or
                `progress` that is not finite (T,) numbers.
        """
        q_waypoints = self._waypoints(q_waypoints)
        B, K, dof = q_waypoints.shape
        progress = as_real_tensor("progress", progress).to(_DTYPE)
        check_shape("progress", progress, (None,))
        check_finite("progress", progress)
        u = progress.clamp(0.0, 1.0) * (K - 1)
        i0 = u.floor().clamp(max=K - 2).long()
        frac = (u - i0)[None, :, None]
        q = q_waypoints[:, i0] * (1 - frac) + q_waypoints[:, i0 + 1] * frac  # (B, T, dof)
        return self.planar_fk(q.reshape(-1, dof)).reshape(B, len(progress), 3)

    # -- side view --------------------------------------------------------------------------
    def sideview_fk(self, q: torch.Tensor) -> torch.Tensor:
        """Pose of the tcp in the side-view plane, as the plane physics uses it.

        Args:
            q: (B, dof) joint angles.

        Returns:
            (B, 3) world ``(x, z, phi)`` of the tcp (see `sideview_pose`).
        """
        T = self.fk(q)
        return torch.stack([T[:, 0, 3], T[:, 2, 3], torch.atan2(T[:, 2, 1], T[:, 0, 1])], dim=-1)

    def _sideview_seed(self, plane_y: float) -> torch.Tensor:
        """(dof,) a tool-down posture in the plane (pan relative to the target direction)."""
        return _sideview_seed_cached(self, float(plane_y))

    def solve_sideview_paths(self, xz: torch.Tensor, plane_y: float) -> PathIK:
        """IK for tcp paths in the side-view plane, with the tool at phi = 0.

        All waypoints of all paths are solved in one batched call, each seeded with a side-view
        posture aimed at its target, which keeps a path on one IK branch; waypoints where that
        fails are retried, in one more call, from the default seeds. A path with a failed or
        discontinuous waypoint is then solved again waypoint by waypoint, each seeded with the
        previous solution.

        Args:
            xz: (B, K, 2) world ``(x, z)`` of the tcp at K waypoints per path (m), K >= 2.
            plane_y: World y of the plane (m).

        Returns:
            Joint waypoints (B, K, dof), per-path success and the first failed waypoint.

        Raises:
            InputError: If `xz` is not a finite (B, K, 2) array with K >= 2.
        """
        check_shape("xz", xz, (None, None, 2))
        check_finite("xz", xz)
        B, K = xz.shape[0], xz.shape[1]
        if K < 2:
            raise InputError(f"xz holds {K} waypoint(s) per path; give at least 2.")
        xz = xz.to(_DTYPE)
        if B == 0:
            return PathIK(
                torch.zeros(0, K, self.dof, dtype=_DTYPE),
                torch.zeros(0, dtype=torch.bool),
                torch.zeros(0, dtype=torch.long),
            )
        flat = xz.reshape(B * K, 2)
        T = sideview_pose(flat, torch.zeros(B * K, dtype=_DTYPE), plane_y)
        default = self._seeds(T)
        first = self._sideview_seed(plane_y).expand(B * K, 1, self.dof).clone()
        first[:, 0, 0] += default[:, 0, 0]  # aim the reference posture at each target
        sol = self.ik(T, first)
        q_flat, conv_flat = sol.q.clone(), sol.converged.clone()
        miss = (~conv_flat).nonzero()[:, 0]
        if miss.numel():  # the default tool-down postures, only where the side-view one failed
            retry = self.ik(T[miss], default[miss])
            q_flat[miss], conv_flat[miss] = retry.q, retry.converged
        q = q_flat.reshape(B, K, self.dof)
        conv = conv_flat.reshape(B, K)
        ok = conv.all(1) & ((q[:, 1:] - q[:, :-1]).abs().amax(dim=(1, 2)) < _MAX_JOINT_STEP)
        for b in (~ok).nonzero()[:, 0].tolist():
            q[b], conv[b] = self._sequential_path(xz[b], plane_y, q[b], conv[b])
        jump = torch.zeros(B, K, dtype=torch.bool)
        jump[:, 1:] = (q[:, 1:] - q[:, :-1]).abs().amax(dim=2) >= _MAX_JOINT_STEP
        bad = ~conv | jump
        ok = ~bad.any(1)
        first_bad = torch.where(ok, -1, bad.to(torch.int8).argmax(1))
        return PathIK(q=q, ok=ok, first_bad=first_bad)

    def _sequential_path(
        self, xz: torch.Tensor, plane_y: float, q: torch.Tensor, conv: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Re-solve one path (K, 2) waypoint by waypoint from its first converged waypoint."""
        K = xz.shape[0]
        q, conv = q.clone(), conv.clone()
        if not bool(conv[0]):
            return q, conv
        zero = torch.zeros(1, dtype=_DTYPE)
        for k in range(1, K):
            nxt = self.ik(sideview_pose(xz[k : k + 1], zero, plane_y), q[k - 1][None, None, :])
            q[k], conv[k] = nxt.q[0], nxt.converged[0]
            if not bool(conv[k]):
                break
        return q, conv

    def sideview_trace(self, q_waypoints: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """Map a joint-space linear interpolation of waypoints through FK, in the side view.

        Args:
            q_waypoints: (B, K, dof) waypoints of each path.
            u: (B, T) fractional waypoint index at each control tick, in [0, K - 1].

        Returns:
            (B, T, 3) world ``(x, z, phi)`` of the tcp at each control tick.

        Raises:
            InputError: For waypoints that are not finite (B, K >= 2, dof) numbers, or `u`
                that is not finite (B, T) numbers.
        """
        q_waypoints = self._waypoints(q_waypoints)
        B, K, dof = q_waypoints.shape
        u = as_real_tensor("u", u).to(_DTYPE)
        check_shape("u", u, (B, None))
        check_finite("u", u)
        u = u.clamp(0.0, K - 1)
        i0 = u.floor().clamp(max=K - 2).long()  # (B, T)
        frac = (u - i0)[..., None]
        rows = torch.arange(B)[:, None]
        q = q_waypoints[rows, i0] * (1 - frac) + q_waypoints[rows, i0 + 1] * frac  # (B, T, dof)
        return self.sideview_fk(q.reshape(-1, dof)).reshape(B, u.shape[1], 3)

    def sideview_reach(
        self, z: float, plane_y: float, x_range: tuple[float, float] = (-1.2, 1.2), n: int = 97
    ) -> tuple[float, float] | None:
        """Reachable interval of tcp x at height `z` in the plane (tool down), from the chain.

        Args:
            z: World height of the tcp (m).
            plane_y: World y of the plane (m).
            x_range: World x interval scanned (m).
            n: Number of scanned points (a positive integer).

        Returns:
            ``(x_min, x_max)`` of the reachable scanned points, or ``None`` if none is.

        Raises:
            InputError: For a `z` or `plane_y` that is not a finite number, an `x_range` that
                is not two finite numbers, low then high, or an `n` that is not a positive
                integer.
        """
        n = check_count("n", n)
        z, plane_y = check_number("z", z, unit="m"), check_number("plane_y", plane_y, unit="m")
        return _sideview_reach_cached(self, z, plane_y, _interval("x_range", x_range), n)

    # -- workspace --------------------------------------------------------------------------
    def reachable(self, xy: torch.Tensor, yaw: torch.Tensor) -> torch.Tensor:
        """Whether the tcp can point down at each table point with each yaw, at push height.

        Args:
            xy: (N, 2) world positions (m).
            yaw: (N,) tool yaws (rad).

        Returns:
            (N,) bool.
        """
        xy, yaw = as_real_tensor("xy", xy), as_real_tensor("yaw", yaw)
        check_shape("xy", xy, (None, 2))
        check_shape("yaw", yaw, (xy.shape[0],))
        check_finite("xy", xy)
        check_finite("yaw", yaw)
        if xy.shape[0] == 0:
            return torch.zeros(0, dtype=torch.bool)
        return self.ik(topdown_pose(xy.to(_DTYPE), yaw.to(_DTYPE), self.spec.push_height)).converged

    def reachable_mask(
        self,
        x_range: tuple[float, float],
        y_range: tuple[float, float],
        resolution: float = 0.02,
        n_yaws: int = 4,
        require: str = "any",
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Reachable region of a rectangle of the table at push height, from the chain.

        A grid point counts as reachable when the tool can point down there with ``any`` (or
        ``all``) of `n_yaws` evenly spaced yaws.

        Args:
            x_range: World x extent (m).
            y_range: World y extent (m).
            resolution: Grid spacing (m).
            n_yaws: Tool yaws tried per point (a positive integer).
            require: ``"any"`` or ``"all"``.

        Returns:
            ``(mask, xs, ys)``: mask (H, W) bool indexed ``[iy, ix]``, xs (W,), ys (H,).

        Raises:
            InputError: If a range is not two finite numbers, low then high, `resolution` is
                not a number > 0, `n_yaws` is not a positive integer or `require` is unknown.
        """
        x_range, y_range = _interval("x_range", x_range), _interval("y_range", y_range)
        resolution = check_number("resolution", resolution, bound="> 0", unit="m")
        n_yaws = check_count("n_yaws", n_yaws)
        if require not in ("any", "all"):
            raise InputError(f"require must be 'any' or 'all', got {require!r}.")
        return _reachable_mask_cached(
            self, tuple(x_range), tuple(y_range), float(resolution), n_yaws, require
        )

    def require_reachable(self, xy: torch.Tensor, yaw: torch.Tensor) -> None:
        """Raise `UnreachablePoseError` if any of the poses cannot be reached.

        Args:
            xy: (N, 2) world positions (m).
            yaw: (N,) tool yaws (rad).
        """
        ok = self.reachable(xy, yaw)
        if not bool(ok.all()):
            i = int((~ok).nonzero()[0, 0])
            x, y = (float(v) for v in xy[i])
            base = self.spec.base_xyz
            raise UnreachablePoseError(
                f"the gripper pose at world (x={x:.3f}, y={y:.3f}, yaw={float(yaw[i]):.3f}) is "
                f"outside the arm's reachable workspace (base at x={base[0]:.2f}, "
                f"y={base[1]:.2f}); move the target closer to the arm or check "
                "Arm.reachable_mask()."
            )


@lru_cache(maxsize=16)
def _reachable_mask_cached(
    arm: Arm,
    x_range: tuple[float, float],
    y_range: tuple[float, float],
    resolution: float,
    n_yaws: int,
    require: str,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    xs = np.arange(x_range[0], x_range[1] + 1e-9, resolution)
    ys = np.arange(y_range[0], y_range[1] + 1e-9, resolution)
    gx, gy = np.meshgrid(xs, ys)
    pts = torch.as_tensor(np.stack([gx.ravel(), gy.ravel()], -1), dtype=_DTYPE)
    yaws = torch.linspace(-math.pi, math.pi, n_yaws + 1, dtype=_DTYPE)[:-1]
    ok = torch.stack(
        [arm.reachable(pts, torch.full((len(pts),), float(a), dtype=_DTYPE)) for a in yaws], dim=-1
    )
    reach = ok.any(-1) if require == "any" else ok.all(-1)
    return reach.numpy().reshape(gy.shape), xs, ys


@lru_cache(maxsize=4)
def load_arm(spec: ArmSpec) -> Arm:
    """Build (once per process) the arm for a world spec."""
    return Arm(spec)


@lru_cache(maxsize=16)
def _sideview_seed_cached(arm: Arm, plane_y: float) -> torch.Tensor:
    """(dof,) IK solution at a reference pose in front of the base; its pan is made relative."""
    ref = torch.tensor([[arm.spec.base_xyz[0], 0.2]], dtype=_DTYPE)
    T = sideview_pose(ref, torch.zeros(1, dtype=_DTYPE), plane_y)
    sol = arm.ik(T)
    if not bool(sol.converged[0]):
        raise ConfigError(
            f"the arm cannot point its tool down at world (x={float(ref[0, 0]):.2f}, "
            f"y={plane_y:.2f}, z={float(ref[0, 1]):.2f}); mount it closer to the side-view plane."
        )
    q = sol.q[0].clone()
    q[0] -= arm._seeds(T)[0, 0, 0]  # pan relative to the direction of the target
    return q


@lru_cache(maxsize=64)
def _sideview_reach_cached(
    arm: Arm, z: float, plane_y: float, x_range: tuple[float, float], n: int
) -> tuple[float, float] | None:
    xs = torch.linspace(x_range[0], x_range[1], n, dtype=_DTYPE)
    xz = torch.stack([xs, torch.full_like(xs, z)], dim=-1)
    ok = arm.ik(sideview_pose(xz, torch.zeros(n, dtype=_DTYPE), plane_y)).converged
    if not bool(ok.any()):
        return None
    return float(xs[ok].min()), float(xs[ok].max())
