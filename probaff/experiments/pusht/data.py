"""Random pushes in gym-pusht, recorded as an observation-only probaff push dataset.

`record_chunk` (a study task) resets the environment with a seed drawn from its own seed, and
runs random push primitives (`probaff.experiments.pusht.primitives.sample_primitives`) one after
another, logging for each what a robot would: the block's pose when the push starts and when it
ends, where the pusher started and in which direction it went how far. A new episode starts
when the next push would run past the environment's 300-step limit or the block nears a wall.
`push_dataset` turns the records into a `probaff.data.PushDataset` with
`probaff.data.observation_dataset` (metres and radians, `PX` metres per pixel, the T's outline
as its cloud), so everything probaff reads of a push dataset reads it.

Each chunk's seed is ``SeedSequence(seed, spawn_key=(role, chunk))``, so a dataset of N pushes
is the first N pushes of any larger one with the same seed, and chunks are resumable tasks.

Two ways to log the block's pose (`OBSERVATIONS`). ``"state"`` reads it off the simulator's
state, in gym-pusht's T frame. ``"pixels"`` logs what a robot with a camera would: every pose
of a push is perceived (`probaff.experiments.pusht.observe.PixelObserver`) from gym-pusht's own
96 x 96 ``pixels_agent_pos`` image, in the frame of the T perceived from the episode's first
frames (its centre of gravity that of a uniform outline; `TeeGeometry.from_shape`), which is the
frame the planner plans in from pixels; primitives are drawn and run on that perceived T.
Where a frame cannot be read it is handled as a robot would: a push whose start cannot be read
is run but dropped (backing away would undo its approach); after a push whose end cannot be
read the pusher backs away and looks again, and the push is dropped if the block still cannot
be read; an episode whose first frames show no T is reset again. Each drop is counted. The
state is still logged beside the perceived poses (``truth_before``, ``truth_after``, in the same
T frame), for scoring the perception only (`perception_errors`): the features and the effects
are computed from the perceived poses alone, and the dataset says so (``meta["observation"]``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import cache
from typing import Any

import numpy as np

from probaff.data import PushDataset, observation_dataset
from probaff.errors import InputError
from probaff.experiments.pusht.env import PushTEnvError, PushTWorker
from probaff.experiments.pusht.geometry import (
    GYM_TEE,
    OUTLINE,
    PX,
    TeeGeometry,
    cog_pose,
    contact_points,
    origin_pose,
    to_world,
)
from probaff.experiments.pusht.observe import OBSERVATIONS, Observed, PixelObserver
from probaff.experiments.pusht.perception import PerceptionOptions
from probaff.experiments.pusht.pixels import FRAME_SIZE, WORLD_SIZE
from probaff.experiments.pusht.primitives import (
    PrimitiveSettings,
    primitive_actions,
    push_frames,
    sample_primitives,
)
from probaff.experiments.pusht.template import TeeShape

__all__ = [
    "OBJECT_NAMES",
    "Chooser",
    "chunk_rng",
    "dataset_observation",
    "perception_errors",
    "push_dataset",
    "record_chunk",
    "record_pushes",
    "with_worker",
    "worker",
]

OBJECT_NAMES = ("pusht_tee",)
"""The dataset's object vocabulary: the T."""
_MAX_STEPS = 300
_CLOUD_POINTS = 48
_HEIGHT = 0.03  # m, the cloud's height above the table (the T is planar)
_ROLES = {"train": 0, "test": 1}
_PER_PUSH = ("before", "after", "origin", "yaw", "dist", "approach_moved")
_PIXEL_PER_PUSH = ("truth_before", "truth_after", "shape")
_MAX_LOST_RESETS = 20  # resets in a row whose first frames show no T before giving up


@cache
def worker(python: str | None) -> PushTWorker:
    """This process's Push-T worker (started once; restarted by `with_worker`)."""
    return PushTWorker(python)


def with_worker(python: str | None, fn: Any, *args: Any) -> Any:
    """``fn(worker, *args)``, run again once on a fresh worker if the worker died.

    A task is deterministic given its arguments, so running it again from its start gives
    the result it would have given; nothing is stored until it returns.

    Raises:
        PushTEnvError: If the worker dies twice, or answers with an error.
    """
    w = worker(python)
    if not w.alive:
        w.start()
    try:
        return fn(w, *args)
    except PushTEnvError:
        if w.alive:
            raise
        w.start()
        return fn(w, *args)


