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
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cache
from typing import Any

import numpy as np

from probaff.data import PushDataset, observation_dataset
from probaff.experiments.pusht.env import PushTEnvError, PushTWorker
from probaff.experiments.pusht.geometry import (
    OUTLINE,
    PERIMETER,
    PX,
    cog_pose,
    contact_points,
    to_world,
)
from probaff.experiments.pusht.primitives import (
    PrimitiveSettings,
    primitive_actions,
    push_frames,
    sample_primitives,
)

__all__ = [
    "OBJECT_NAMES",
    "Chooser",
    "chunk_rng",
    "push_dataset",
    "record_chunk",
    "with_worker",
    "worker",
]

OBJECT_NAMES = ("pusht_tee",)
"""The dataset's object vocabulary: the T."""
_MAX_STEPS = 300
_CLOUD_POINTS = 48
_HEIGHT = 0.03  # m, the cloud's height above the table (the T is planar)
_ROLES = {"train": 0, "test": 1}


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
) -> dict[str, list[Any]]:
    """`n` pushes, each new episode reset from `rng`.

    A reset whenever the next push could outrun the limit or the T nears a wall.

    Args:
        w: The Push-T worker.
        rng: The resets' seeds and the random pushes.
        n: Pushes to record.
        s: The primitives' settings.
        choose: Picks each push; random ones (`sample_primitives`) when None.

    Returns:
        `record_chunk`'s lists.
    """
    rows: dict[str, list[Any]] = {k: [] for k in ("before", "after", "origin", "yaw", "dist")}
    moved: list[float] = []
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
        geo = push_frames(prim[None], s)
        rows["before"].append(before.tolist())
        rows["after"].append(cog_pose(np.array(state["block"])).tolist())
        rows["origin"].append(to_world(before, geo["start"])[0].tolist())
        rows["yaw"].append(float(before[2] + geo["yaw"][0]))
        rows["dist"].append(float(s.gap + prim[2]))
        moved.append(float(np.abs(before[:2] - pose[:2]).max()))
    return {**rows, "approach_moved": moved}


def record_chunk(
    role: str, chunk: int, seed: int, n: int, *, settings: PrimitiveSettings, python: str | None
) -> dict[str, Any]:
    """Record one chunk of `n` random pushes (a study task; Dask workers import it).

    Args:
        role: ``"train"`` or ``"test"`` (independent seeds).
        chunk: The chunk's index.
        seed: The study's seed.
        n: Pushes in the chunk.
        settings: The primitives' settings.
        python: The Push-T environment's Python (`probaff.experiments.pusht.env.pusht_python`).

    Returns:
        Lists (px, rad): ``before`` and ``after`` centre-of-gravity poses, the pusher's world
        start ``origin``, the push's world ``yaw``, its target travel ``dist``, and
        ``approach_moved``, how far (px) the block moved while the pusher went around it.
    """
    return dict(with_worker(python, record_pushes, chunk_rng(seed, role, chunk), n, settings))


def _outline_cloud(poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, 1, P, 3) outline points (m) and unit normals of the T at `poses` (px)."""
    pts, nrm = contact_points(np.linspace(0.0, PERIMETER, _CLOUD_POINTS, endpoint=False))
    world = to_world(poses, np.broadcast_to(pts, (len(poses), *pts.shape)))
    c, s = np.cos(poses[:, 2:3]), np.sin(poses[:, 2:3])
    normals = np.stack([c * nrm[:, 0] - s * nrm[:, 1], s * nrm[:, 0] + c * nrm[:, 1]], axis=-1)
    z = np.zeros((*world.shape[:2], 1))
    points = np.concatenate([world * PX, z + _HEIGHT], axis=-1)[:, None]
    return points, np.concatenate([normals, z], axis=-1)[:, None]


def push_dataset(records: list[dict[str, Any]], seed: int) -> PushDataset:
    """The chunks' pushes as one observation-only push dataset (metres and radians).

    Args:
        records: `record_chunk` results, in order.
        seed: The study's seed (kept in the dataset's meta).

    Returns:
        The dataset: one object (the T), its centre-of-gravity poses, the pushes, and the
        T's outline as its cloud.
    """
    cat = {k: np.concatenate([np.asarray(r[k], dtype=float) for r in records]) for k in records[0]}
    before, after = cat["before"], cat["after"]
    points, normals = _outline_cloud(before)
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
    meta = {"scene": "pusht", "seed": int(seed), "outline_px": OUTLINE.tolist(), "px_m": PX}
    return observation_dataset(arrays, list(OBJECT_NAMES), meta)
