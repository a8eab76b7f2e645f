"""Accuracy of loopy BP and of method='auto' against gtsam's exact marginals on 20 maps.

The maps are the warehouse generator's (12 x 12 cells, 10-30 boxes, seed 0); unary
probabilities are drawn uniformly from [0.05, 0.95] (harder than a confident classifier), the
Ising coupling is J = 0.4, with and without the symmetry coupling. For each map the worst
absolute difference of any marginal is reported, unconditioned and with every variable clamped
in turn (the planner's batched evidence).

Usage: python benchmarks/bp_accuracy.py [--maps 20]
"""

import argparse

import numpy as np
import torch

from probaff.maps import (
    AffordanceGraph,
    BPOptions,
    affordance_marginals,
    exact_marginals,
    single_variable_evidence,
)
from probaff.maps.options import DEFAULT_COUPLING
from probaff.sim import load_warehouse
from probaff.sim.warehouse import generate_map


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--maps", type=int, default=20)
    a = ap.parse_args()
    spec = load_warehouse()
    rng = np.random.default_rng(0)
    exact_bp = BPOptions(tol=1e-12, dtype=torch.float64)
    for sym in (None, DEFAULT_COUPLING):
        worst_bp, worst_auto, cycles = [], [], 0
        for _ in range(a.maps):
            m = generate_map(spec, rng)
            unary = rng.uniform(0.05, 0.95, (*m.shape, 4))
            g = AffordanceGraph(m.occupancy, unary, DEFAULT_COUPLING, sym)
            cycles += int(g.num_edges - g.num_variables + len(g.components) > 0)
            ev = single_variable_evidence(g.num_variables, range(g.num_variables))
            exact = exact_marginals(g, ev)
            bp = affordance_marginals(g, ev, method="bp", options=exact_bp)
            auto = affordance_marginals(
                g, ev, method="auto", options=BPOptions(dtype=torch.float64)
            )
            worst_bp.append(float((bp.marginals - exact).abs().max()))
            worst_auto.append(float((auto.marginals - exact).abs().max()))
        wb, wa = np.array(worst_bp), np.array(worst_auto)
        print(f"symmetry coupling {sym}: {a.maps} maps, {cycles} with cycles")
        print(
            f"  loopy BP vs gtsam: worst {wb.max():.2e}, median {np.median(wb):.2e}, "
            f"maps within 1e-3: {(wb <= 1e-3).sum()}/{a.maps}"
        )
        print(f"  method='auto' vs gtsam: worst {wa.max():.2e}")


if __name__ == "__main__":
    main()