def chunk_rng(seed: int, role: str, chunk: int) -> np.random.Generator:
    """The random generator of one chunk of pushes (`role` is ``"train"`` or ``"test"``)."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(_ROLES[role], chunk)))


def _near_wall(pose: np.ndarray) -> bool:
    return bool(np.any(pose[:2] < 80.0) or np.any(pose[:2] > 432.0))


Chooser = Callable[[np.random.Generator, np.ndarray, np.ndarray], np.ndarray]
"""``choose(rng, pose, agent)``: the (3,) primitive to run from the T's (3,) centre-of-gravity
pose and the agent's (2,) position (px)."""


def record_pushes(
    w: PushTWorker,
    rng: np.random.Generator,
    n: int,
    s: PrimitiveSettings,
    choose: Chooser | None = None,
    *,
    observation: str = "state",
    perception: PerceptionOptions | None = None,
) -> dict[str, Any]:
    """`n` pushes, each new episode reset from `rng`.

    A reset whenever the next push could outrun the limit or the T nears a wall.

    Args:
        w: The Push-T worker.
        rng: The resets' seeds and the random pushes.
        n: Pushes to record.
        s: The primitives' settings.
        choose: Picks each push; random ones (`sample_primitives`) when None.
        observation: Where the block's poses come from: ``"state"`` (the simulator's state)
            or ``"pixels"`` (perceived from the 96 x 96 image; the module docstring).
        perception: Perception settings (``"pixels"`` only).

    Returns:
        `record_chunk`'s lists.

    Raises:
        InputError: For an unknown `observation`.
        PushTEnvError: From the worker, or if `_MAX_LOST_RESETS` resets in a row show no T.
    """
    if _check_observation(observation) == "state":
        return _record_state(w, rng, n, s, choose)
    return _record_pixels(w, rng, n, s, choose, perception)


def _check_observation(observation: Any) -> str:
    """`observation`, if it is one of `OBSERVATIONS`.

    Raises:
        InputError: Otherwise.
    """
    if observation not in OBSERVATIONS:
        raise InputError(
            f"observation must be one of {list(OBSERVATIONS)}, got {observation!r}; pass "
            "'pixels' to record the pushes from perceived poses."
        )
    return str(observation)


def _record_state(
    w: PushTWorker,
    rng: np.random.Generator,
    n: int,
    s: PrimitiveSettings,
    choose: Chooser | None,
) -> dict[str, Any]:
    """`record_pushes` from the simulator's state."""
    rows: dict[str, list[Any]] = {k: [] for k in _PER_PUSH}
    state: dict[str, Any] = {}
    steps = _MAX_STEPS
    while len(rows["before"]) < n:
        if steps > _MAX_STEPS - 40 or _near_wall(cog_pose(np.array(state["block"]))):
            state = w.ask("reset", seed=int(rng.integers(2**31)))
            steps = 0
        pose = cog_pose(np.array(state["block"]))
        agent = np.array(state["agent"])
        prim = sample_primitives(rng, 1, s)[0] if choose is None else choose(rng, pose, agent)
        plan = primitive_actions(pose, agent, prim, s)
        if not plan.feasible or steps + len(plan.actions) > _MAX_STEPS:
            steps = _MAX_STEPS if plan.feasible else steps
            continue
        approach = w.ask("step", actions=plan.actions[: plan.push_start].tolist())
        state = w.ask("step", actions=plan.actions[plan.push_start :].tolist())
        steps = int(state["steps"])
        if state["terminated"] or state["truncated"]:
            steps = _MAX_STEPS
            continue
        before = cog_pose(np.array(approach["block"]))
        _append_push(rows, prim, pose, before, cog_pose(np.array(state["block"])), s, GYM_TEE)
    return rows


def _append_push(
    rows: dict[str, list[Any]],
    prim: np.ndarray,
    pose: np.ndarray,
    before: np.ndarray,
    after: np.ndarray,
    s: PrimitiveSettings,
    tee: TeeGeometry,
) -> None:
    """Append one push's `_PER_PUSH` entries to `rows`.

    Args:
        rows: The lists being recorded, keyed by `_PER_PUSH` (and more).
        prim: (3,) the push's primitive.
        pose: (3,) the block's pose (px, rad) when the primitive was chosen.
        before: (3,) its pose at the push's start, after the approach.
        after: (3,) its pose at the push's end.
        s: The primitives' settings.
        tee: The T the primitive was drawn on.
    """
    geo = push_frames(prim[None], s, tee)
    rows["before"].append(before.tolist())
    rows["after"].append(after.tolist())
    rows["origin"].append(to_world(before, geo["start"])[0].tolist())
    rows["yaw"].append(float(before[2] + geo["yaw"][0]))
    rows["dist"].append(float(s.gap + prim[2]))
    rows["approach_moved"].append(float(np.abs(before[:2] - pose[:2]).max()))


