"""The chapter 4 task: push a flat book over the table edge until it can be grasped.

The task lives in ``worlds/tasks/push_to_edge.yaml`` (its scene in
``worlds/scenes/push_to_edge.yaml``). World frame: the table's, z up; the edge is the line
``x = edge_x`` (the table's +x side), the book (object 0) starts inside it and the battery
(object 1, 15 kg, which the hand cannot move) stands on the table.

Success, from the gripper and book geometry. The gripper closes vertically on the part of the
book that overhangs the edge: one fingertip slides under the book beyond the edge, the other
presses on top; the 3 cm book fits the 15 cm finger span. The fingertip under the book needs
its diameter ``2 r_f`` (``gripper.finger_radius`` of ``worlds/tabletop.yaml``) plus a
``clearance`` from the edge, the *grasp depth* ``d_g = 2 r_f + clearance``; it needs a pad of
book at least one fingertip wide. So the book is graspable when

- its footprint crosses the line ``x = edge_x + d_g`` along a chord at least ``2 r_f`` long,
  and
- its centre of mass (the footprint's centre: the book is uniform) lies at least
  ``com_margin`` inside the edge, so that it does not tip over.

It falls when its centre leaves the table, the simulator's rule (`probaff.sim.tabletop`).

Covered by tests/planning/push_to_edge/test_edge_task.py.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from probaff._checks import (
    as_float_vectors,
    check_count,
    check_finite,
    check_positive,
    check_shape,
)
from probaff.errors import ConfigError, InputError
from probaff.planning._checks import check_instance, check_rng
from probaff.planning.geometry import box_corners, boxes_overlap, chord_at
from probaff.sim.sampling import sample_scene
from probaff.sim.specs import ObjectSpec, load_catalogue
from probaff.sim.tabletop import SceneInstance
from probaff.sim.tabletop_config import SceneSpec, TabletopSpec, load_scene, load_tabletop
from probaff.sim.world_files import mapping, no_extra, optional_section, read_yaml, worlds_dir

__all__ = [
    "START_OVERLAP",
    "EdgeTask",
    "RiskBounds",
    "SearchOptions",
    "check_book_pose",
    "check_task",
    "load_edge_task",
    "sample_episode",
]

_MAX_EPISODE_DRAWS = 500

START_OVERLAP = 0.01
"""Deepest interpenetration (m) of the book's and the battery's footprints that a planning
start may have: deeper is a wrong pose, shallower is the physics (a push leaves the book up to
a few millimetres into the battery it was pushed against)."""


@dataclass(frozen=True)
class SearchOptions:
    """How A* searches (``search`` in the task YAML).

    Attributes:
        xy_resolution: Closed-set cell of the book's position (m).
        yaw_resolution: Closed-set bin of the book's yaw (rad); yaw is taken modulo pi.
        max_expansions: Nodes A* expands before it returns its best partial plan.
        batch: Nodes expanded together; all their candidates are predicted in one call.
        step_bound: Largest move of the book's centre by one push (m), the heuristic's
            divisor; it must bound every transition for the heuristic to be admissible.
        safety_margin: The planner's buffer against its model's errors (m): it aims for
            goals whose centre lies this much farther inside the edge than the task
            requires, and treats a predicted centre this close to a table edge as a fall.
    """

    xy_resolution: float = 0.02
    yaw_resolution: float = 0.2618
    max_expansions: int = 240
    batch: int = 8
    step_bound: float = 0.16
    safety_margin: float = 0.0

    def __post_init__(self) -> None:
        for name in ("xy_resolution", "yaw_resolution", "step_bound"):
            check_positive(f"search.{name}", getattr(self, name))
        check_positive("search.safety_margin", self.safety_margin, allow_zero=True)
        object.__setattr__(
            self, "max_expansions", check_count("search.max_expansions", self.max_expansions)
        )
        object.__setattr__(self, "batch", check_count("search.batch", self.batch))


@dataclass(frozen=True)
class RiskBounds:
    """The risk-aware planner's bounds (``risk`` in the task YAML).

    Attributes:
        samples: Draws from the model's predictive distribution per candidate push.
        max_fall: Largest accepted P(the book falls off the table).
        max_collision: Largest accepted P(the book ends overlapping the battery).
    """

    samples: int = 32
    max_fall: float = 0.1
    max_collision: float = 0.1

    def __post_init__(self) -> None:
        object.__setattr__(self, "samples", check_count("risk.samples", self.samples))
        for name in ("max_fall", "max_collision"):
            v = getattr(self, name)
            check_positive(f"risk.{name}", v, allow_zero=True)
            if v > 1:
                raise InputError(f"risk.{name} is a probability bound in [0, 1], got {v}.")


@dataclass(frozen=True)
class EdgeTask:
    """The push-to-edge task.

    Attributes:
        scene: The scene template (book first, battery second).
        world: The tabletop world.
        edge_x: World x of the edge the book goes over (m).
        start_x: Range of the book's start x in an episode (m).
        start_y: Range of its start y (m).
        clearance: Clearance of the lower fingertip from the edge (m).
        com_margin: Distance the centre of mass stays inside the edge (m).
        budget: Pushes allowed per episode.
        replan_distance: Replan when the book lands farther than this from the prediction (m).
        directions: Candidate pushing frames around the book.
        start_gap: Hand start distance from the book's footprint (m).
        push_distance: L, the hand's travel per push (m), from the scene.
        contact_tolerance: Footprints that overlap by less than this (m) touch, they do not
            collide: the simulator leaves a book resting against the battery with a sliver
            of overlap (its collision slop).
        search: A* options.
        risk: The risk-aware planner's bounds.
    """

    scene: SceneSpec
    world: TabletopSpec
    edge_x: float = 0.5
    start_x: tuple[float, float] = (-0.15, 0.15)
    start_y: tuple[float, float] = (-0.25, 0.25)
    clearance: float = 0.005
    com_margin: float = 0.01
    budget: int = 15
    replan_distance: float = 0.05
    directions: int = 16
    start_gap: float = 0.02
    push_distance: float = 0.15
    contact_tolerance: float = 0.002
    search: SearchOptions = SearchOptions()
    risk: RiskBounds = RiskBounds()
    _objects: tuple[ObjectSpec, ObjectSpec] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not isinstance(self.scene, SceneSpec):
            raise ConfigError(
                f"scene must be a SceneSpec (load_scene('push_to_edge')), got "
                f"{type(self.scene).__name__}."
            )
        if not isinstance(self.world, TabletopSpec):
            raise ConfigError(
                f"world must be a TabletopSpec (load_tabletop()), got {type(self.world).__name__}."
            )
        if len(self.scene.objects) != 2:
            raise ConfigError(
                f"scene {self.scene.name!r} has {len(self.scene.objects)} objects; the "
                "push-to-edge task needs the book first and the battery second."
            )
        object.__setattr__(self, "budget", check_count("budget (pushes per episode)", self.budget))
        object.__setattr__(
            self, "directions", check_count("candidates.directions", self.directions)
        )
        for name in ("clearance", "com_margin", "start_gap", "contact_tolerance"):
            check_positive(name, getattr(self, name), allow_zero=True)
        for name in ("replan_distance", "push_distance"):
            check_positive(name, getattr(self, name))
        check_finite("edge_x", self.edge_x)
        hx = 0.5 * self.world.table_size[0]
        if not 0 < self.edge_x <= hx + 1e-9:
            raise ConfigError(
                f"edge_x = {self.edge_x} is not the table's +x edge (the table spans x in "
                f"[-{hx}, {hx}]); set edge_x to {hx}."
            )
        if self.start_gap >= self.push_distance:
            raise ConfigError(
                f"candidates.start_gap = {self.start_gap} m is not shorter than the push "
                f"distance {self.push_distance} m, so the hand never reaches the book; lower "
                "candidates.start_gap."
            )
        for name, half in (("start_x", hx), ("start_y", 0.5 * self.world.table_size[1])):
            lo, hi = getattr(self, name)
            if not lo <= hi:
                raise ConfigError(f"start.{name[-1]} must be [low, high], got {[lo, hi]}.")
            if not -half <= lo <= hi <= half:
                raise ConfigError(
                    f"start.{name[-1]} = {[lo, hi]} leaves the table (its {name[-1]} spans "
                    f"[-{half}, {half}]), so episodes would start with the book fallen off; "
                    "choose a start region on the table."
                )
        catalogue = load_catalogue()
        object.__setattr__(
            self,
            "_objects",
            tuple(catalogue[p.choices[0]] for p in self.scene.objects[:2]),
        )
        book = self.book
        if self.grasp_depth + self.com_margin >= self.half_diagonal:
            raise ConfigError(
                f"the goal is unreachable by construction: a {book.size[0]} x {book.size[1]} m "
                f"book cannot reach {self.grasp_depth:.3f} m beyond the edge with its centre "
                f"{self.com_margin} m inside it; lower grasp.clearance or grasp.com_margin."
            )
        if self.start_x[1] + self.half_diagonal >= self.edge_x + self.grasp_depth:
            raise ConfigError(
                "start.x reaches the goal already; start the book farther from the edge "
                f"(start.x[1] + {self.half_diagonal:.3f} < {self.edge_x + self.grasp_depth:.3f})."
            )

    # ------------------------------------------------------------------ objects
    @property
    def book(self) -> ObjectSpec:
        """The pushed book (the scene's first object)."""
        return self._objects[0]

    @property
    def battery(self) -> ObjectSpec:
        """The obstacle (the scene's second object)."""
        return self._objects[1]

    @property
    def grasp_depth(self) -> float:
        """d_g = 2 r_f + clearance: how far beyond the edge the gripper needs book (m)."""
        return 2 * self.world.gripper.finger_radius + self.clearance

    @property
    def finger_width(self) -> float:
        """2 r_f: the shortest chord of book a fingertip can close on (m)."""
        return 2 * self.world.gripper.finger_radius

    @property
    def half_diagonal(self) -> float:
        """The book's largest extent from its centre (m)."""
        return 0.5 * math.hypot(*self.book.size)

    # ------------------------------------------------------------------ tests
    @staticmethod
    def _poses(poses: Any) -> np.ndarray:
        """`poses` as finite (..., 3) floats, or `InputError` naming ``poses``."""
        return as_float_vectors("poses", poses, 3, "world (x, y, yaw) book poses")

    def graspable(self, poses: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Whether book poses (..., 3) are goals (see the module docstring); (...,) bool.

        A book that has fallen off the table (`fallen`) is never a goal.

        Args:
            poses: (..., 3) world book poses.
            margin: Keep the centre this much farther inside the edge (m) than
                ``com_margin`` (the planner's safety margin; 0 for the task's own test).
        """
        return self._graspable(self._poses(poses), margin)

    def _graspable(self, poses: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """`graspable` of checked poses."""
        chord = chord_at(poses, self.book.size, self.edge_x + self.grasp_depth)
        inside = poses[..., 0] <= self.edge_x - self.com_margin - margin
        return (chord >= self.finger_width) & inside & ~self._fallen(poses)

    def fallen(self, poses: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Whether the book's centre is off the table, for poses (..., 3); (...,) bool.

        Args:
            poses: (..., 3) world book poses.
            margin: Count a centre closer than this to an edge (m) as fallen too.
        """
        return self._fallen(self._poses(poses), margin)

    def _fallen(self, poses: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """`fallen` of checked poses."""
        hx, hy = 0.5 * self.world.table_size[0] - margin, 0.5 * self.world.table_size[1] - margin
        return (np.abs(poses[..., 0]) > hx) | (np.abs(poses[..., 1]) > hy)

    def check_start(self, book: Any, battery: Any) -> tuple[np.ndarray, np.ndarray]:
        """Validate a planning start: the book and the battery on the table, apart.

        Args:
            book: (3,) world start pose of the book.
            battery: (3,) world pose of the battery.

        Returns:
            ``(book, battery)`` as float arrays.

        Raises:
            InputError: For a pose that is not a finite (3,), a centre off the table, or a
                book whose footprint reaches more than `START_OVERLAP` into the battery's
                (a book pushed against the battery rests a few millimetres into it in the
                physics; a replan starts from there).
        """
        book = check_book_pose("book", book)
        battery = check_book_pose("battery", battery)
        w, d = self.world.table_size
        for name, pose in (("book", book), ("battery", battery)):
            if bool(self.fallen(pose)):
                raise InputError(
                    f"the start pose of the {name}, {np.round(pose, 3).tolist()}, is off the "
                    f"{w} x {d} m table (its centre must lie within x in [{-w / 2}, {w / 2}] "
                    f"and y in [{-d / 2}, {d / 2}]); give a start pose on the table "
                    "(sample_episode draws valid starts)."
                )
        overlap = boxes_overlap(
            book, self.book.size, battery, self.battery.size, margin=-0.5 * START_OVERLAP
        )
        if bool(overlap):
            raise InputError(
                f"the start pose of the book, {np.round(book, 3).tolist()}, overlaps the "
                f"battery at {np.round(battery, 3).tolist()}; give poses whose footprints are "
                "apart (sample_episode draws valid starts)."
            )
        return book, battery

    def collides(self, poses: np.ndarray, battery: np.ndarray) -> np.ndarray:
        """Whether book poses (..., 3) overlap the battery at world pose (3,); (...,) bool.

        An overlap of less than ``contact_tolerance`` is a touch, not a collision.
        """
        return boxes_overlap(
            poses, self.book.size, battery, self.battery.size, margin=-self.contact_tolerance
        )

    def heuristic(self, poses: np.ndarray) -> np.ndarray:
        """Admissible lower bound on the pushes from book poses (..., 3) to a goal; (...,) int.

        Every goal pose has ``x >= edge_x + d_g - R`` (R the half diagonal: no footprint
        point is farther from the centre), and one push moves the centre at most
        ``search.step_bound``.
        """
        poses = self._poses(poses)
        gap = self.edge_x + self.grasp_depth - self.half_diagonal - poses[..., 0]
        return np.ceil(np.maximum(gap, 0.0) / self.search.step_bound - 1e-9).astype(int)

    def progress(self, poses: np.ndarray) -> np.ndarray:
        """How far (m) the book still lacks of a goal along x, 0 at a goal; (...,) float.

        ``edge_x + d_g`` minus the farthest footprint point along +x, for a tie-break and for
        the greedy planner (it ignores the chord and centre conditions).
        """
        poses = self._poses(poses)
        reach = box_corners(poses, self.book.size)[..., 0].max(-1)
        return np.where(
            self._graspable(poses), 0.0, np.maximum(self.edge_x + self.grasp_depth - reach, 0.0)
        )

    # ------------------------------------------------------------------ pushes
    def candidate_pushes(self, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pushing frames placed evenly around book poses, oriented to their centres.

        Direction ``i`` points along world yaw ``2 pi i / directions``; the hand starts
        ``start_gap`` plus its fingertip radius behind the book's footprint.

        Args:
            poses: (B, 3) world book poses.

        Returns:
            ``(origins, yaws)``: (B, C, 2) world hand starts and (C,) world push yaws.
        """
        poses = self._poses(poses).reshape(-1, 3)
        yaws = 2 * math.pi * np.arange(self.directions) / self.directions
        d = np.stack([np.cos(yaws), np.sin(yaws)], -1)  # (C, 2)
        rel = poses[:, 2, None] - yaws[None, :]  # book yaw in each pushing frame
        a, b = 0.5 * self.book.size[0], 0.5 * self.book.size[1]
        support = np.abs(np.cos(rel)) * a + np.abs(np.sin(rel)) * b  # footprint extent along -d
        back = support + self.world.gripper.finger_radius + self.start_gap
        origins = poses[:, None, :2] - back[..., None] * d[None]
        return origins, yaws

    def hand_hits_battery(
        self, origins: np.ndarray, yaws: np.ndarray, battery: np.ndarray
    ) -> np.ndarray:
        """Whether either fingertip at the hand's start overlaps the battery.

        Args:
            origins: (..., 2) world hand starts.
            yaws: (...,) push yaws, broadcastable.
            battery: (3,) world battery pose.

        Returns:
            (...,) bool.
        """
        g = self.world.gripper
        yaws = np.broadcast_to(yaws, origins.shape[:-1])
        side = np.stack([-np.sin(yaws), np.cos(yaws)], -1) * (0.5 * g.push_opening)
        c, s = math.cos(battery[2]), math.sin(battery[2])
        hit = np.zeros(origins.shape[:-1], dtype=bool)
        for sign in (-1.0, 1.0):
            rel = origins + sign * side - battery[:2]
            u = np.abs(rel[..., 0] * c + rel[..., 1] * s) - 0.5 * self.battery.size[0]
            v = np.abs(-rel[..., 0] * s + rel[..., 1] * c) - 0.5 * self.battery.size[1]
            dist = np.hypot(np.maximum(u, 0.0), np.maximum(v, 0.0))
            hit |= (np.maximum(u, v) < 0) | (dist < g.finger_radius)
        return hit


def check_task(task: Any) -> EdgeTask:
    """`task`, or `InputError` unless it is an `EdgeTask`."""
    return check_instance(task, EdgeTask, "task must be an EdgeTask (load_edge_task())")


def _pair(where: str, value: Any) -> tuple[float, float]:
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise ConfigError(f"{where} must be [low, high], got {value!r}.")
    try:
        return float(value[0]), float(value[1])
    except (TypeError, ValueError):
        raise ConfigError(f"{where} must hold two numbers, got {value!r}.") from None


_SECTIONS: dict[str, set[str]] = {
    "start": {"x", "y"},
    "grasp": {"clearance", "com_margin"},
    "candidates": {"directions", "start_gap"},
    "search": set(SearchOptions.__dataclass_fields__),
    "risk": set(RiskBounds.__dataclass_fields__),
}
"""The sections of a task file and the fields each may hold."""


def load_edge_task(path: Path | str | None = None, world: TabletopSpec | None = None) -> EdgeTask:
    """Load the push-to-edge task (``worlds/tasks/push_to_edge.yaml`` by default).

    Args:
        path: Another task file.
        world: The tabletop world; ``worlds/tabletop.yaml`` by default.

    Raises:
        ConfigError: For a missing file, an unknown key or a malformed value, naming it.
    """
    p = Path(path) if path is not None else worlds_dir() / "tasks" / "push_to_edge.yaml"
    if not p.is_file():
        raise ConfigError(f"no task file at {p}; give the path of a push-to-edge task YAML.")
    raw = read_yaml(p)
    w = p.name
    top = mapping(w, {} if raw is None else raw)
    no_extra(w, top, {*_SECTIONS, "scene", "edge_x", "budget", "replan_distance"})
    start, grasp, cand, search, risk = (
        optional_section(w, top, key, allowed) for key, allowed in _SECTIONS.items()
    )
    scene = load_scene(str(top.get("scene", "push_to_edge")))
    kw: dict[str, Any] = {}
    if "x" in start:
        kw["start_x"] = _pair(f"{w}:start.x", start["x"])
    if "y" in start:
        kw["start_y"] = _pair(f"{w}:start.y", start["y"])
    for key, src in (("edge_x", top), ("replan_distance", top), ("budget", top)):
        if key in src:
            kw[key] = src[key]
    kw.update({k: grasp[k] for k in grasp})
    kw.update({k: cand[k] for k in cand})
    try:
        return EdgeTask(
            scene=scene,
            world=world or load_tabletop(),
            push_distance=scene.push.distance,
            search=SearchOptions(**search),
            risk=RiskBounds(**risk),
            **kw,
        )
    except InputError as exc:
        raise ConfigError(f"{w}: {exc}") from None


def sample_episode(task: EdgeTask, rng: np.random.Generator) -> SceneInstance:
    """Draw an episode's start: the scene's objects and physics, the book in the start region.

    The battery, the frictions, masses and pressure distributions come from the scene's
    ranges, as for its training pushes; the book is drawn in ``start_x`` x ``start_y``. The
    draw's push is not used. Objects never overlap at the start.

    Args:
        task: The task.
        rng: Source of randomness (the draw depends on nothing else).

    Returns:
        The episode's scene, object 0 the book and object 1 the battery.

    Raises:
        InputError: For a `task` that is not an `EdgeTask` or an `rng` that is not a
            ``numpy.random.Generator``.
        ConfigError: If valid starts are too rare to draw.
    """
    check_task(task)
    check_rng(rng)
    first = replace(task.scene.objects[0], x=task.start_x, y=task.start_y)
    scene = replace(task.scene, objects=(first, *task.scene.objects[1:]))
    catalogue = load_catalogue()
    for _ in range(_MAX_EPISODE_DRAWS):
        s = sample_scene(scene, catalogue, task.world, rng)
        if s is None:
            continue
        if (
            bool(task.fallen(s.poses[0]))
            or bool(task.collides(s.poses[0], s.poses[1]))
            or bool(task.graspable(s.poses[0]))
        ):
            continue
        return s
    raise ConfigError(
        f"fewer than 1 in {_MAX_EPISODE_DRAWS} draws of scene {task.scene.name!r} gives a start "
        "with the book and battery apart; widen the start region or the battery's range."
    )


def check_book_pose(name: str, pose: Any) -> np.ndarray:
    """A finite (3,) world pose as an array, or `InputError` naming `name`."""
    arr = np.asarray(pose, dtype=float)
    check_shape(name, arr, (3,))
    check_finite(name, arr)
    return arr
