"""Time of one chained prediction over a row of boxes, against one feature call.

A push model is fitted on analytic push-through data (a box moving along +y by d pushes
another box by what is left of d after the touch distance), on the continuous feature groups
(pose and action) and the geometry's motion columns; a chain of `--objects` boxes in
a row, 3 cm apart, pushed by the hand, is then predicted with `--samples` samples on one
thread. For reference, one `interaction_features` call of the same size (`--samples` rows,
box actor and box target of the chain's sizes, actions along +y with a 3 mm sideways spread
like sampled motions) is timed, and the ratio printed, with the
share of the chain's time spent in the geometry's feature calls. Times are the best of
`--repeats` runs, in wall-clock and CPU seconds of this process. `--spacing` and
`--contact-distance` set the geometry (default: `Ch6Geometry`'s, 1.25 r_d and r_d = 1 cm).
The last line compares the chain's wall-clock time with the goal of 0.5 s (5 objects, 256
samples, one thread, the default geometry).

Usage: python benchmarks/chain_prediction.py [--objects 5] [--samples 256] [--repeats 5]
    [--spacing M] [--contact-distance M]
"""

import argparse
import time

import numpy as np
import torch
from _timing import best_times
from threadpoolctl import threadpool_limits

from probaff.features import (
    INTERACTION_GROUPS,
    Ch6Geometry,
    InteractionFeatureConfig,
    box_surface,
    interaction_features,
    tabletop_transform,
)
from probaff.models import ChainScene, ModularTransitionModel, SkillTransitionModel, fit_transition

SIZE = 0.10  # m, edge of every box of the chain
GAP = 0.03  # m, surface gap between neighbours (and between the hand and the first box)
HAND = (0.02, 0.04, 0.04)  # m, the hand: a small box
GOAL = 0.5  # s, the most one chained prediction of the defaults may take on one thread


def _row(n: int, y0: np.ndarray | float = 0.0) -> np.ndarray:
    pose = np.zeros((n, 3))
    pose[:, 1] = y0 + np.arange(n) * (SIZE + GAP)
    return tabletop_transform(pose, np.full(n, SIZE))


def _train(geometry: Ch6Geometry, n: int, rng: np.random.Generator) -> SkillTransitionModel:
    """A push model fitted on n analytic pushes of boxes by boxes along +y."""
    t_size = rng.uniform(0.08, 0.15, (n, 3))
    a_size = rng.uniform(0.08, 0.15, (n, 3))
    T_t = tabletop_transform(np.zeros((n, 3)), t_size[:, 2])
    pose = np.zeros((n, 3))
    pose[:, 0] = rng.uniform(-0.03, 0.03, n)
    pose[:, 1] = -(t_size[:, 1] + a_size[:, 1]) / 2 - rng.uniform(0.0, 0.06, n)
    T_s = tabletop_transform(pose, a_size[:, 2])
    T_e = T_s.copy()
    T_e[:, 1, 3] += rng.uniform(0.01, 0.15, n)
    t_pts, t_nrm = box_surface(t_size, T_t)
    a_pts, a_nrm = box_surface(a_size, T_s)
    X, _, _ = geometry.features(t_pts, t_nrm, a_pts, a_nrm, T_s, T_e)
    Y = np.column_stack([np.zeros(n), X[:, -1], np.zeros(n)])  # the travel after the touch
    Y += 0.002 * rng.standard_normal(Y.shape)
    model = SkillTransitionModel("push", backward=False)
    fit_transition(model, X, Y)
    return model


class _TimedGeometry(Ch6Geometry):
    """`Ch6Geometry` that adds up the wall-clock time of its feature calls."""

    seconds = 0.0

    def features(self, *args: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = time.perf_counter()
        out = super().features(*args)
        self.seconds += time.perf_counter() - t
        return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--objects", type=int, default=5)
    ap.add_argument("--samples", type=int, default=256)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--train", type=int, default=150)
    ap.add_argument("--spacing", type=float, default=None)
    ap.add_argument("--contact-distance", type=float, default=0.01)
    args = ap.parse_args()
    torch.set_num_threads(1)
    with threadpool_limits(1):
        pose, action = INTERACTION_GROUPS["pose"], INTERACTION_GROUPS["action"]
        continuous = [*range(pose.start, pose.stop), *range(action.start, action.stop)]
        config = InteractionFeatureConfig(contact_distance=args.contact_distance)
        geometry = _TimedGeometry(config, columns=continuous, spacing=args.spacing)
        model = _train(geometry, args.train, np.random.default_rng(0))
        chain = ModularTransitionModel({"push": model}, geometry)
        k = args.objects
        sizes = np.full((k, 3), SIZE)
        start = np.eye(4)
        start[:3, 3] = [0.0, -SIZE / 2 - GAP - HAND[1] / 2, 0.03]
        end = start.copy()
        end[1, 3] += 0.15
        hand_p, hand_n = box_surface(np.array([HAND]), np.eye(4)[None])
        scene = ChainScene(sizes, _row(k), hand_p[0], hand_n[0], start, end)
        pred = chain.predict_chain(scene, n_samples=args.samples, seed=0)  # warm up
        geometry.seconds = 0.0
        t = time.perf_counter()
        chain.predict_chain(scene, n_samples=args.samples, seed=0)
        share = geometry.seconds / (time.perf_counter() - t)
        chain_wall, chain_cpu = best_times(
            lambda: chain.predict_chain(scene, n_samples=args.samples, seed=0), args.repeats
        )

        s = args.samples
        sp = geometry.spacing
        t_pts, t_nrm = box_surface(np.full((s, 3), SIZE), _row(1, SIZE + GAP).repeat(s, 0), sp)
        T_s = _row(1).repeat(s, 0)
        a_pts, a_nrm = box_surface(np.full((s, 3), SIZE), T_s, sp)
        T_e = T_s.copy()
        T_e[:, 1, 3] += np.linspace(0.02, 0.2, s)
        T_e[:, 0, 3] += np.random.default_rng(1).normal(0.0, 0.003, s)  # as sampled motions
        feat_wall, feat_cpu = best_times(
            lambda: interaction_features(
                t_pts, t_nrm, a_pts, a_nrm, T_s, T_e, config, chunk=geometry.chunk
            ),
            args.repeats,
        )

    print(
        f"chain of {k} boxes, {s} samples, 1 thread (best of {args.repeats}); surface spacing "
        f"{sp * 100:.3g} cm ({t_pts.shape[1]} points per box), "
        f"r_d {config.contact_distance * 100:.3g} cm"
    )
    print(f"  touched per object: {np.round(pred.touched.mean(axis=0), 2).tolist()}")
    print(f"  mean push along +y (cm): {np.round(100 * pred.mean_displacement[:, 1], 2).tolist()}")
    print(f"{'':28s}{'wall (s)':>10s}{'cpu (s)':>10s}")
    print(f"{'predict_chain':28s}{chain_wall:10.4f}{chain_cpu:10.4f}")
    print(f"{'interaction_features':28s}{feat_wall:10.4f}{feat_cpu:10.4f}")
    ratio_wall, ratio_cpu = chain_wall / feat_wall, chain_cpu / feat_cpu
    print(f"{'ratio chain / features':28s}{ratio_wall:10.2f}{ratio_cpu:10.2f}")
    print(f"share of one chain in feature calls: {share:.0%}")
    print(f"goal <= 0.5 s (predict_chain, wall): {'met' if chain_wall <= GOAL else 'NOT met'}")


if __name__ == "__main__":
    main()