def _in_frame(truth: np.ndarray, tee: TeeGeometry) -> list[float]:
    """The state's (3,) gym-pusht centre-of-gravity pose as the centre of gravity of `tee`."""
    return [float(v) for v in cog_pose(origin_pose(truth, GYM_TEE), tee)]


def _record_pixels(
    w: PushTWorker,
    rng: np.random.Generator,
    n: int,
    s: PrimitiveSettings,
    choose: Chooser | None,
    options: PerceptionOptions | None,
) -> dict[str, Any]:
    """`record_pushes` from perceived poses (the module docstring); the state for scoring only."""
    eye = PixelObserver(w, options)
    keys = (*_PER_PUSH, *_PIXEL_PER_PUSH)
    rows: dict[str, list[Any]] = {k: [] for k in keys}
    counts = dict.fromkeys(
        ("lost_resets", "dropped_start", "dropped_end", "flagged", "retreats"), 0
    )
    seen: Observed | None = None
    steps, lost_in_row = _MAX_STEPS, 0

    def tally() -> None:  # the observer's counts of the episode that ends
        log = eye.record()
        counts["flagged"] += int(log["flagged"])
        counts["retreats"] += int(log["retreats"])

    while len(rows["before"]) < n:
        if seen is None or seen.lost or steps > _MAX_STEPS - 40 or _near_wall(seen.pose):
            if seen is not None:
                tally()
            seen = eye.reset(int(rng.integers(2**31)))
            steps = seen.steps
            if seen.lost:  # the first frames show no T: another episode
                counts["lost_resets"] += 1
                lost_in_row += 1
                if lost_in_row >= _MAX_LOST_RESETS:
                    raise PushTEnvError(
                        f"{lost_in_row} resets in a row showed no T that could be perceived; "
                        "check the worker's obs_type='pixels_agent_pos' images, or record "
                        "with observation='state'."
                    )
                continue
            lost_in_row = 0
        pose, agent, tee = seen.pose, seen.agent, eye.tee
        prim = sample_primitives(rng, 1, s, tee)[0] if choose is None else choose(rng, pose, agent)
        plan = primitive_actions(pose, agent, prim, s, tee)
        if not plan.feasible or steps + len(plan.actions) > _MAX_STEPS:
            steps = _MAX_STEPS if plan.feasible else steps
            continue
        # the push's start is read where it is: backing away would undo the approach
        start = eye.look(plan.actions[: plan.push_start]) if plan.push_start else seen
        seen = eye.step(plan.actions[plan.push_start :])
        steps = seen.steps
        if seen.terminated or seen.truncated:
            steps = _MAX_STEPS
            continue
        if start.lost or seen.lost:  # never filled in from the state: dropped, counted
            counts["dropped_start" if start.lost else "dropped_end"] += 1
            continue
        before, after = start.pose, seen.pose.copy()
        turn = after[2] - before[2]  # perceived angles are wrapped: unwrap along the push
        after[2] = before[2] + math.atan2(math.sin(turn), math.cos(turn))
        _append_push(rows, prim, pose, before, after, s, tee)
        rows["truth_before"].append(_in_frame(start.truth, tee))
        rows["truth_after"].append(_in_frame(seen.truth, tee))
        assert eye.scene is not None  # perceived at the reset, or the reset was lost
        rows["shape"].append([float(v) for v in eye.scene.shape.as_array()])
    tally()
    return {**rows, "perception": {"observation": "pixels", **counts}}


def record_chunk(
    role: str,
    chunk: int,
    seed: int,
    n: int,
    *,
    settings: PrimitiveSettings,
    python: str | None,
    observation: str = "state",
) -> dict[str, Any]:
    """Record one chunk of `n` random pushes (a study task; Dask workers import it).

    Args:
        role: ``"train"`` or ``"test"`` (independent seeds).
        chunk: The chunk's index.
        seed: The study's seed.
        n: Pushes in the chunk.
        settings: The primitives' settings.
        python: The Push-T environment's Python (`probaff.experiments.pusht.env.pusht_python`).
        observation: Where the poses come from: ``"state"`` or ``"pixels"`` (`record_pushes`).

    Returns:
        Lists (px, rad), one entry per push: ``before`` and ``after`` centre-of-gravity poses,
        the pusher's world start ``origin``, the push's world ``yaw``, its target travel
        ``dist``, and ``approach_moved``, how far (px) the block moved while the pusher went
        around it. From pixels the poses are the perceived ones, in the perceived T's frame,
        and the chunk also holds ``truth_before`` and ``truth_after`` (the state's poses in
        that frame, for scoring only), ``shape`` (the perceived T's (4,) bar length, bar
        width, stem width, stem length) and ``perception`` (``{"observation": "pixels"}``
        and the counts of resets lost, pushes dropped at their start or end, frames flagged
        and retreats).
    """
    _check_observation(observation)  # before a worker is started
    return dict(with_worker(python, _record, (seed, role, chunk), n, settings, observation))


