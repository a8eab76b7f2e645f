"""Push-T perception from the diffusion policy's 96 x 96 image, scored against the state.

Each episode (reset seed ``--seed + i``) is observed as LeRobot's diffusion policy observes
it, ``obs_type="pixels_agent_pos"``, in the unmodified gym-pusht environment. The scene (the
T's outline, the goal region, the block's rim) is perceived from the episode's first frame
(`probaff.experiments.pusht.perception.perceive_scene`); then random push primitives of the
study (`sample_primitives`, `primitive_actions`) push the block, and the block's pose is read
off every frame the environment returns (`perceive_block`, a global search each frame, no
tracking), until the episode ends (its 300-step limit or its success) or the block nears a
wall. The pushes are scripted from the state; perception sees only the image.

Each frame's perceived pose is compared with the state's block pose: position error in px of
the 96 x 96 image (world units x 96 / 512) and angle error in degrees. Frames are counted as
"pusher on the T" when pusher-coloured pixels touch the block's (within one pixel): the frames
where the pusher overlaps or hides part of the T. The summary gives, over the frames the
perception accepts (status ``ok``) and over all frames: mean, median, 95th percentile and max;
the fraction of frames flagged (and why); the same for the pusher-on-the-T frames; the goal
region's pose error; the perceived outline; how often the errors lie within two of the
reported standard deviations; and seconds per frame.

Outputs in ``--out`` (default ``results/pusht_perception``): ``episodes/seed<S>.json`` (one
per episode, reused when its setup matches, so an interrupted run resumes), ``frames.csv``
(every frame) and ``summary.json``, ``summary.md``.

Usage::

    python benchmarks/pusht_perception.py [--episodes 12] [--seed 2000] [--min-frames 2000]
        [--python .venv-pusht/bin/python] [--out results/pusht_perception]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from scipy import ndimage

from probaff._checks import check_count
from probaff._cli_errors import run_cli
from probaff._io import atomic_write_text
from probaff.errors import InputError
from probaff.experiments.pusht.env import PushTWorker, pixel_observations
from probaff.experiments.pusht.geometry import cog_pose
from probaff.experiments.pusht.perception import PerceptionOptions, perceive_block, perceive_scene
from probaff.experiments.pusht.pixels import FRAME_SIZE, WORLD_SIZE, class_fractions
from probaff.experiments.pusht.primitives import (
    PrimitiveSettings,
    primitive_actions,
    sample_primitives,
)

_MAX_STEPS = 300
_VERSION = 2
_PX = FRAME_SIZE / WORLD_SIZE  # image px per world unit


def _angle_error(a: float, b: float) -> float:
    return math.degrees(math.atan2(math.sin(a - b), math.cos(a - b)))


def _pusher_on_tee(pixels: np.ndarray) -> bool:
    """Whether pusher-coloured pixels touch the block's (within one pixel)."""
    frac = class_fractions(pixels)
    block = ndimage.binary_dilation(frac[..., 2] > 0.05, iterations=1)
    return bool(np.any(block & (frac[..., 3] > 0.05)))


def _frame_row(obs: dict[str, Any], block: list[float], scene: Any, opts: Any) -> dict[str, Any]:
    t = time.perf_counter()
    est = perceive_block(obs["pixels"], scene, opts)
    seconds = time.perf_counter() - t
    err = np.asarray(est.pose[:2]) - np.asarray(block[:2])
    std = est.std()
    return {
        "status": est.status,
        "err_px": float(np.hypot(*err) * _PX),
        "err_x_px": float(err[0] * _PX),
        "err_y_px": float(err[1] * _PX),
        "err_deg": _angle_error(float(est.pose[2]), float(block[2])),
        "std_x_px": float(std[0] * _PX),
        "std_y_px": float(std[1] * _PX),
        "std_deg": float(math.degrees(std[2])),
        "pusher_on_tee": _pusher_on_tee(obs["pixels"]),
        "hidden": est.hidden,
        "mismatch": est.rms,
        "seconds": seconds,
    }


def _near_wall(block: list[float]) -> bool:
    pose = cog_pose(np.asarray(block, dtype=float))
    return bool(np.any(pose[:2] < 80.0) or np.any(pose[:2] > 432.0))


