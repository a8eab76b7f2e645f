"""Pick and place skills in the side view (thesis chapter 6), batched over scenes.

A skill is a piecewise-linear tcp path in the side-view plane with the tool pointing down and
the fingers closing along world x. Every waypoint of every scene of a batch is solved in one
batched IK call on the arm (`probaff.sim.arm.Arm.solve_sideview_paths`); the physics then
follows the FK of the joint path (`Arm.sideview_trace`), as the tabletop push does.

- pick: from ``approach_height`` above the object's top, down to ``grasp_fraction`` of its
  height, close the fingers, lift by ``lift``, hold.
- place: a held object ``hold_height`` above its target (the table or another object's top),
  lowered to the scene's release height above it, fingers opened, settle.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch

from probaff._checks import check_count, default_or_instance
from probaff.errors import ConfigError, InputError, UnreachablePoseError
from probaff.sim.arm import Arm, load_arm
from probaff.sim.inputs import check_items, check_rng, check_type
from probaff.sim.runner import trapezoid_progress
from probaff.sim.sampling import draw_in_range
from probaff.sim.sideview import SideViewRun, SideViewScene, simulate_sideview
from probaff.sim.sideview_config import SideViewSceneSpec, SideViewSpec, load_sideview
from probaff.sim.specs import ObjectSpec

__all__ = [
    "SkillOutcome",
    "SkillPlan",
    "pick",
    "place",
    "plan_skills",
    "run_sampled",
    "run_skills",
    "sample_sideview_scenes",
    "simulate_skill",
]

_MAX_DRAWS_PER_SAMPLE = 200
_PLACE_MAX_TILT = 0.1  # rad; a placed object rests flat within this angle
_BETWEEN_TOL = 0.005  # m; a squeezed object's width matches the finger gap within this


@dataclass(frozen=True)
class SkillPlan:
    """The arm's commanded motion for one skill.

    Attributes:
        skill: ``"pick"`` or ``"place"``.
        q_waypoints: (K, dof) joint waypoints (rad).
        hand_path: (T_c, 3) commanded world ``(x, z, phi)`` of the tcp per control tick: the
            FK of the joint path.
        opening: (T_c,) commanded gap between the finger pads (m).
        initial_opening: Actual gap of the fingers at the start (m).
        marks: Control ticks ``(a, b, end)``: pick: end of closing, end of lifting; place:
            start, release (end of lowering); ``end`` the last tick.
    """

    skill: str
    q_waypoints: np.ndarray
    hand_path: np.ndarray
    opening: np.ndarray
    initial_opening: float
    marks: tuple[int, int, int]


@dataclass(frozen=True)
class SkillOutcome:
    """What one pick or place did.

    Attributes:
        skill: ``"pick"`` or ``"place"``.
        times: (T,) sample times (s), 0 when the hand starts moving.
        ee_commanded: (T, 3) commanded world ``(x, z, phi)`` of the tcp.
        ee_actual: (T, 3) actual world ``(x, z, phi)``; the difference is the reaction.
        opening_commanded: (T,) commanded gap between the finger pads (m).
        opening_actual: (T,) actual gap (m).
        objects: (T, K, 3) world ``(x, z, phi)`` of the objects.
        state_before: (K, 3) object poses when the hand starts moving (after the settle).
        state_after: (K, 3) object poses at the end.
        grasped: Pick: the object ends squeezed between both finger pads, off the table and
            other objects; place: it was held between the pads until the release.
        lifted: Pick: grasped and raised by at least half the lift.
        slipped: The held object moved relative to the hand by more than the world's slip
            tolerance while it should have been held (or fell out). Pick: from the end of
            closing to the last tick, once the fingers closed on it (whether they touched it
            when closing ended or only during the lift).
        placed: Place: the object rests, released and flat, on its target top.
        q_waypoints: (K_w, dof) the arm's joint waypoints (rad).
        object_specs: The K objects' catalogue specs.
        target: Index of the picked or placed object.
    """

    skill: str
    times: np.ndarray
    ee_commanded: np.ndarray
    ee_actual: np.ndarray
    opening_commanded: np.ndarray
    opening_actual: np.ndarray
    objects: np.ndarray
    state_before: np.ndarray
    state_after: np.ndarray
    grasped: bool
    lifted: bool
    slipped: bool
    placed: bool
    q_waypoints: np.ndarray
    object_specs: tuple[ObjectSpec, ...]
    target: int


def _world(world: object) -> SideViewSpec:
    """`world`, or ``worlds/sideview.yaml`` when None; an `InputError` for another type."""
    return default_or_instance(
        "world", world, SideViewSpec, load_sideview, "a SideViewSpec (load_sideview())"
    )


def _progress(distance: float, world: SideViewSpec) -> np.ndarray:
    """(T,) fraction of a straight move covered per control tick (a single tick if none)."""
    if distance < 1e-9:
        return np.zeros(1)
    return trapezoid_progress(distance, world.speed, world.acceleration, world.physics.control_rate)


def _ramp(start: float, stop: float, n_ticks: int, n_move: int) -> np.ndarray:
    """(n_ticks,) from `start` to `stop` linearly over the first `n_move` ticks, then held."""
    n_move = max(1, min(n_move, n_ticks))
    out = np.full(n_ticks, stop)
    out[:n_move] = start + (stop - start) * np.arange(1, n_move + 1) / n_move
    return out


def _ticks(seconds: float, rate: float) -> int:
    return max(1, round(seconds * rate))


@dataclass(frozen=True)
class _Route:
    """A skill's path before IK: waypoints and, per tick, the waypoint index and opening."""

    waypoints: np.ndarray  # (K, 2) world (x, z) of the tcp
    u: np.ndarray  # (T,) fractional waypoint index per tick
    opening: np.ndarray  # (T,)
    initial_opening: float
    marks: tuple[int, int, int]


