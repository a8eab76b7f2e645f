"""Repeatability of one push under randomised friction: the spread of Delta z_p.

The same scene and push are simulated 200 times; each repeat redraws the ground and contact
friction coefficients (and masses) from the scene template's randomisation ranges. The spread
is reported as the standard deviation of Delta z_p in % of its mean, for comparison with the
5-12 % a real robot shows on repeated pushes.

Usage: python benchmarks/push_spread.py [--scene single_free] [--repeats 200]
"""

import argparse
import dataclasses

import numpy as np
import torch

from probaff.sim import PushSimulator, simulate_push


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default="single_free")
    ap.add_argument("--repeats", type=int, default=200)
    ap.add_argument("--pushes", type=int, default=5, help="distinct pushes to repeat")
    args = ap.parse_args()
    torch.set_num_threads(1)
    sim = PushSimulator(args.scene)
    spec = sim.scene
    rng = np.random.default_rng(0)
    print(
        f"scene {args.scene}: friction scale ground {spec.ground_friction_scale}, contact "
        f"{spec.contact_friction_scale}, mass {spec.mass_scale}, support-load variation "
        f"{spec.support_load_variation}"
    )
    print(f"{'push':>4s} {'object':14s} {'mean dz_p (cm)':>15s} {'sd (cm)':>8s} {'sd/mean %':>10s}")
    spreads = []
    for p, base in enumerate(sim.run(args.pushes, rng)):
        _, _, path = sim.hand_paths([base.scene])
        dz = []
        for _ in range(args.repeats):
            k = len(base.scene.objects)
            nominal_g = np.array([o.ground_friction for o in base.scene.objects])
            nominal_c = np.array([o.contact_friction for o in base.scene.objects])
            nominal_m = np.array([o.mass for o in base.scene.objects])
            scene = dataclasses.replace(
                base.scene,
                ground_friction=nominal_g * rng.uniform(*spec.ground_friction_scale, size=k),
                contact_friction=nominal_c * rng.uniform(*spec.contact_friction_scale, size=k),
                mass=nominal_m * rng.uniform(*spec.mass_scale, size=k),
                support_weights=tuple(
                    (lambda w: w / w.mean())(
                        rng.uniform(
                            1 - spec.support_load_variation,
                            1 + spec.support_load_variation,
                            size=len(sw),
                        )
                    )
                    for sw in base.scene.support_weights
                ),
            )
            dz.append(simulate_push(sim.world, scene, path[0]).effect[0, 1])
        dz = np.array(dz)
        spreads.append(100 * dz.std() / abs(dz.mean()))
        print(
            f"{p:4d} {base.scene.objects[0].name:14s} {100 * dz.mean():15.2f} "
            f"{100 * dz.std():8.3f} {spreads[-1]:10.2f}"
        )
    print(
        f"median spread over {len(spreads)} pushes: {np.median(spreads):.2f} % of the mean "
        "(real repeated pushes: 5-12 %)"
    )


if __name__ == "__main__":
    main()