def _record(
    w: PushTWorker, key: tuple[int, str, int], n: int, s: PrimitiveSettings, observation: str
) -> dict[str, Any]:
    """`record_pushes` from the chunk's own generator, drawn afresh on every try."""
    return record_pushes(w, chunk_rng(*key), n, s, observation=observation)


def _outline_cloud(poses: np.ndarray, tee: TeeGeometry = GYM_TEE) -> tuple[np.ndarray, np.ndarray]:
    """(N, 1, P, 3) outline points (m) and unit normals of `tee` at (N, 3) `poses` (px)."""
    pts, nrm = contact_points(np.linspace(0.0, tee.perimeter, _CLOUD_POINTS, endpoint=False), tee)
    world = to_world(poses, np.broadcast_to(pts, (len(poses), *pts.shape)))
    c, s = np.cos(poses[:, 2:3]), np.sin(poses[:, 2:3])
    normals = np.stack([c * nrm[:, 0] - s * nrm[:, 1], s * nrm[:, 0] + c * nrm[:, 1]], axis=-1)
    z = np.zeros((*world.shape[:2], 1))
    points = np.concatenate([world * PX, z + _HEIGHT], axis=-1)[:, None]
    return points, np.concatenate([normals, z], axis=-1)[:, None]


def _records_observation(records: list[dict[str, Any]]) -> str:
    """``"pixels"`` if every chunk was recorded from pixels, ``"state"`` if none was.

    Raises:
        InputError: For no records, or a mix of both.
    """
    if not records:
        raise InputError("records must hold at least one record_chunk result, got none.")
    kinds = {"pixels" if "perception" in r else "state" for r in records}
    if len(kinds) > 1:
        raise InputError(
            "records mix chunks recorded from the state and from pixels; build one dataset "
            "per observation (record_chunk(..., observation=...))."
        )
    return kinds.pop()


def push_dataset(records: list[dict[str, Any]], seed: int, *, truth: bool = False) -> PushDataset:
    """The chunks' pushes as one observation-only push dataset (metres and radians).

    Args:
        records: `record_chunk` results, in order, all from the state or all from pixels.
        seed: The study's seed (kept in the dataset's meta).
        truth: For chunks recorded from pixels, build the dataset of the state's poses logged
            beside the perceived ones (``truth_before``, ``truth_after``; for scoring the
            perception only, never to fit on) instead of the perceived poses.

    Returns:
        The dataset: one object (the T), its centre-of-gravity poses, the pushes, and the
        T's outline as its cloud (from pixels, each push's perceived T). ``meta`` holds
        ``observation`` (``"state"`` or ``"pixels"``: where the poses come from, see
        `dataset_observation`) and ``poses`` (``"state"``, ``"perceived"`` or
        ``"state_beside_perceived"`` when `truth`).

    Raises:
        InputError: For no records, a mix of state and pixel records, or `truth` with
            records from the state.
    """
    observation = _records_observation(records)
    if truth and observation != "pixels":
        raise InputError(
            "truth=True needs records from pixels (record_chunk(..., observation='pixels')): "
            "records from the state hold no perceived poses beside the state's."
        )
    keys = [k for k in records[0] if isinstance(records[0][k], list)]
    cat = {k: np.concatenate([np.asarray(r[k], dtype=float) for r in records]) for k in keys}
    before, after = cat["before"], cat["after"]
    if truth:
        before, after = cat["truth_before"], cat["truth_after"]
    if observation == "pixels":  # each push's own perceived T
        tees = [TeeGeometry.from_shape(TeeShape(*row)) for row in cat["shape"]]
        clouds = [_outline_cloud(b[None], tee) for b, tee in zip(before, tees, strict=True)]
        points = np.concatenate([c[0] for c in clouds])
        normals = np.concatenate([c[1] for c in clouds])
        outline = np.median([tee.outline for tee in tees], axis=0)
    else:
        points, normals = _outline_cloud(before)
        outline = OUTLINE
    arrays = {
        "object_ids": np.zeros((len(before), 1), dtype=np.int16),
        "state_before": (before * [PX, PX, 1.0])[:, None],
        "state_after": (after * [PX, PX, 1.0])[:, None],
        "push_origin": cat["origin"] * PX,
        "push_yaw": cat["yaw"],
        "push_distance": cat["dist"] * PX,
        "cloud_points": points,
        "cloud_normals": normals,
    }
    meta: dict[str, Any] = {
        "scene": "pusht",
        "seed": int(seed),
        "outline_px": np.asarray(outline).tolist(),
        "px_m": PX,
        "observation": observation,
        "poses": "state" if observation == "state" else "perceived",
    }
    if observation == "pixels":
        meta["perception"] = _summed_counts(records)
        meta["poses"] = "state_beside_perceived" if truth else "perceived"
    return observation_dataset(arrays, list(OBJECT_NAMES), meta)


