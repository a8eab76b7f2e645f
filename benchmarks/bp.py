"""Belief propagation benchmarks for affordance maps.

Run with ``python benchmarks/bp.py`` (about two minutes on a 2-core CPU). Prints:

(a) milliseconds per BP iteration on a 1000x1000 Ising grid (one direction, every cell
    occupied, random unaries, B = 1): the grid fast path, the generic edge-list path and a
    naive per-edge log-domain reference, with ratios. With ``--device cuda`` (or
    ``cuda:N``) the grid fast path and the generic edge-list path also run on that device,
    in the same process and on the same problem: their milliseconds per iteration are
    printed next to the CPU's with the ratio CPU / device, and the device's marginals are
    compared with the CPU's (a converged grid solve, and 10 generic iterations);
(b) the time to score every single-variable observation of one 12x12 warehouse map
    (each variable clamped to 1 and to 0, one batched BP call, plus map entropies), next to
    gtsam exact inference on the same conditioned graphs;
(c) the largest square grid whose BP state fits in 8 GiB, from the bytes per cell of the
    grid layout, checked by running a 2000x2000 grid in a fresh process and reading its
    peak RSS (printed first).

Options: ``--grid``, ``--boxes`` and ``--memory-grid`` set the sizes of (a), (b) and (c);
``--device`` (default ``cpu``) adds the device timings to (a); ``--quick`` runs (a) alone
(its CPU timings, the naive reference included, take most of its time; the device's part
takes seconds). A device that is malformed or that this machine does not have
(``--device cuda`` without CUDA) is refused with one line and exit status 2, before any
work.

Timings are minima over repeats: the machine may be shared, and the minimum is the least
disturbed measurement. Device timings synchronise the device before each clock reading.
"""

from __future__ import annotations

import argparse
import math
import resource
import statistics
import subprocess
import sys
import time
from collections.abc import Callable

import gtsam
import numpy as np
import torch
from _timing import bench_device, best_times, synchronize

from probaff._cli_errors import run_cli
from probaff.maps import (
    AffordanceGraph,
    BeliefPropagationResult,
    BPOptions,
    affordance_marginals,
    exact_marginals,
    grid_belief_propagation,
    loopy_belief_propagation,
    map_entropy,
    single_variable_evidence,
)
from probaff.maps.grid_bp import GRID_BYTES_PER_CELL
from probaff.maps.options import DEFAULT_COUPLING
from probaff.maps.synthetic import drop_shelves

COUPLING = DEFAULT_COUPLING
GIB = 1024**3


def per_iteration_ms(run: Callable[[int], object], short: int, long: int, repeats: int) -> float:
    """Milliseconds per iteration: difference of best times at two iteration counts.

    Short and long runs alternate so that a burst of load elsewhere hits both alike.
    """
    t_short, t_long = math.inf, math.inf
    for _ in range(repeats):
        t_short = min(t_short, best_times(lambda: run(short), 1)[0])
        t_long = min(t_long, best_times(lambda: run(long), 1)[0])
    return (t_long - t_short) / (long - short) * 1e3


def grid_unary(n: int, seed: int = 0) -> torch.Tensor:
    """``(n, n, 2)`` log unaries of probabilities drawn uniformly from [0.05, 0.95]."""
    gen = torch.Generator().manual_seed(seed)
    p = torch.rand(n, n, generator=gen) * 0.9 + 0.05
    return torch.stack([torch.log1p(-p), torch.log(p)], dim=-1)


