"""`probaff demo`'s affordance-map part: one small map explored, pushed by information gain."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Any

import numpy as np

from probaff._checks import check_count
from probaff.experiments.affordance_map.config import world
from probaff.experiments.affordance_map.figures import plot_loop_steps
from probaff.experiments.affordance_map.run import STREAM_LOOP, STREAM_TEST, train_classifier
from probaff.perception.exploration import explore
from probaff.planning import ManipulationLoop
from probaff.sim import generate_map

__all__ = ["demo"]


def demo(
    out_dir: str | os.PathLike[str],
    seed: int = 0,
    steps: int = 4,
    train_maps: int = 2,
    sensor: str | None = None,
) -> dict[str, Any]:
    """Explore one small map, push boxes by information gain, and report the entropy per step.

    The map is 8 x 8 cells with 8 to 14 boxes and the world file's interior walls, their
    segments scaled by area (wall blocks the sensor cannot tell from boxes), seen by the world
    file's sensor (the head camera). The classifier is trained on only `train_maps` other maps
    of that size, so that some of its predictions are unsure: that is what the loop's pushes
    are for. The loop
    pushes its best candidate `steps` times even when no push is worth its travel (the study's
    ``stop_at_no_gain=False``), so that each step's effect on the map entropy shows; a push
    that moves a box gives the box fresh, unsure variables in its new cell.

    Args:
        out_dir: Folder of the figure ``loop_steps.png`` (created).
        seed: Seed of the maps and the sensor noise (an integer >= 0).
        steps: Pushes (an integer >= 0).
        train_maps: Maps the classifier is trained on (a positive integer).
        sensor: One of `SENSOR_KINDS`; None keeps the world file's.

    Returns:
        ``{"entropy", "accuracy", "pushes", "moved", "stop", "figure", "walls", "boxes"}``:
        the map entropy (nats) and the MAP accuracy at each step (``steps + 1`` values), the
        pushes ``[row, col, direction]``, whether each moved its box, the stop reason, and the
        map's interior wall blocks and boxes ``[row, col]``.

    Raises:
        InputError: If `seed` or `steps` is not an integer >= 0, `train_maps` not a positive
            integer, or `sensor` unknown.
    """
    seed = check_count("seed", seed, minimum=0)
    steps = check_count("steps", steps, minimum=0)
    train_maps = check_count("train_maps", train_maps)
    full = world(sensor=sensor)
    scale = 64 / (full.rows * full.cols)
    spec = dataclasses.replace(
        full,
        rows=8,
        cols=8,
        boxes=(8, 14),
        wall_segments=(
            round(full.wall_segments[0] * scale),
            round(full.wall_segments[1] * scale),
        ),
        wall_blocks=(),
    )
    classifier, _ = train_classifier(spec, train_maps, seed)
    rng = np.random.default_rng((seed, STREAM_TEST, 0))
    m = generate_map(spec, rng)
    free = np.argwhere(~m.occupancy)
    exploration = explore(spec, m, free[rng.integers(len(free))], rng)
    loop = ManipulationLoop(
        spec,
        m,
        exploration,
        classifier,
        rng=np.random.default_rng((seed, STREAM_LOOP, 0)),
        stop_at_no_gain=False,
    )
    result = loop.run(steps, snapshots=steps + 1)
    figure = Path(out_dir) / "loop_steps.png"
    plot_loop_steps(
        result.snapshots, figure, title="information-gain loop on a small map", walls=m.walls
    )
    entropy = [s.entropy for s in result.steps]
    accuracy = [s.accuracy for s in result.steps]
    done = [s for s in result.steps[1:] if s.push is not None]
    pushes = [list(s.push) for s in done if s.push is not None]
    moved = [bool(s.moved) for s in done]
    trail = " -> ".join(f"{h:.2f}" for h in entropy)
    print(
        f"map entropy by step (nats, classifier trained on {train_maps} maps): {trail}; "
        f"{len(pushes)} push(es), {sum(moved)} moved a box (stop: {result.stop}); the map "
        f"holds {int(m.movable.sum())} boxes and {int(m.walls.sum())} interior wall blocks"
    )
    print(f"MAP accuracy: {accuracy[0]:.3f} -> {accuracy[-1]:.3f}; figure: {os.fspath(figure)}")
    return {
        "entropy": entropy,
        "accuracy": accuracy,
        "pushes": pushes,
        "moved": moved,
        "stop": result.stop,
        "figure": os.fspath(figure),
        "walls": np.argwhere(m.walls).tolist(),
        "boxes": np.argwhere(m.movable).tolist(),
    }
