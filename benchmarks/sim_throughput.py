"""Push-simulation throughput: pushes per second per core, IK included.

Three runs side by side in one process:
  physics only   simulate_push on pre-drawn scenes with ideal straight hand paths (no arm),
  serial         the full pipeline: draw scenes, batched IK on the arm, trace, simulate,
  dask           the full pipeline as shards on a local Dask cluster of 2 single-threaded workers
                 (cluster start-up excluded; each worker is warmed up first).

Usage: python benchmarks/sim_throughput.py [--scene two_objects] [--n 400]
"""

import argparse
import time

import numpy as np
import torch

from probaff.data.generation import GenerateConfig, make_shard
from probaff.sim import PushSimulator, simulate_push
from probaff.sim.runner import straight_path
from probaff.sim.sampling import sample_scene


def physics_only(scene: str, n: int) -> float:
    sim = PushSimulator(scene)
    rng = np.random.default_rng(0)
    scenes = []
    while len(scenes) < n:
        s = sample_scene(sim.scene, sim.catalogue, sim.world, rng)
        if s is not None:
            scenes.append(s)
    t = time.perf_counter()
    for s in scenes:
        simulate_push(
            sim.world, s, straight_path(sim.world, s.push_origin, s.push_yaw, s.push_distance)
        )
    return n / (time.perf_counter() - t)


def serial(scene: str, n: int) -> float:
    sim = PushSimulator(scene)
    list(sim.run(4, np.random.default_rng(99)))  # warm caches
    t = time.perf_counter()
    out = list(sim.run(n, np.random.default_rng(0)))
    assert len(out) == n
    return n / (time.perf_counter() - t)


def dask(scene: str, n: int, workers: int = 2) -> float:
    from dask.distributed import Client, LocalCluster, wait

    cfg = GenerateConfig(
        scene=scene, n=n, seed=0, shard_size=max(1, n // (4 * workers)), cloud_points=64
    )
    with (
        LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None
        ) as cluster,
        Client(cluster) as client,
    ):
        warm = GenerateConfig(scene=scene, n=2 * workers, seed=1, shard_size=2, cloud_points=8)
        wait(client.map(make_shard, [warm] * workers, range(workers), pure=False))
        t = time.perf_counter()
        futures = client.map(make_shard, [cfg] * cfg.n_shards, range(cfg.n_shards), pure=False)
        rows = sum(len(f.result()["effect"]) for f in futures)
        assert rows == n
        return n / (time.perf_counter() - t)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default="two_objects")
    ap.add_argument("--n", type=int, default=400)
    args = ap.parse_args()
    torch.set_num_threads(1)
    ref = physics_only(args.scene, args.n)
    ser = serial(args.scene, args.n)
    dsk = dask(args.scene, args.n)
    print(f"scene {args.scene}, {args.n} pushes each")
    print(f"{'run':28s} {'pushes/s':>9s} {'per core':>9s}")
    print(f"{'physics only (no arm)':28s} {ref:9.1f} {ref:9.1f}")
    print(f"{'serial, IK included':28s} {ser:9.1f} {ser:9.1f}")
    print(f"{'dask 2 workers, IK incl.':28s} {dsk:9.1f} {dsk / 2:9.1f}")
    print(f"ratio serial / physics only: {ser / ref:.2f}")
    print(f"ratio dask per core / serial: {dsk / 2 / ser:.2f}")
    print(
        f"target >= 100 pushes/s/core: serial {'met' if ser >= 100 else 'missed'}, "
        f"dask {'met' if dsk / 2 >= 100 else 'missed'}"
    )


if __name__ == "__main__":
    main()