def _segment(a: np.ndarray, b: np.ndarray, arm: Arm) -> np.ndarray:
    """(n, 2) waypoints from `a` to `b`, both included, at most the IK spacing apart."""
    n = arm.waypoint_count(float(np.linalg.norm(b - a)))
    return a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)


def _pick_route(world: SideViewSpec, scene: SideViewScene, arm: Arm) -> _Route:
    p, g, rate = world.pick, world.gripper, world.physics.control_rate
    obj, pose = scene.objects[scene.target], scene.poses[scene.target]
    bottom = pose[1] - 0.5 * obj.height
    grasp = np.array([pose[0], bottom + p.grasp_fraction * obj.height])
    approach = np.array([pose[0], bottom + obj.height + p.approach_height])
    top = grasp + np.array([0.0, p.lift])
    down, up = _segment(approach, grasp, arm), _segment(grasp, top, arm)
    k1 = len(down) - 1
    s_down = _progress(float(approach[1] - grasp[1]), world)
    n_close = _ticks(p.close_time, rate)
    s_up = _progress(p.lift, world)[1:]
    n_hold = round(p.hold_time * rate)
    u = np.concatenate(
        [
            s_down * k1,
            np.full(n_close, float(k1)),
            k1 + s_up * (len(up) - 1),
            np.full(n_hold, float(k1 + len(up) - 1)),
        ]
    )
    n_move = math.ceil(g.span / (2 * g.finger_speed) * rate)
    opening = np.concatenate(
        [
            np.full(len(s_down), g.span),
            _ramp(g.span, 0.0, n_close, n_move),
            np.zeros(len(s_up) + n_hold),
        ]
    )
    close_end = len(s_down) + n_close - 1
    lift_end = close_end + len(s_up)
    return _Route(
        np.concatenate([down, up[1:]]), u, opening, g.span, (close_end, lift_end, len(u) - 1)
    )


def _place_route(world: SideViewSpec, scene: SideViewScene, arm: Arm) -> _Route:
    pl, g, rate = world.place, world.gripper, world.physics.control_rate
    obj, pose = scene.objects[scene.target], scene.poses[scene.target]
    bottom = pose[1] - 0.5 * obj.height
    start = np.array([pose[0], bottom + world.pick.grasp_fraction * obj.height])
    drop = bottom - scene.support_top - scene.release_height
    end = start - np.array([0.0, drop])
    path = _segment(start, end, arm)
    s_down = _progress(drop, world)
    n_open = _ticks(pl.open_time, rate)
    n_settle = round(pl.settle_time * rate)
    k = float(len(path) - 1)
    u = np.concatenate([s_down * k, np.full(n_open + n_settle, k)])
    width = min(obj.size[0], g.span)
    n_move = math.ceil((g.span - width) / (2 * g.finger_speed) * rate)
    opening = np.concatenate(
        [np.zeros(len(s_down)), _ramp(width, g.span, n_open + n_settle, n_move)]
    )
    return _Route(path, u, opening, width, (0, len(s_down) - 1, len(u) - 1))