def _summed_counts(records: list[dict[str, Any]]) -> dict[str, int]:
    """The pixel chunks' counts of lost resets, dropped pushes, flagged frames and retreats."""
    out: dict[str, int] = {}
    for r in records:
        for k, v in r["perception"].items():
            if k != "observation":
                out[k] = out.get(k, 0) + int(v)
    return out


def dataset_observation(ds: PushDataset) -> str:
    """Where a Push-T dataset's poses come from: ``"state"`` or ``"pixels"`` (perceived).

    Datasets written before the field existed were all recorded from the state.

    Raises:
        InputError: For a dataset whose ``meta["observation"]`` is neither.
    """
    observation = ds.meta.get("observation", "state")
    if observation not in OBSERVATIONS:
        raise InputError(
            f"dataset meta['observation'] must be one of {list(OBSERVATIONS)}, got "
            f"{observation!r}; record it with record_chunk(..., observation=...)."
        )
    return str(observation)


def perception_errors(records: list[dict[str, Any]]) -> dict[str, np.ndarray]:
    """Errors of the perceived pushes against the state logged beside them (scoring only).

    Both are in the perceived T's frame (`record_chunk`), so that the error is the
    perception's alone, not the difference of two T's centres of gravity.

    Args:
        records: `record_chunk` results recorded from pixels.

    Returns:
        Per push, (N,) arrays: ``pose_px`` and ``pose_deg`` (distance of the perceived
        centre of gravity from the state's, in pixels of the 96 x 96 image, and angle error
        in degrees, both over the poses before and after each push, so (2N,)), and ``effect_y``,
        ``effect_z`` (px of the image) and ``effect_deg``: errors of the pushing-frame effect
        ``(dy_p, dz_p, dtheta)`` the model learns; ``start_px``, the error of the push's start
        in the block frame (a feature).

    Raises:
        InputError: For records from the state, or whose logged state is not finite.
    """
    from probaff.experiments.pusht.models import push_effects, push_features

    if _records_observation(records) != "pixels":
        raise InputError(
            "perception_errors needs records from pixels (record_chunk(..., "
            "observation='pixels')): records from the state hold no perceived poses."
        )
    seen = push_dataset(records, 0)
    logged = np.concatenate([np.asarray(r[k], float) for r in records for k in _PIXEL_PER_PUSH[:2]])
    if not np.all(np.isfinite(logged)):
        raise InputError(
            "records hold no finite state beside the perceived poses (truth_before, "
            "truth_after): there is nothing to score the perception against."
        )
    true = push_dataset(records, 0, truth=True)
    scale = FRAME_SIZE / WORLD_SIZE  # image px per world unit
    cat = {
        k: np.concatenate([np.asarray(r[k], dtype=float) for r in records])
        for k in ("before", "after", "truth_before", "truth_after")
    }
    poses = np.concatenate([cat["before"], cat["after"]])
    truths = np.concatenate([cat["truth_before"], cat["truth_after"]])
    d_angle = np.arctan2(np.sin(poses[:, 2] - truths[:, 2]), np.cos(poses[:, 2] - truths[:, 2]))
    d_effect = push_effects(seen) - push_effects(true)
    d_start = push_features(seen)[:, :2] - push_features(true)[:, :2]
    return {
        "pose_px": np.hypot(*(poses[:, :2] - truths[:, :2]).T) * scale,
        "pose_deg": np.degrees(np.abs(d_angle)),
        "effect_y": np.abs(d_effect[:, 0]) * scale,
        "effect_z": np.abs(d_effect[:, 1]) * scale,
        "effect_deg": np.degrees(np.abs(d_effect[:, 2])),
        "start_px": np.hypot(*d_start.T) * scale,
    }