def grid_problem(n: int, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Random n x n Ising grid: ``(n, n, 2)`` unary logs, ``(E, 2)`` edges, ``(E, 2, 2)`` logs."""
    unary = grid_unary(n, seed)
    ids = torch.arange(n * n).reshape(n, n)
    edges = torch.cat(
        [
            torch.stack([ids[:-1].reshape(-1), ids[1:].reshape(-1)], dim=1),
            torch.stack([ids[:, :-1].reshape(-1), ids[:, 1:].reshape(-1)], dim=1),
        ]
    )
    table = torch.tensor([[COUPLING, -COUPLING], [-COUPLING, COUPLING]])
    return unary, edges, table.expand(edges.shape[0], 2, 2)


def naive_bp_iteration_ms(
    unary: torch.Tensor, edges: torch.Tensor, pairwise: torch.Tensor, iterations: int
) -> float:
    """Straightforward per-edge log-domain BP: ``(D, 2)`` messages, logsumexp over tables.

    Returns the median milliseconds per iteration.
    """
    num_edges = edges.shape[0]
    src = torch.cat([edges[:, 0], edges[:, 1]])
    dst = torch.cat([edges[:, 1], edges[:, 0]])
    rev = torch.cat([torch.arange(num_edges, 2 * num_edges), torch.arange(num_edges)])
    tables = torch.cat([pairwise, pairwise.transpose(1, 2)])  # [d, x_src, x_dst]
    log_msgs = torch.full((2 * num_edges, 2), -math.log(2.0))
    times = []
    for _ in range(iterations):
        start = time.perf_counter()
        beliefs = unary.clone().index_add_(0, dst, log_msgs)
        cavity = beliefs[src] - log_msgs[rev]
        new = torch.logsumexp(cavity[:, :, None] + tables, dim=1)
        new = new - torch.logsumexp(new, dim=1, keepdim=True)
        new = 0.5 * log_msgs + 0.5 * new
        _ = float((new - log_msgs).abs().max())
        log_msgs = new
        times.append(time.perf_counter() - start)
    return statistics.median(times) * 1e3


def bench_grid_device(
    problem: tuple[torch.Tensor, torch.Tensor, torch.Tensor],
    device: torch.device,
    cpu_ms: tuple[float, float],
    threads: int,
    cpu_solve: BeliefPropagationResult,
) -> None:
    """Part (a) on `device`: ms per iteration next to the CPU's, and the marginals' agreement.

    Args:
        problem: The CPU ``(n, n, 2)`` unaries, ``(E, 2)`` edges and ``(E, 2, 2)`` tables.
        device: A CUDA device.
        cpu_ms: The CPU's ms per iteration of the grid fast path (`threads` threads) and of
            the generic edge-list path.
        threads: Torch threads of the CPU timings.
        cpu_solve: The CPU's converged grid solve of the same problem.
    """
    unary, edges, pairwise = problem
    dev_unary = unary.to(device)
    dev_flat = dev_unary.reshape(-1, 2)
    dev_edges, dev_pairwise = edges.to(device), pairwise.to(device)

    def grid(iters: int) -> BeliefPropagationResult:
        opts = BPOptions(tol=0.0, max_iterations=iters)
        result = grid_belief_propagation(dev_unary, COUPLING, options=opts)
        synchronize(device)
        return result

    def generic(iters: int) -> BeliefPropagationResult:
        opts = BPOptions(tol=0.0, max_iterations=iters)
        result = loopy_belief_propagation(dev_flat, dev_edges, dev_pairwise, options=opts)
        synchronize(device)
        return result

    grid(2)  # warm-up: the context, the kernels and the caching allocator
    generic(2)
    fast = per_iteration_ms(grid, 1, 101, repeats=5)
    edge_list = per_iteration_ms(generic, 1, 101, repeats=5)
    name = torch.cuda.get_device_name(device) if device.type == "cuda" else str(device)
    print(f"    on {device} ({name}), the same problem, float32, ms/iter:")
    print(f"    {'':18s} {'CPU':>9s} {device!s:>9s}   CPU / {device}")
    for label, cpu, dev in (
        ("grid fast path", cpu_ms[0], fast),
        ("generic edge list", cpu_ms[1], edge_list),
    ):
        ratio = cpu / dev if dev > 0 else math.nan
        print(f"    {label:18s} {cpu:9.2f} {dev:9.3f}   {ratio:.1f}x")
    print(f"    (CPU: the grid fast path on {threads} threads, as above)")
    solve = grid_belief_propagation(dev_unary, COUPLING)  # default options, as on the CPU
    synchronize(device)
    err = (solve.marginals.cpu() - cpu_solve.marginals).abs().max()
    print(
        f"    full solve on {device}: converged={solve.converged} after {solve.iterations} "
        f"iterations (CPU: {cpu_solve.iterations}); max |{device} - CPU| marginal {float(err):.1e}"
    )
    opts = BPOptions(tol=0.0, max_iterations=10)
    cpu_generic = loopy_belief_propagation(unary.reshape(-1, 2), edges, pairwise, options=opts)
    err = (generic(10).marginals.cpu() - cpu_generic.marginals).abs().max()
    print(f"    generic edge list, 10 iterations: max |{device} - CPU| marginal {float(err):.1e}")


def bench_grid(n: int, device: torch.device) -> None:
    unary, edges, pairwise = grid_problem(n)
    flat_unary = unary.reshape(-1, 2)
    print(f"(a) BP iteration time, {n}x{n} Ising grid, J={COUPLING}, B=1, float32")

    def grid(iters: int) -> object:
        opts = BPOptions(tol=0.0, max_iterations=iters)
        return grid_belief_propagation(unary, COUPLING, options=opts)

    def generic(iters: int) -> object:
        opts = BPOptions(tol=0.0, max_iterations=iters)
        return loopy_belief_propagation(flat_unary, edges, pairwise, options=opts)

    threads = torch.get_num_threads()
    fast = per_iteration_ms(grid, 1, 21, repeats=4)
    torch.set_num_threads(1)
    fast_one = per_iteration_ms(grid, 1, 21, repeats=3)
    torch.set_num_threads(threads)
    edge_list = per_iteration_ms(generic, 1, 11, repeats=3)
    naive = naive_bp_iteration_ms(flat_unary, edges, pairwise, iterations=4)
    print(f"    grid fast path     {fast:8.1f} ms/iter  ({threads} threads)")
    print(f"    grid fast path     {fast_one:8.1f} ms/iter  (1 thread)")
    print(f"    generic edge list  {edge_list:8.1f} ms/iter")
    print(f"    naive per-edge     {naive:8.1f} ms/iter")
    print(
        f"    naive / grid fast path = {naive / fast:.1f}x, "
        f"naive / generic = {naive / edge_list:.1f}x"
    )
    converged = grid_belief_propagation(unary, COUPLING)
    print(
        f"    full solve: converged={converged.converged} after {converged.iterations} "
        f"iterations (max_delta {converged.max_delta:.1e})"
    )
    if device.type != "cpu":
        bench_grid_device((unary, edges, pairwise), device, (fast, edge_list), threads, converged)


def warehouse_map(rng: np.random.Generator, size: int, boxes: int) -> np.ndarray:
    """Shelves of 1- or 2-deep boxes until exactly `boxes` cells are occupied."""
    occ = drop_shelves(rng, size, boxes)
    extra = np.flatnonzero(occ)[rng.permutation(int(occ.sum()))[: int(occ.sum()) - boxes]]
    occ.flat[extra] = False
    return occ


def whole_map_gtsam(graph: AffordanceGraph, clamp: dict[int, int]) -> np.ndarray:
    marginals = gtsam.DiscreteMarginals(graph.to_gtsam(evidence=clamp))
    return np.stack([marginals.marginalProbabilities((v, 2)) for v in range(graph.num_variables)])


def bench_candidates(boxes: int) -> None:
    rng = np.random.default_rng(7)
    occ = warehouse_map(rng, 12, boxes)
    graph = AffordanceGraph(occ, rng.uniform(0.05, 0.95, (12, 12, 4)), COUPLING, COUPLING)
    evidence = single_variable_evidence(graph.num_variables)
    unary = graph.unary_log_potentials()
    edges = graph.edge_tensor()
    pairwise = graph.pairwise_log_potentials()
    cycles = graph.num_edges - graph.num_variables + len(graph.components)
    print(
        f"(b) candidate scoring, 12x12 map: {boxes} boxes, V={graph.num_variables}, "
        f"E={graph.num_edges} (incl. symmetry), {cycles} independent cycles, "
        f"B={evidence.shape[0]} conditioned copies"
    )

    result = {}

    def score() -> None:
        result["bp"] = loopy_belief_propagation(unary, edges, pairwise, evidence)
        result["entropy"] = map_entropy(result["bp"].marginals)

    bp_s = best_times(score, 5)[0]
    bp = result["bp"]
    print(
        f"    batched BP + entropies: {bp_s * 1e3:7.1f} ms  (converged={bp.converged}, "
        f"{bp.iterations} iterations)"
    )

    exact = {}

    def per_component() -> None:
        exact["marginals"] = exact_marginals(graph, evidence)

    exact_s = best_times(per_component, 2)[0]
    print(
        f"    gtsam exact, every candidate, re-solving only the clamped component: "
        f"{exact_s * 1e3:7.1f} ms  -> BP is {exact_s / bp_s:.1f}x faster"
    )
    subset = 20
    clamps = [{v: value} for v in range(subset // 2) for value in (1, 0)]
    whole_s = best_times(lambda: [whole_map_gtsam(graph, c) for c in clamps], 2)[0]
    whole_all = whole_s / subset * evidence.shape[0]
    print(
        f"    gtsam exact on the whole conditioned map: {whole_s * 1e3:.1f} ms for "
        f"{subset} candidates, extrapolated to {evidence.shape[0]}: {whole_all * 1e3:.0f} ms "
        f"-> BP is {whole_all / bp_s:.0f}x faster"
    )
    err = (bp.marginals.double() - exact["marginals"]).abs().max()
    print(
        f"    max |BP - exact| over all candidates and variables: {float(err):.2e} "
        "(loopy BP approximation on cycles)"
    )
    auto = {}

    def score_auto() -> None:
        auto["r"] = affordance_marginals(graph, evidence, method="auto")
        auto["m"] = auto["r"].marginals
        auto["entropy"] = map_entropy(auto["m"])

    auto_s = best_times(score_auto, 5)[0]
    methods = sorted(set(auto["r"].component_methods))
    err_auto = (auto["m"].double() - exact["marginals"]).abs().max()
    print(
        f"    method='auto' ({'/'.join(methods)}) + entropies: {auto_s * 1e3:7.1f} ms, "
        f"max |auto - gtsam| = {float(err_auto):.1e} -> {exact_s / auto_s:.1f}x faster than gtsam"
    )


def current_rss() -> int:
    """Resident set size of this process now, in bytes (Linux)."""
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    raise RuntimeError("VmRSS not found in /proc/self/status")


def memory_probe(n: int) -> None:
    """Run one grid solve and print baseline and peak RSS in bytes (child process mode)."""
    grid_belief_propagation(torch.zeros(2, 2, 2), COUPLING)  # warm-up: lazy allocations
    base = current_rss()
    unary = grid_unary(n)
    result = grid_belief_propagation(unary, COUPLING, options=BPOptions(tol=0.0, max_iterations=3))
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    print(base, peak, result.iterations)


def bench_memory(n: int) -> None:
    state = GRID_BYTES_PER_CELL[torch.float32]
    per_cell = state + 8  # + the caller's (H, W, 2) float32 unary
    side = math.isqrt(int(8 * GIB / per_cell))
    print("(c) memory, grid fast path, float32, B=1")
    print(
        f"    layout: {state} B/cell of BP state (fields, beliefs, 4 message arrays, "
        f"2 scratch) + 8 B/cell unary input = {per_cell} B/cell"
    )
    print(f"    largest square grid in 8 GiB: {side}x{side} ({side * side / 1e6:.0f}M cells)")
    out = subprocess.run(
        [sys.executable, __file__, "--memory-probe", str(n)],
        check=True,
        capture_output=True,
        text=True,
    ).stdout.split()
    base, peak = int(out[0]), int(out[1])
    print(
        f"    measured {n}x{n} (fresh process): peak RSS {peak / 2**20:.0f} MiB (getrusage), "
        f"{(peak - base) / 2**20:.0f} MiB above the RSS before the solve"
    )
    if peak > base:
        measured = (peak - base) / (n * n)
        fit = math.isqrt(int((8 * GIB - base) / measured))
        print(
            f"    = {measured:.1f} B/cell -> largest square grid in 8 GiB including the "
            f"{base / 2**20:.0f} MiB interpreter baseline: {fit}x{fit}"
        )
    edge_bytes = 2 * 4 + 2 * 4 + 2 * 2 * 8 + 2 * 4
    generic = 2 * 4 + 2 * edge_bytes
    print(
        f"    (generic edge-list path: {2 * 4} B/variable + {edge_bytes} B/edge, about "
        f"{generic} B/cell on a grid -> {math.isqrt(int(8 * GIB / generic))}^2 in 8 GiB)"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grid", type=int, default=1000, help="side of the timing grid")
    parser.add_argument("--boxes", type=int, default=25, help="boxes of the scoring map")
    parser.add_argument("--memory-grid", type=int, default=2000, help="side of the RSS check")
    parser.add_argument(
        "--device",
        default="cpu",
        help="also time part (a) on this device (cuda or cuda:N) next to the CPU",
    )
    parser.add_argument("--quick", action="store_true", help="run part (a) alone")
    parser.add_argument("--memory-probe", type=int, default=0, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.memory_probe:
        memory_probe(args.memory_probe)
        return
    device = bench_device(args.device)
    print(f"torch {torch.__version__}, {torch.get_num_threads()} threads")
    if device.type == "cuda":
        print(f"device {device}: {torch.cuda.get_device_name(device)}, CUDA {torch.version.cuda}")
    start = time.perf_counter()
    if not args.quick:
        # First, while this process is small: a child's getrusage peak starts at the RSS
        # its parent had when it was forked.
        bench_memory(args.memory_grid)
    bench_grid(args.grid, device)
    if not args.quick:
        bench_candidates(args.boxes)
    print(f"total benchmark time {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    sys.exit(run_cli(main))