def _unreachable(
    world: SideViewSpec, arm: Arm, i: int, scene: SideViewScene, xz: np.ndarray
) -> UnreachablePoseError:
    x, z = (float(v) for v in xz)
    reach = arm.sideview_reach(z, world.plane_y)
    where = (
        f"at that height the tcp reaches x in [{reach[0]:.2f}, {reach[1]:.2f}] m"
        if reach
        else "no x is reachable at that height"
    )
    what = "target" if scene.skill == "place" else "object"
    base = world.arm.base_xyz
    return UnreachablePoseError(
        f"scenes[{i}]: the {scene.skill} {what} needs the tcp at world (x={x:.3f}, z={z:.3f}), "
        f"outside the arm's reachable workspace; {where} (arm base at x={base[0]:.2f}, "
        f"y={base[1]:.2f}, z={base[2]:.2f}). Move the {what} towards the arm."
    )


def _check_scenes(scenes: Sequence[SideViewScene]) -> list[SideViewScene]:
    how = "see sample_sideview_scenes or SideViewScene.nominal"
    out = check_items("scenes", scenes, SideViewScene, how)
    for s in out:
        s.validate()
    return out


def _plan(
    world: SideViewSpec, scenes: list[SideViewScene]
) -> tuple[list[SkillPlan | None], list[tuple[int, np.ndarray]]]:
    """Plans of valid scenes (``None`` where unreachable) and the failures ``(i, (x, z))``."""
    arm = load_arm(world.arm)
    routes = [(_pick_route if s.skill == "pick" else _place_route)(world, s, arm) for s in scenes]
    K = max(len(r.waypoints) for r in routes)
    xz = np.stack(
        [
            np.concatenate([r.waypoints, np.repeat(r.waypoints[-1:], K - len(r.waypoints), 0)])
            for r in routes
        ]
    )
    # FK once per distinct waypoint index of a path: the holds of a skill share one pose
    distinct = [np.unique(r.u, return_inverse=True) for r in routes]
    U = max(len(d[0]) for d in distinct)
    u = np.stack([np.concatenate([d[0], np.full(U - len(d[0]), d[0][-1])]) for d in distinct])
    sol = arm.solve_sideview_paths(torch.as_tensor(xz), world.plane_y)
    traced = arm.sideview_trace(sol.q, torch.as_tensor(u)).numpy()
    q = sol.q.numpy()
    plans: list[SkillPlan | None] = []
    failures = []
    for i, (s, r) in enumerate(zip(scenes, routes, strict=True)):
        if not bool(sol.ok[i]):
            plans.append(None)
            failures.append((i, xz[i, int(sol.first_bad[i])]))
            continue
        n = len(r.waypoints)
        plans.append(
            SkillPlan(
                s.skill,
                q[i, :n],
                traced[i, distinct[i][1].reshape(-1)],
                r.opening,
                r.initial_opening,
                r.marks,
            )
        )
    return plans, failures


def plan_skills(
    scenes: Sequence[SideViewScene], world: SideViewSpec | None = None
) -> list[SkillPlan]:
    """Solve the arm's motion for a batch of skills, with one batched IK call.

    Args:
        scenes: B pick or place scenes.
        world: The side-view world; defaults to ``worlds/sideview.yaml``.

    Returns:
        One plan per scene, in order.

    Raises:
        InputError: If `scenes` is not a non-empty list of valid `SideViewScene`.
        UnreachablePoseError: Naming the first scene, and the tcp position, the arm cannot
            reach, with the reachable x range at that height.
    """
    world = _world(world)
    scenes = _check_scenes(scenes)
    plans, failures = _plan(world, scenes)
    if failures:
        i, xz = failures[0]
        raise _unreachable(world, load_arm(world.arm), i, scenes[i], xz)
    return [p for p in plans if p is not None]


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