def run_episode(
    worker: PushTWorker, seed: int, opts: PerceptionOptions, settings: PrimitiveSettings
) -> dict[str, Any]:
    """One scripted-push episode: the scene from its first frame, then every frame's pose."""
    state = worker.ask("reset", seed=seed, obs_type="pixels_agent_pos")
    first = pixel_observations(state)[0]
    t = time.perf_counter()
    scene = perceive_scene(first["pixels"], opts)
    scene_seconds = time.perf_counter() - t
    goal = np.asarray(state["goal"], dtype=float)
    rows = [_frame_row(first, state["block"], scene, opts)]
    rng = np.random.default_rng(seed)
    steps, tries = 0, 0
    while steps < _MAX_STEPS and not _near_wall(state["block"]) and tries < 200:
        tries += 1
        pose = cog_pose(np.asarray(state["block"], dtype=float))
        prim = sample_primitives(rng, 1, settings)[0]
        plan = primitive_actions(pose, np.asarray(state["agent"]), prim, settings)
        if not plan.feasible:
            continue
        actions = plan.actions[: _MAX_STEPS - steps].tolist()
        state = worker.ask("step", actions=actions)
        for obs, block in zip(pixel_observations(state), _blocks(state), strict=True):
            rows.append(_frame_row(obs, block, scene, opts))
        steps = int(state["steps"])
        if state["terminated"] or state["truncated"]:
            break
    return {
        "seed": seed,
        "version": _VERSION,
        "scene_seconds": scene_seconds,
        "shape": scene.shape.as_array().tolist(),
        "block_rim": scene.block_rim,
        "goal_err_px": float(np.hypot(*(scene.goal[:2] - goal[:2])) * _PX),
        "goal_err_deg": _angle_error(float(scene.goal[2]), float(goal[2])),
        "frames": rows,
    }


def _blocks(answer: dict[str, Any]) -> list[list[float]]:
    """Each step's block pose (body origin and angle) from the logged state observations."""
    return [[float(o[2]), float(o[3]), float(o[4])] for o in answer["obs"]]


def _stats(values: np.ndarray) -> dict[str, float]:
    v = np.abs(np.asarray(values, dtype=float))
    if not v.size:
        return {"n": 0}
    return {
        "n": int(v.size),
        "mean": float(v.mean()),
        "median": float(np.median(v)),
        "p95": float(np.percentile(v, 95)),
        "max": float(v.max()),
    }


def summarise(episodes: list[dict[str, Any]]) -> dict[str, Any]:
    """The error statistics over every frame of `episodes`."""
    frames = [r for e in episodes for r in e["frames"]]
    cols = {k: np.array([r[k] for r in frames]) for k in frames[0]}
    ok = cols["status"] == "ok"
    on = cols["pusher_on_tee"].astype(bool)
    statuses, counts = np.unique(cols["status"], return_counts=True)

    def block(mask: np.ndarray) -> dict[str, Any]:
        return {"px": _stats(cols["err_px"][mask]), "deg": _stats(cols["err_deg"][mask])}

    within = {
        k: float(np.mean(np.abs(cols[f"err_{k}"][ok]) <= 2 * cols[f"std_{k}"][ok]))
        for k in ("x_px", "y_px", "deg")
    }
    shapes = np.array([e["shape"] for e in episodes])
    return {
        "episodes": len(episodes),
        "frames": len(frames),
        "accepted": block(ok),
        "all_frames": block(np.ones_like(ok)),
        "flagged_fraction": float(1 - ok.mean()),
        "statuses": {str(s): int(c) for s, c in zip(statuses, counts, strict=True)},
        "pusher_on_tee": {
            "frames": int(on.sum()),
            "flagged_fraction": float(1 - ok[on].mean()) if on.any() else 0.0,
            "accepted": block(ok & on),
            "all_frames": block(on),
        },
        "within_2_std": within,
        "goal": {
            "px": _stats(np.array([e["goal_err_px"] for e in episodes])),
            "deg": _stats(np.array([e["goal_err_deg"] for e in episodes])),
        },
        "shape_mean": shapes.mean(0).tolist(),
        "shape_std": shapes.std(0).tolist(),
        "block_rim_mean": float(np.mean([e["block_rim"] for e in episodes])),
        "seconds_per_frame": float(cols["seconds"].mean()),
        "scene_seconds": float(np.mean([e["scene_seconds"] for e in episodes])),
    }


