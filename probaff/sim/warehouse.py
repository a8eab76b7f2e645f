"""The grid warehouse of chapter 3: maps, their generator, and one-cell box pushes in pymunk.

Grid convention: a map is indexed ``[row, col]``; row 0 is the top row. Cell ``(r, c)`` has its
centre at world ``x = (c + 0.5) s``, ``y = (rows - r - 0.5) s`` for cell size ``s``. Directions
are ordered (up, down, left, right): up is +y (row - 1), left is -x (col - 1). Walls run along
the outer border of the grid, and interior walls stand inside it as wall blocks: a block of a
box's footprint and height in one cell, which the sensor cannot tell from a box (thesis ch. 3:
"walls and boxes look alike"). A map's `WarehouseMap.occupancy` marks every block, box or wall;
`WarehouseMap.walls` marks the wall blocks among them.

A box is pushable in a direction when the cell beyond it is inside the border walls and free:
walls (border or interior) never move, and the robot cannot push two boxes in a row.
`physics_affordances` measures this in the physics engine; `rule_affordances` states the rule.

The module registers the ``warehouse`` world kind (`probaff.sim.registry`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pymunk

from probaff._checks import as_float_vectors, check_count, check_positive
from probaff.errors import ConfigError, InputError
from probaff.grid import DIRECTION_NAMES, DIRECTION_OFFSETS
from probaff.sim.friction import add_sliding_body
from probaff.sim.inputs import check_rng, check_type
from probaff.sim.pusher import TrackedPusher
from probaff.sim.registry import WorldKind, register_world
from probaff.sim.runner import trapezoid_progress
from probaff.sim.warehouse_config import WarehouseSpec, load_warehouse

__all__ = [
    "DIRECTION_NAMES",
    "BoxPush",
    "WarehouseMap",
    "generate_map",
    "physics_affordances",
    "push_box",
    "rule_affordances",
]

_PUSHED_FRACTION = 0.8  # a push succeeds when the box travels this fraction of a cell
_NO_WALLS = np.zeros((0, 0), dtype=bool)  # WarehouseMap's default: no interior walls


def _index(name: str, value: object) -> int:
    """`value` as an int, or an `InputError` unless it is an integer (not a bool or string)."""
    if isinstance(value, (bool, str, bytes)):
        raise InputError(f"{name} must be an integer, got {value!r}.")
    try:
        as_float = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise InputError(f"{name} must be an integer, got {value!r}.") from None
    if not math.isfinite(as_float) or as_float != int(as_float):
        raise InputError(f"{name} must be an integer, got {value!r}.")
    return int(as_float)


def _pair(name: str, value: object, minimum: int | None = None) -> tuple[int, int]:
    """A ``(row, col)`` pair of integers (each >= `minimum` if given), or an `InputError`."""
    items = list(value) if isinstance(value, (tuple, list, np.ndarray)) else []
    if len(items) != 2:
        raise InputError(f"{name} must be a (row, col) pair of integers, got {value!r}.")
    if minimum is not None:
        return (
            check_count(f"{name}[0]", items[0], minimum=minimum),
            check_count(f"{name}[1]", items[1], minimum=minimum),
        )
    return _index(f"{name}[0]", items[0]), _index(f"{name}[1]", items[1])


def _direction(direction: object) -> int:
    """`direction` as an index 0..3 into `DIRECTION_NAMES`, or an `InputError`."""
    if isinstance(direction, (bool, str, bytes)) or direction not in range(4):
        raise InputError(f"direction must be 0..3 ({DIRECTION_NAMES}), got {direction!r}.")
    return int(direction)  # type: ignore[call-overload]


def _check_world(spec: object, m: object) -> None:
    """Raise `InputError` unless `spec` is a `WarehouseSpec` and `m` a `WarehouseMap`."""
    check_type("spec", spec, WarehouseSpec, "load_warehouse()")
    check_type("m", m, WarehouseMap, "generate_map or WarehouseMap.from_boxes")


@dataclass(frozen=True)
class WarehouseMap:
    """Which cells hold a block, and which blocks are interior walls.

    Attributes:
        occupancy: (rows, cols) bool, ``True`` where a block stands: a box or a wall block
            (the sensor sees both alike).
        cell_size: Side of a cell (m).
        walls: (rows, cols) bool, ``True`` where the block is an interior wall block, which
            never moves; a subset of `occupancy`. Left out (or None): no interior walls.
    """

    occupancy: np.ndarray
    cell_size: float = 1.0
    walls: np.ndarray = field(default_factory=lambda: _NO_WALLS)

    def __post_init__(self) -> None:
        occ = np.asarray(self.occupancy)
        if occ.ndim != 2 or occ.dtype != bool:
            raise InputError(f"occupancy must be a 2-D bool array, got {occ.dtype} {occ.shape}.")
        if min(occ.shape) < 2:
            raise InputError(f"a warehouse needs at least 2 x 2 cells, got {occ.shape}.")
        if isinstance(self.cell_size, (bool, str, bytes)):
            raise InputError(f"cell_size must be a finite number > 0, got {self.cell_size!r}.")
        check_positive("cell_size", self.cell_size)
        given = self.walls
        walls = np.zeros_like(occ) if given is None or given is _NO_WALLS else np.asarray(given)
        if walls.shape != occ.shape or walls.dtype != bool:
            raise InputError(
                f"walls must be a bool array of the occupancy's shape {occ.shape}, got "
                f"{walls.dtype} {walls.shape}."
            )
        stray = np.argwhere(walls & ~occ)
        if len(stray):
            r, c = stray[0].tolist()
            raise InputError(
                f"walls marks cell ({r}, {c}), which occupancy leaves free; occupancy holds every "
                "block, boxes and wall blocks alike: set occupancy there too, or build the map "
                "with WarehouseMap.from_boxes(shape, boxes, walls=...)."
            )
        object.__setattr__(self, "occupancy", occ)
        object.__setattr__(self, "cell_size", float(self.cell_size))
        object.__setattr__(self, "walls", walls)

    @classmethod
    def from_boxes(
        cls,
        shape: tuple[int, int],
        boxes: list[tuple[int, int]],
        cell_size: float = 1.0,
        walls: Sequence[tuple[int, int]] = (),
    ) -> WarehouseMap:
        """A map from a list of box cells and a list of interior wall blocks.

        Args:
            shape: ``(rows, cols)``.
            boxes: ``(row, col)`` of each box.
            cell_size: Side of a cell (m).
            walls: ``(row, col)`` of each interior wall block.

        Raises:
            InputError: For a shape that is not two integers >= 2, a box or wall cell that is
                not two integers or lies outside the grid, two boxes in one cell, or a wall
                block on a box or on another wall block.
        """
        rows, cols = _pair("shape", shape, minimum=2)
        occ = _cells("boxes", boxes, (rows, cols), "box")
        wall = _cells("walls", walls, (rows, cols), "wall block")
        both = np.argwhere(occ & wall)
        if len(both):
            r, c = both[0].tolist()
            raise InputError(
                f"walls puts a wall block on the box at cell ({r}, {c}); a cell holds one box or "
                "one wall block: move the wall block or the box to a free cell."
            )
        return cls(occ | wall, cell_size, wall)

    @property
    def shape(self) -> tuple[int, int]:
        """``(rows, cols)``."""
        return self.occupancy.shape

    @property
    def boxes(self) -> np.ndarray:
        """(B, 2) ``(row, col)`` of every block, row-major.

        Boxes and wall blocks alike, as the sensor sees them; `movable` tells them apart.
        """
        return np.argwhere(self.occupancy)

    @property
    def movable(self) -> np.ndarray:
        """(rows, cols) bool, ``True`` where a box stands (a block that is not a wall)."""
        return self.occupancy & ~self.walls

    def cell_centre(self, cells: np.ndarray) -> np.ndarray:
        """World xy (..., 2) of cell centres given (..., 2) ``(row, col)``.

        Raises:
            InputError: For `cells` that are not finite (..., 2) numbers.
        """
        cells = as_float_vectors("cells", cells, 2, "pairs of numbers")
        x = (cells[..., 1] + 0.5) * self.cell_size
        y = (self.shape[0] - cells[..., 0] - 0.5) * self.cell_size
        return np.stack([x, y], -1)

    def cell_of(self, xy: np.ndarray) -> np.ndarray:
        """``(row, col)`` (..., 2) of the cells holding world points (..., 2).

        Raises:
            InputError: For `xy` that is not finite (..., 2) numbers.
        """
        xy = as_float_vectors("xy", xy, 2, "pairs of numbers")
        col = np.floor(xy[..., 0] / self.cell_size).astype(int)
        row = self.shape[0] - 1 - np.floor(xy[..., 1] / self.cell_size).astype(int)
        return np.stack([row, col], -1)

    def inside(self, cells: np.ndarray) -> np.ndarray:
        """(...,) whether ``(row, col)`` (..., 2) lie inside the walls.

        Raises:
            InputError: For `cells` that are not finite (..., 2) numbers.
        """
        cells = as_float_vectors("cells", cells, 2, "pairs of numbers")
        return (
            (cells[..., 0] >= 0)
            & (cells[..., 0] < self.shape[0])
            & (cells[..., 1] >= 0)
            & (cells[..., 1] < self.shape[1])
        )

    def moved(self, cell: tuple[int, int], direction: int) -> WarehouseMap:
        """The map after the box at `cell` moved one cell in `direction`.

        Raises:
            InputError: For a cell that is not two integers, holds no box or holds a wall
                block, a direction that is not 0..3, or a target cell that is outside the walls
                or taken.
        """
        r, c = _pair("cell", cell)
        if not self.inside(np.array([r, c])):
            raise InputError(f"cell ({r}, {c}) lies outside the {self.shape} warehouse.")
        dr, dc = DIRECTION_OFFSETS[_direction(direction)]
        occ = self.occupancy.copy()
        if not occ[r, c]:
            raise InputError(f"no box at cell ({r}, {c}) to move.")
        if not self.movable[r, c]:
            raise InputError(f"cell ({r}, {c}) holds a wall block, which never moves.")
        if not self.inside(np.array([r + dr, c + dc])) or occ[r + dr, c + dc]:
            raise InputError(f"cell ({r + dr}, {c + dc}) is not free; the box cannot move there.")
        occ[r, c], occ[r + dr, c + dc] = False, True
        return WarehouseMap(occ, self.cell_size, self.walls)


def _cells(name: str, cells: object, shape: tuple[int, int], what: str) -> np.ndarray:
    """(rows, cols) bool mask of a list of distinct ``(row, col)`` cells inside `shape`.

    Raises:
        InputError: Naming `name`, for a list that is not of cells, a cell outside the grid or
            one listed twice.
    """
    if isinstance(cells, (str, bytes)) or not hasattr(cells, "__iter__"):
        raise InputError(f"{name} must be a list of (row, col) cells, got {cells!r}.")
    mask = np.zeros(shape, dtype=bool)
    for i, cell in enumerate(cells):
        r, c = _pair(f"{name}[{i}]", cell)
        if not (0 <= r < shape[0] and 0 <= c < shape[1]):
            raise InputError(
                f"{name}[{i}]: {what} at cell ({r}, {c}) lies outside the walls of a {shape[0]} x "
                f"{shape[1]} warehouse; rows run 0..{shape[0] - 1} and columns 0..{shape[1] - 1}."
            )
        if mask[r, c]:
            plural = "boxes" if what == "box" else f"{what}s"
            raise InputError(
                f"two {plural} in cell ({r}, {c}); a cell holds at most one {what}: list it once."
            )
        mask[r, c] = True
    return mask


def generate_map(
    spec: WarehouseSpec,
    rng: np.random.Generator,
    shape: tuple[int, int] | None = None,
    n_boxes: tuple[int, int] | None = None,
) -> WarehouseMap:
    """A random warehouse map: interior wall blocks, then boxes.

    The walls are the spec's fixed ``wall_blocks`` and ``wall_segments`` random segments, each
    ``wall_length`` blocks in one of ``wall_layouts`` from a uniform start cell and heading,
    clipped to the grid (segments may cross). Then ``box_row_share`` of the boxes stand in rows
    of ``box_row_length`` along a row or a column from uniform free cells (a row stops short at a
    block or the border), and the rest on uniform free cells; a box may stand against a wall.

    Args:
        spec: The warehouse world.
        rng: Source of randomness.
        shape: ``(rows, cols)``, integers >= 2; default the spec's grid. Any size works (e.g.
            100 x 100).
        n_boxes: Inclusive range ``(low, high)`` of the box count (wall blocks not counted),
            integers >= 0; default the spec's range, scaled by area for another shape (as is
            the number of wall segments).

    Returns:
        A map whose `WarehouseMap.walls` marks the wall blocks.

    Raises:
        InputError: If `spec` is not a `WarehouseSpec`, `rng` not a `numpy.random.Generator`,
            a size or box count is not such an integer, or a fixed wall block lies outside
            `shape`.
        ConfigError: If the boxes cannot fit beside the walls with one cell left free.
    """
    check_type("spec", spec, WarehouseSpec, "load_warehouse()")
    check_rng(rng)
    rows, cols = _pair("shape", shape, minimum=2) if shape is not None else (spec.rows, spec.cols)
    scale = rows * cols / (spec.rows * spec.cols)
    if n_boxes is None:
        n_boxes = (round(spec.boxes[0] * scale), round(spec.boxes[1] * scale))
    if isinstance(n_boxes, (str, bytes)) or not hasattr(n_boxes, "__len__") or len(n_boxes) != 2:
        raise InputError(f"n_boxes must be a (low, high) pair of counts, got {n_boxes!r}.")
    lo, hi = (check_count(f"n_boxes[{i}]", v, minimum=0) for i, v in enumerate(n_boxes))
    walls = _wall_layout(spec, rng, (rows, cols), scale)
    room = rows * cols - int(walls.sum())
    if hi < lo or hi > room - 1:
        raise ConfigError(
            f"cannot place {n_boxes} boxes in a {rows} x {cols} warehouse with "
            f"{int(walls.sum())} wall blocks; keep at least one cell free for the robot "
            "(fewer boxes, or fewer interior_walls.segments in the world file)."
        )
    n = int(rng.integers(lo, hi + 1))
    occ = walls.copy()
    in_rows = round(spec.box_row_share * n)
    placed = 0
    while placed < in_rows:
        length = int(rng.integers(spec.box_row_length[0], spec.box_row_length[1] + 1))
        placed += _place_run(occ, rng, min(length, in_rows - placed))
    free = np.flatnonzero(~occ.ravel())
    occ.ravel()[rng.choice(free, size=n - placed, replace=False)] = True
    return WarehouseMap(occ, spec.cell_size, walls)


def _place_run(occ: np.ndarray, rng: np.random.Generator, length: int) -> int:
    """Set up to `length` free cells of `occ` in a straight run from a uniform free cell.

    The run heads one of the four ways (uniformly) and stops short at a taken cell or the
    border. Returns the cells set (at least 1).
    """
    free = np.argwhere(~occ)
    r, c = free[rng.integers(len(free))]
    dr, dc = DIRECTION_OFFSETS[int(rng.integers(4))]
    done = 0
    while done < length and 0 <= r < occ.shape[0] and 0 <= c < occ.shape[1] and not occ[r, c]:
        occ[r, c] = True
        r, c, done = r + dr, c + dc, done + 1
    return done


def _wall_layout(
    spec: WarehouseSpec, rng: np.random.Generator, shape: tuple[int, int], scale: float
) -> np.ndarray:
    """(rows, cols) bool, the interior wall blocks of one generated map (see `generate_map`).

    Raises:
        InputError: If a fixed wall block lies outside `shape`.
    """
    rows, cols = shape
    walls = np.zeros(shape, dtype=bool)
    for r, c in spec.wall_blocks:
        if r >= rows or c >= cols:
            raise InputError(
                f"the world's interior_walls.blocks holds [{r}, {c}], outside the requested "
                f"{rows} x {cols} map; pass a shape that holds it, or clear the fixed blocks "
                "(dataclasses.replace(spec, wall_blocks=()))."
            )
        walls[r, c] = True
    lo, hi = (round(k * scale) for k in spec.wall_segments)
    for _ in range(int(rng.integers(lo, hi + 1))):
        length = int(rng.integers(spec.wall_length[0], spec.wall_length[1] + 1))
        layout = spec.wall_layouts[int(rng.integers(len(spec.wall_layouts)))]
        r, c = int(rng.integers(rows)), int(rng.integers(cols))
        heading = int(rng.integers(4))
        turn = int(rng.integers(1, length)) if layout == "corner" and length > 1 else -1
        for i in range(length):
            if i == turn:  # an L: turn to one of the two perpendicular headings
                heading = (2 if heading < 2 else 0) + int(rng.integers(2))
            if 0 <= r < rows and 0 <= c < cols:
                walls[r, c] = True
            dr, dc = DIRECTION_OFFSETS[heading]
            r, c = r + int(dr), c + int(dc)
    return walls


def rule_affordances(m: WarehouseMap) -> np.ndarray:
    """The ground-truth rule: a box moves into a free cell inside the walls.

    A wall block never moves, and no box moves into a wall block, a second box or the border.

    Returns:
        (rows, cols, 4) bool, ``True`` where a box (not a wall block) stands and can be pushed
        in that direction.
    """
    rows, cols = m.shape
    padded = np.ones((rows + 2, cols + 2), dtype=bool)  # the walls count as occupied
    padded[1:-1, 1:-1] = m.occupancy
    out = np.zeros((rows, cols, 4), dtype=bool)
    for k, (dr, dc) in enumerate(DIRECTION_OFFSETS):
        beyond = padded[1 + dr : 1 + dr + rows, 1 + dc : 1 + dc + cols]
        out[..., k] = m.movable & ~beyond
    return out


@dataclass(frozen=True)
class BoxPush:
    """The outcome of pushing one box one cell.

    Attributes:
        displacement: (2,) world displacement of the pushed box (m).
        moved: The box travelled most of a cell in the push direction.
        robot_lag: Largest distance between the commanded and the actual robot (m).
        others_moved: Largest displacement of any other box (m).
    """

    displacement: np.ndarray
    moved: bool
    robot_lag: float
    others_moved: float


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    u = float(np.clip((p - a) @ ab / (ab @ ab), 0.0, 1.0))
    return float(np.hypot(*(a + u * ab - p)))


def _box_support(spec: WarehouseSpec) -> np.ndarray:
    n, half = spec.friction_grid, 0.5 * spec.box_size
    u = ((np.arange(n) + 0.5) / n * 2 - 1) * half
    gx, gy = np.meshgrid(u, u)
    return np.stack([gx.ravel(), gy.ravel()], -1)


def push_box(
    spec: WarehouseSpec,
    m: WarehouseMap,
    cell: tuple[int, int],
    direction: int,
    neighbourhood: int = 2,
) -> BoxPush:
    """Push the box at `cell` one cell in `direction` with the robot, in pymunk.

    The robot starts on the far side of the box, touching it, and drives one cell length with
    a force-limited controller. Only blocks within `neighbourhood` cells (Chebyshev) of the box
    take part, except any in the cell the robot starts from: boxes as sliding bodies, interior
    wall blocks as static boxes of the same footprint; the border walls are static segments,
    except one the robot would stand in: this measures whether the box can move, not whether
    the robot can get behind it (the planner checks that). Pushing a wall block measures it
    too: it stays put.

    Args:
        spec: The warehouse world.
        m: The map.
        cell: ``(row, col)`` of the box (or wall block).
        direction: Index into `DIRECTION_NAMES`.
        neighbourhood: Radius of the simulated neighbourhood (cells), an integer >= 0.

    Returns:
        What the push did.

    Raises:
        InputError: For a `spec` or `m` of the wrong type, a `cell` that is not two integers
            or holds no box, a `direction` that is not 0..3 or a `neighbourhood` that is not
            an integer >= 0.
    """
    _check_world(spec, m)
    neighbourhood = check_count("neighbourhood", neighbourhood, minimum=0)
    r, c = _pair("cell", cell)
    if not m.inside(np.array([r, c])) or not m.occupancy[r, c]:
        raise InputError(f"there is no box (or wall block) at cell {(r, c)} to push.")
    direction = _direction(direction)
    dr, dc = DIRECTION_OFFSETS[direction]
    d = np.array([dc, -dr], dtype=float)  # world unit vector of the push
    s = spec.cell_size
    space = pymunk.Space()
    space.iterations = spec.iterations
    space.collision_slop = spec.collision_slop
    pushed, others = _add_blocks(space, spec, m, (r, c), (r - dr, c - dc), neighbourhood)
    start = m.cell_centre(np.array(cell)) - d * (0.5 * spec.box_size + spec.robot_radius + 0.005)
    _add_walls(space, spec, m, start)
    yaw = math.atan2(d[1], d[0])

    def make_robot(body: pymunk.Body) -> list[pymunk.Shape]:
        disc = pymunk.Circle(body, spec.robot_radius)
        disc.friction = 0.5
        return [disc]

    robot = TrackedPusher(
        space,
        np.array([*start, yaw]),
        80.0,
        pymunk.moment_for_circle(80.0, 0, spec.robot_radius),
        make_robot,
        spec.robot_max_force,
        200.0,
        spec.robot_speed,
    )
    prog = s * trapezoid_progress(s, spec.robot_speed, spec.robot_acceleration, spec.control_rate)
    settle = int(0.3 * spec.control_rate)
    prog = np.concatenate([prog, np.full(settle, prog[-1])])
    path = np.stack([start[0] + prog * d[0], start[1] + prog * d[1], np.full_like(prog, yaw)], -1)
    x0 = np.array(pushed.position)
    dt = 1.0 / spec.control_rate / spec.substeps
    lag = 0.0
    for i in range(len(path) - 1):
        robot.command(path[i], path[i + 1], spec.control_rate)
        for _ in range(spec.substeps):
            space.step(dt)
        lag = max(lag, robot.lag(path[i + 1]))
    disp = np.array(pushed.position) - x0
    moved = float(disp @ d) > _PUSHED_FRACTION * s
    other = max((float(np.hypot(*(np.array(b.position) - c0))) for b, c0 in others), default=0.0)
    return BoxPush(displacement=disp, moved=moved, robot_lag=lag, others_moved=other)


def _add_blocks(
    space: pymunk.Space,
    spec: WarehouseSpec,
    m: WarehouseMap,
    cell: tuple[int, int],
    access: tuple[int, int],
    neighbourhood: int,
) -> tuple[pymunk.Body, list[tuple[pymunk.Body, np.ndarray]]]:
    """Add the blocks within `neighbourhood` of `cell`, but the one at `access`.

    Boxes become sliding bodies, interior wall blocks static bodies of the same footprint.

    Returns:
        ``(pushed, others)``: the body at `cell`, and each other box's body with its start
        centre.
    """
    support = _box_support(spec)
    ones = np.ones(len(support))
    r, c = cell
    pushed, others = None, []

    def make_shape(body: pymunk.Body) -> pymunk.Shape:
        shape = pymunk.Poly.create_box(body, (spec.box_size, spec.box_size))
        shape.friction = math.sqrt(spec.box_contact_friction)
        return shape

    for rr, cc in m.boxes:
        if max(abs(rr - r), abs(cc - c)) > neighbourhood or (rr, cc) == access:
            continue
        centre = m.cell_centre(np.array([rr, cc]))
        if m.walls[rr, cc]:
            body = pymunk.Body(body_type=pymunk.Body.STATIC)
            body.position = (float(centre[0]), float(centre[1]))
            space.add(body, make_shape(body))
        else:
            body, _ = add_sliding_body(
                space,
                spec.box_mass,
                make_shape,
                (*centre, 0.0),
                support,
                ones,
                spec.box_ground_friction,
                9.81,
            )
        if (rr, cc) == (r, c):
            pushed = body
        elif not m.walls[rr, cc]:
            others.append((body, centre))
    assert pushed is not None
    return pushed, others


def _add_walls(
    space: pymunk.Space, spec: WarehouseSpec, m: WarehouseMap, start: np.ndarray
) -> None:
    """Add the border walls as static segments, but one the robot at `start` would stand in."""
    rows, cols = m.shape
    s = spec.cell_size
    t = 0.5 * spec.wall_thickness
    W, H = cols * s, rows * s
    for a, b in (
        ((-t, -t), (W + t, -t)),
        ((W + t, -t), (W + t, H + t)),
        ((W + t, H + t), (-t, H + t)),
        ((-t, H + t), (-t, -t)),
    ):
        if _segment_distance(start, np.array(a), np.array(b)) < spec.robot_radius + t:
            continue  # the robot stands where this wall is: it measures the box, not access
        seg = pymunk.Segment(space.static_body, a, b, t)
        seg.friction = 0.5
        space.add(seg)


def physics_affordances(spec: WarehouseSpec, m: WarehouseMap) -> np.ndarray:
    """Ground-truth affordances measured by pushing every box every way in the physics.

    Returns:
        (rows, cols, 4) bool, ``True`` where a box stands and moved a cell when pushed (every
        block is pushed, wall blocks included).

    Raises:
        InputError: For a `spec` or `m` of the wrong type.
    """
    _check_world(spec, m)
    out = np.zeros((*m.shape, 4), dtype=bool)
    for r, c in m.boxes:
        for k in range(4):
            out[r, c, k] = push_box(spec, m, (int(r), int(c)), k).moved
    return out


register_world(
    WorldKind(
        name="warehouse", label="warehouse", load_world=load_warehouse, simulate=push_box, order=2
    )
)
