"""Rays per second of the depth camera's `render`, against a plain numpy ray-plane intersection.

An office-like scene of 30 primitives (a floor, three walls, three tables of a top and four
legs, six boxes on the floor and five cylinders) is rendered by `DepthCamera.render` at the
camera's resolution (`worlds/camera.yaml`, 320 x 240 by default) from a head 1.2 m above the
floor, tilted 20 degrees down, with and without the sensor model (`--noise` off/on both
timed). For reference, the same number of rays (the same world-frame directions) is cut with
one plane in plain numpy (``t = (h - n . o) / (n . d)``, then the hit points), and the ratio
printed. Times are the best of `--repeats` runs on one thread (threadpoolctl), in wall-clock
and CPU seconds of this process.

Usage: python benchmarks/depth_camera.py [--repeats 5] [--width 320] [--height 240]
"""

import argparse

import numpy as np
import torch
from _timing import best_times
from threadpoolctl import threadpool_limits

from probaff._checks import check_count
from probaff.errors import ProbaffError
from probaff.sim.camera import DepthCamera, head_views, load_camera
from probaff.sim.primitives import PrimitiveScene


def _office() -> PrimitiveScene:
    """30 primitives: floor, 3 walls, 3 tables (top + 4 legs), 6 boxes, 5 cylinders."""
    boxes = [
        [2.5, 0.0, -0.05, 6.0, 6.0, 0.1, 0.0],  # floor, top at z = 0
        [5.0, 0.0, 1.25, 0.1, 6.0, 2.5, 0.0],  # back wall
        [2.5, 3.0, 1.25, 6.0, 0.1, 2.5, 0.0],  # left wall
        [2.5, -3.0, 1.25, 6.0, 0.1, 2.5, 0.0],  # right wall
    ]
    ids = [0, 1, 2, 3]
    for k, (x, y, yaw) in enumerate([(2.0, 0.8, 0.2), (3.2, -0.6, -0.4), (4.0, 1.5, 1.0)]):
        oid = 10 + k
        c, s = np.cos(yaw), np.sin(yaw)
        boxes.append([x, y, 0.72, 1.2, 0.7, 0.04, yaw])
        ids.append(oid)
        for lx, ly in ((0.55, 0.3), (0.55, -0.3), (-0.55, 0.3), (-0.55, -0.3)):
            boxes.append([x + c * lx - s * ly, y + s * lx + c * ly, 0.35, 0.05, 0.05, 0.7, yaw])
            ids.append(oid)
    rng = np.random.default_rng(0)
    for k in range(6):
        size = rng.uniform(0.15, 0.5, 3)
        x, y = 1.5 + 0.5 * k, rng.uniform(-2.5, -1.2)
        boxes.append([x, y, size[2] / 2, *size, rng.uniform(-np.pi, np.pi)])
        ids.append(20 + k)
    cylinders = [[1.3 + 0.6 * k, 2.3, 0.3, 0.12, 0.6] for k in range(5)]
    return PrimitiveScene(
        boxes=np.array(boxes),
        box_ids=np.array(ids),
        cylinders=np.array(cylinders),
        cylinder_ids=np.arange(30, 35),
    )


def _plane(o: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Hit points (N, 3) of the rays o + t d with the floor plane z = 0 (NaN behind)."""
    n, h = np.array([0.0, 0.0, 1.0]), 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (h - n @ o) / (d @ n)
    t = np.where(t > 0, t, np.nan)
    return o + t[:, None] * d


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--width", type=int, default=None)
    ap.add_argument("--height", type=int, default=None)
    args = ap.parse_args()
    try:
        args.repeats = check_count("--repeats", args.repeats)
        spec = load_camera(width=args.width, height=args.height)
    except ProbaffError as exc:
        ap.error(str(exc))
    torch.set_num_threads(1)
    with threadpool_limits(1):
        camera = DepthCamera(spec)
        scene = _office()
        head = np.eye(4)
        head[:3, 3] = [0.0, 0.0, 1.2]
        pose = head_views(head, [0.0], [20.0])[0]
        image = camera.render(scene, pose, rng=np.random.default_rng(0))  # warm up
        exact_wall, exact_cpu = best_times(
            lambda: camera.render(scene, pose, noise=False), args.repeats
        )
        noisy_wall, noisy_cpu = best_times(
            lambda: camera.render(scene, pose, rng=np.random.default_rng(0)), args.repeats
        )
        rays = spec.pixel_rays().reshape(-1, 3) @ pose[:3, :3].T
        origin = pose[:3, 3]
        plane_wall, plane_cpu = best_times(lambda: _plane(origin, rays), args.repeats)

    n = len(rays)
    k = len(scene.boxes) + len(scene.cylinders)
    print(
        f"{spec.width} x {spec.height} = {n} rays, {k} primitives "
        f"({len(scene.boxes)} boxes, {len(scene.cylinders)} cylinders), 1 thread "
        f"(best of {args.repeats}); {image.valid.mean():.1%} of pixels return with noise"
    )
    print(f"{'':28s}{'wall (s)':>10s}{'cpu (s)':>10s}{'rays/s (wall)':>16s}")
    for name, wall, cpu in (
        ("render, noise=False", exact_wall, exact_cpu),
        ("render, noise=True", noisy_wall, noisy_cpu),
        ("numpy ray-plane", plane_wall, plane_cpu),
    ):
        print(f"{name:28s}{wall:10.4f}{cpu:10.4f}{n / wall:16.3g}")
    print(f"ratio render (noise) / ray-plane, wall: {noisy_wall / plane_wall:.1f}")
    print(
        f"ratio render (noise) / ray-plane per primitive, wall: {noisy_wall / plane_wall / k:.2f}"
    )


if __name__ == "__main__":
    main()