def _markdown(s: dict[str, Any], command: str) -> str:
    def line(name: str, b: dict[str, Any]) -> str:
        px, deg = b["px"], b["deg"]
        if not px.get("n"):
            return f"| {name} | 0 | | | | | | | | |"
        return (
            f"| {name} | {px['n']} | {px['mean']:.3f} | {px['median']:.3f} | {px['p95']:.3f} | "
            f"{px['max']:.3f} | {deg['mean']:.3f} | {deg['median']:.3f} | {deg['p95']:.3f} | "
            f"{deg['max']:.3f} |"
        )

    on = s["pusher_on_tee"]
    rows = [
        "# Push-T perception from the 96 x 96 image",
        "",
        f"`{command}`",
        "",
        f"{s['frames']} frames of {s['episodes']} scripted-push episodes; "
        f"{on['frames']} with the pusher on the T. Flagged: {s['flagged_fraction']:.2%} of all "
        f"frames ({s['statuses']}), {on['flagged_fraction']:.2%} of the pusher-on-T frames.",
        "",
        "| frames | n | mean px | median px | p95 px | max px | mean deg | median deg | "
        "p95 deg | max deg |",
        "|---|---|---|---|---|---|---|---|---|---|",
        line("accepted", s["accepted"]),
        line("all (flagged too)", s["all_frames"]),
        line("pusher on T, accepted", on["accepted"]),
        line("pusher on T, all", on["all_frames"]),
        "",
        f"Errors within 2 reported std (accepted frames): {s['within_2_std']}.",
        f"Goal region: mean {s['goal']['px']['mean']:.3f} px, "
        f"{s['goal']['deg']['mean']:.3f} deg (max {s['goal']['px']['max']:.3f} px, "
        f"{s['goal']['deg']['max']:.3f} deg).",
        f"Perceived outline (bar length, bar width, stem width, stem length; world units): "
        f"{[round(v, 2) for v in s['shape_mean']]} +- {[round(v, 2) for v in s['shape_std']]}; "
        f"block rim {s['block_rim_mean']:.2f}.",
        f"Seconds per frame {s['seconds_per_frame']:.3f}; per scene {s['scene_seconds']:.2f}.",
        "",
    ]
    return "\n".join(rows)


def main() -> None:
    """Run (or resume) the episodes, then print and write the summary."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--episodes", type=int, default=12)
    ap.add_argument("--seed", type=int, default=2000)
    ap.add_argument("--min-frames", type=int, default=2000)
    ap.add_argument("--python", default=None, help="the Push-T environment's Python")
    ap.add_argument("--out", default="results/pusht_perception")
    args = ap.parse_args()
    episodes_n = check_count("--episodes", args.episodes)
    seed = check_count("--seed", args.seed, minimum=0)
    min_frames = check_count("--min-frames", args.min_frames, minimum=0)
    out = Path(args.out)
    opts, settings = PerceptionOptions(), PrimitiveSettings()
    worker = PushTWorker(args.python)
    episodes: list[dict[str, Any]] = []
    try:
        i = 0
        while i < episodes_n or sum(len(e["frames"]) for e in episodes) < min_frames:
            path = out / "episodes" / f"seed{seed + i}.json"
            record = json.loads(path.read_text()) if path.is_file() else None
            if record is None or record.get("version") != _VERSION:
                record = run_episode(worker, seed + i, opts, settings)
                atomic_write_text(path, json.dumps(record) + "\n")
            episodes.append(record)
            i += 1
            if i > 10 * max(episodes_n, 1) + 100:
                raise InputError("--min-frames is out of reach; lower it or add --episodes.")
    finally:
        worker.close()
    summary = summarise(episodes)
    command = "python benchmarks/pusht_perception.py " + " ".join(sys.argv[1:])
    frames = [{"seed": e["seed"], **r} for e in episodes for r in e["frames"]]
    header = list(frames[0])
    csv = [",".join(header)] + [",".join(str(r[k]) for k in header) for r in frames]
    atomic_write_text(out / "frames.csv", "\n".join(csv) + "\n")
    atomic_write_text(out / "summary.json", json.dumps(summary, indent=1) + "\n")
    text = _markdown(summary, command.strip())
    atomic_write_text(out / "summary.md", text)
    print(text)


if __name__ == "__main__":
    sys.exit(run_cli(main))