def _between(scene: SideViewScene, run: SideViewRun, row: int) -> bool:
    """Whether the target is squeezed between both finger pads at snapshot `row`."""
    k = scene.target
    obj = scene.objects[k]
    a = run.snap_objects[row, k, 2] - run.snap_hand[row, 2]
    width = obj.size[0] * abs(math.cos(a)) + obj.height * abs(math.sin(a))
    return bool(
        run.snap_fingers[row, k] == 2 and abs(run.snap_opening[row] - width) <= _BETWEEN_TOL
    )


def _pick_flags(
    world: SideViewSpec, scene: SideViewScene, run: SideViewRun
) -> tuple[bool, bool, bool, bool]:
    """Pick flags from a run with a snapshot at every tick from the end of closing on.

    The fingers may still be closing when the lift starts (a narrow object is reached a few
    ticks late, later still with a weak squeeze), so slip is not judged from the contacts at
    the end of closing alone: the object slipped when the fingers closed on it at some tick
    (it was squeezed between both pads) and, from the end of closing to the last tick, it
    moved relative to the hand by more than the slip tolerance, or it ended not held.

    Args:
        world: The side-view world.
        scene: The pick scene.
        run: Its run; snapshot row 0 is the end of closing, the last row the last tick.
    """
    k = scene.target
    end = len(run.snap_hand) - 1
    grasped = _between(scene, run, end) and not bool(run.snap_supported[end, k])
    rise = run.state_after[k, 1] - run.state_before[k, 1]
    lifted = grasped and rise >= 0.5 * world.pick.lift
    rel = run.snap_objects[:, k, :2] - run.snap_hand[:, :2]
    drift = float(np.linalg.norm(rel - rel[0], axis=1).max())
    closed_on = any(_between(scene, run, row) for row in range(end + 1))
    slipped = bool(closed_on and (drift > world.slip_tolerance or not grasped))
    return grasped, bool(lifted), slipped, False


def _place_flags(
    world: SideViewSpec, scene: SideViewScene, run: SideViewRun
) -> tuple[bool, bool, bool, bool]:
    k = scene.target
    start, release = 0, 1
    grasped = _between(scene, run, start) and _between(scene, run, release)
    rel_start = run.snap_objects[start, k, :2] - run.snap_hand[start, :2]
    rel_release = run.snap_objects[release, k, :2] - run.snap_hand[release, :2]
    slipped = float(np.linalg.norm(rel_release - rel_start)) > world.slip_tolerance
    obj = scene.objects[k]
    if scene.support < 0:
        top, half_width, cx = 0.0, 0.5 * world.table_length, 0.0
    else:
        sup = scene.objects[scene.support]
        top = run.state_after[scene.support, 1] + 0.5 * sup.height
        half_width, cx = 0.5 * sup.size[0], run.state_after[scene.support, 0]
    x, z, phi = run.state_after[k]
    placed = (
        abs(z - (top + 0.5 * obj.height)) <= world.place_tolerance
        and abs(x - cx) <= half_width
        and abs(_wrap(phi)) <= _PLACE_MAX_TILT
        and run.snap_fingers[2, k] == 0
    )
    return grasped, False, bool(slipped), bool(placed)


