"""Side-view skill throughput: pick and place samples per second per core, IK included.

Each run draws scenes from a side-view template, solves the arm's IK for each batch in one
batched call, traces the FK and simulates (`probaff.sim.run_sampled`), single-threaded. The
tabletop push pipeline (`PushSimulator.run`) is measured in the same process for reference.
Rates are given per wall-clock second and per CPU second of this process (the per-core rate
that other load on the machine does not distort).

Usage: python benchmarks/sideview_throughput.py [--n 200] [--push-scene two_objects]
"""

import argparse
import time

import numpy as np
import torch

from probaff.sim import PushSimulator, load_sideview, load_sideview_scene
from probaff.sim.skills import run_sampled


def skill(scene: str, n: int) -> tuple[float, float, dict[str, float]]:
    world = load_sideview()
    spec = load_sideview_scene(scene)
    run_sampled(spec, 4, np.random.default_rng(99), world)  # warm caches
    t, c = time.perf_counter(), time.process_time()
    out = run_sampled(spec, n, np.random.default_rng(0), world)
    wall, cpu = n / (time.perf_counter() - t), n / (time.process_time() - c)
    assert len(out) == n
    flags = {
        f: float(np.mean([getattr(o, f) for _, o in out]))
        for f in ("grasped", "lifted", "slipped", "placed")
    }
    return wall, cpu, flags


def push(scene: str, n: int) -> tuple[float, float]:
    sim = PushSimulator(scene)
    list(sim.run(4, np.random.default_rng(99)))  # warm caches
    t, c = time.perf_counter(), time.process_time()
    out = list(sim.run(n, np.random.default_rng(0)))
    assert len(out) == n
    return n / (time.perf_counter() - t), n / (time.process_time() - c)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=200)
    ap.add_argument("--push-scene", default="two_objects")
    args = ap.parse_args()
    torch.set_num_threads(1)
    ref_wall, ref_cpu = push(args.push_scene, args.n)
    print(f"{args.n} samples each, one thread")
    print(f"{'run':32s} {'per s':>7s} {'per cpu s':>9s} {'vs push':>8s}  outcome rates")
    name = f"tabletop push ({args.push_scene})"
    print(f"{name:32s} {ref_wall:7.1f} {ref_cpu:9.1f} {1.0:8.2f}")
    for scene in ("pick", "place"):
        wall, cpu, flags = skill(scene, args.n)
        shown = ", ".join(f"{k} {v:.2f}" for k, v in flags.items())
        name = f"side view {scene}, IK included"
        print(f"{name:32s} {wall:7.1f} {cpu:9.1f} {cpu / ref_cpu:8.2f}  {shown}")
        print(f"  target >= 50 {scene} samples/s/core: {'met' if cpu >= 50 else 'missed'}")


if __name__ == "__main__":
    main()