def simulate_skill(
    scene: SideViewScene, plan: SkillPlan, world: SideViewSpec | None = None
) -> SkillOutcome:
    """Simulate one planned skill.

    Args:
        scene: The scene the plan was made for.
        plan: Its plan (`plan_skills`); a plan can be simulated in worlds that differ in
            their physical parameters (e.g. the squeeze force).
        world: The side-view world; defaults to ``worlds/sideview.yaml``.

    Returns:
        The skill's outcome.

    Raises:
        InputError: If `scene` is invalid or `plan` belongs to another skill.
    """
    world = _world(world)
    if not isinstance(scene, SideViewScene) or not isinstance(plan, SkillPlan):
        raise InputError("simulate_skill needs a SideViewScene and its SkillPlan (plan_skills).")
    if plan.skill != scene.skill:
        raise InputError(f"plan is for a {plan.skill}, but scene is a {scene.skill}.")
    if scene.skill == "pick":
        close, _, last = plan.marks
        run = simulate_sideview(
            world,
            scene,
            plan.hand_path,
            plan.opening,
            plan.initial_opening,
            range(close, last + 1),
        )
        flags = _pick_flags(world, scene, run)
    else:
        run = simulate_sideview(
            world, scene, plan.hand_path, plan.opening, plan.initial_opening, plan.marks
        )
        flags = _place_flags(world, scene, run)
    return SkillOutcome(
        skill=scene.skill,
        times=run.times,
        ee_commanded=run.hand_commanded,
        ee_actual=run.hand,
        opening_commanded=run.opening_commanded,
        opening_actual=run.opening,
        objects=run.objects,
        state_before=run.state_before,
        state_after=run.state_after,
        grasped=flags[0],
        lifted=flags[1],
        slipped=flags[2],
        placed=flags[3],
        q_waypoints=plan.q_waypoints,
        object_specs=scene.objects,
        target=scene.target,
    )


def run_skills(
    scenes: Sequence[SideViewScene], world: SideViewSpec | None = None
) -> list[SkillOutcome]:
    """Plan (one batched IK call) and simulate a batch of pick or place scenes.

    Args:
        scenes: B scenes; picks and places may be mixed.
        world: The side-view world; defaults to ``worlds/sideview.yaml``.

    Returns:
        One outcome per scene, in order.

    Raises:
        InputError: For an invalid scene.
        UnreachablePoseError: Naming the first scene the arm cannot execute.
    """
    world = _world(world)
    plans = plan_skills(scenes, world)
    return [simulate_skill(s, p, world) for s, p in zip(scenes, plans, strict=True)]


def _single(scene: SideViewScene, skill: str, world: SideViewSpec | None) -> SkillOutcome:
    check_type("scene", scene, SideViewScene)
    if scene.skill != skill:
        raise InputError(f"scene is a {scene.skill} scene; {skill} needs a {skill} scene.")
    return run_skills([scene], world)[0]


def pick(scene: SideViewScene, world: SideViewSpec | None = None) -> SkillOutcome:
    """Pick ``scene.objects[scene.target]`` (see `run_skills`)."""
    return _single(scene, "pick", world)


def place(scene: SideViewScene, world: SideViewSpec | None = None) -> SkillOutcome:
    """Place the held ``scene.objects[scene.target]`` on its support (see `run_skills`)."""
    return _single(scene, "place", world)


def _draw(
    spec: SideViewSceneSpec, world: SideViewSpec, rng: np.random.Generator
) -> SideViewScene | None:
    """One scene, or ``None`` if the draw is invalid (overlap, too close, off the table)."""
    objs: list[ObjectSpec] = []
    poses: list[tuple[float, float, float]] = []
    index: dict[int, int] = {}  # placement index -> object index
    below: list[int] = []  # per object: the index of its support, -1 for the table
    for i, pl in enumerate(spec.objects):
        present = rng.random() < pl.probability
        obj = pl.choices[int(rng.integers(len(pl.choices)))]
        dx = draw_in_range(rng, pl.x)
        if not present or (pl.on is not None and pl.on not in index):
            continue
        if pl.on is None:
            x, z, sup = dx, 0.5 * obj.height, -1
        else:
            sup = index[pl.on]
            x = poses[sup][0] + dx
            z = poses[sup][1] + 0.5 * objs[sup].height + 0.5 * obj.height
        index[i] = len(objs)
        objs.append(obj)
        poses.append((x, z, 0.0))
        below.append(sup)
    for a in range(len(objs)):
        for b in range(a + 1, len(objs)):
            if below[a] == below[b]:
                free = abs(poses[a][0] - poses[b][0]) - 0.5 * (objs[a].size[0] + objs[b].size[0])
                if free < spec.gap:
                    return None
    last = len(objs) - 1  # nothing rests on it: only later objects are stacked on earlier ones
    if spec.skill == "pick":
        target, support, release = last, -1, 0.0
    else:
        assert spec.held is not None
        held = spec.held
        offset = draw_in_range(rng, spec.target_offset)
        table_x = draw_in_range(rng, spec.table_x)
        release = draw_in_range(rng, world.place.release_height)
        support = last
        if support < 0:
            x, top = table_x, 0.0
        else:
            x, top = poses[support][0] + offset, poses[support][1] + 0.5 * objs[support].height
        objs.append(held)
        poses.append((x, top + world.place.hold_height + 0.5 * held.height, 0.0))
        target = len(objs) - 1
    if any(abs(p[0]) > 0.5 * world.table_length for p in poses):
        return None
    try:
        return SideViewScene(
            skill=spec.skill,
            objects=tuple(objs),
            poses=np.array(poses),
            mass=np.array([o.mass for o in objs]),
            friction=np.array([o.contact_friction for o in objs]),
            target=target,
            support=support,
            release_height=release,
        )
    except InputError:
        return None


def sample_sideview_scenes(
    scene_spec: SideViewSceneSpec,
    n: int,
    rng: np.random.Generator,
    world: SideViewSpec | None = None,
) -> list[SideViewScene]:
    """Draw `n` valid scenes from a side-view template.

    Draws whose objects overlap, crowd each other (closer than the template's ``gap``) or
    leave the table are drawn again; each draw consumes a fixed pattern of `rng`, so the
    result depends only on its state. Reachability is checked later, by IK.

    Args:
        scene_spec: The template (`load_sideview_scene`).
        n: Number of scenes (an integer >= 0).
        rng: Source of randomness.
        world: The side-view world (table, place heights); defaults to
            ``worlds/sideview.yaml``.

    Returns:
        `n` scenes with the catalogue's masses and frictions.

    Raises:
        InputError: If `scene_spec` is not a template, `n` not an integer >= 0, or `rng` not
            a `numpy.random.Generator`.
        ConfigError: If valid draws are too rare.
    """
    check_type("scene_spec", scene_spec, SideViewSceneSpec, "load_sideview_scene(name)")
    n = check_count("n", n, minimum=0)
    check_rng(rng)
    world = _world(world)
    out: list[SideViewScene] = []
    draws = 0
    while len(out) < n:
        draws += 1
        if draws > _MAX_DRAWS_PER_SAMPLE * (n + 1):
            raise ConfigError(
                f"side-view scene {scene_spec.name!r}: fewer than 1 in {_MAX_DRAWS_PER_SAMPLE} "
                "draws is valid; widen its ranges or reduce its gap."
            )
        s = _draw(scene_spec, world, rng)
        if s is not None:
            out.append(s)
    return out


def run_sampled(
    scene_spec: SideViewSceneSpec,
    n: int,
    rng: np.random.Generator,
    world: SideViewSpec | None = None,
) -> list[tuple[SideViewScene, SkillOutcome]]:
    """Draw and simulate `n` reachable scenes of a template, one batched IK call per batch.

    Candidates are drawn in batches (`sample_sideview_scenes`); those the arm cannot reach are
    discarded, so the result depends only on `rng`'s state.

    Args:
        scene_spec: The template.
        n: Number of samples (an integer >= 0).
        rng: Source of randomness.
        world: The side-view world; defaults to ``worlds/sideview.yaml``.

    Returns:
        `n` pairs ``(scene, outcome)``, in order.

    Raises:
        InputError: For a bad template, `n` or `rng`.
        ConfigError: If reachable scenes are too rare.
    """
    world = _world(world)
    n = check_count("n", n, minimum=0)
    out: list[tuple[SideViewScene, SkillOutcome]] = []
    batches = 0
    while len(out) < n:
        batches += 1
        if batches > _MAX_DRAWS_PER_SAMPLE:
            raise ConfigError(
                f"side-view scene {scene_spec.name!r}: the arm reaches too few of its draws; "
                "move its objects towards the arm."
            )
        want = n - len(out)
        scenes = sample_sideview_scenes(scene_spec, math.ceil(1.2 * want) + 1, rng, world)
        plans, _ = _plan(world, scenes)
        for s, p in zip(scenes, plans, strict=True):
            if p is not None and len(out) < n:
                out.append((s, simulate_skill(s, p, world)))
    return out
