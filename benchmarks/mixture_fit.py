"""Time an EM fit of a GP mixture against one scikit-learn ARD GP on the same data.

Usage::

    python benchmarks/mixture_fit.py [--n 321] [--d 101] [--e 6] [--sklearn-restarts 0]
    python benchmarks/mixture_fit.py --batched-vs-reference [--sizes 250,500,1000] [--repeats 2]
    python benchmarks/mixture_fit.py --device cuda [--n 321] [--d 101] [--repeats 1]

The data come from `probaff.models.synthetic.regime_features`: three regimes selected by
the first two feature columns, each mapping its own four columns to the E effects. The
mixture (M experts, gate on columns 0-2, experts on every column) is fitted by `fit_em`;
the baseline is one `GaussianProcessRegressor` with an anisotropic RBF kernel (one length
scale per column, initialised like the experts' at sqrt(D)) times a constant, plus a white
noise kernel, on the same standardised features. Both run with `--threads` torch/BLAS
threads. A small EM fit runs first so that one-time import costs are not timed.

With ``--batched-vs-reference`` it instead times, at each N of `--sizes` and alternating
`--repeats` times, the default EM fit (the experts of each M-step fitted as one batch,
`probaff.models.experts.expert_batch`) against the reference path that fits and predicts the experts
one at a time (`per_expert_fits`), in this one process, and prints both wall and CPU times,
their ratio, and both fits' final objective and held-out NLPD (which should agree).

With ``--device cuda`` (or ``cuda:N``; the default ``cpu`` runs the comparison above) it
instead times the same EM fit as the first mode (same data, model and iterations) on the CPU
(`--threads` threads) and on that device, alternating `--repeats` times in this one process,
after a small warm-up fit on each; device times synchronise the device before the clock is
read. It prints each fit's wall seconds (the least over repeats), best objective and held-out
NLPD, the ratio CPU / device, and the largest relative difference between the two objective
traces, which should be small (float64 on both). A device that is malformed or that this
machine does not have is refused with one line and exit status 2 before any work.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import math
import sys
import time

import numpy as np
import torch
from _timing import bench_device, synchronize
from scipy.stats import norm
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel
from sklearn.preprocessing import StandardScaler
from threadpoolctl import threadpool_limits

from probaff._cli_errors import run_cli
from probaff._threads import limit_threads
from probaff.errors import InputError
from probaff.models import MIXTURE_GP, GPOptions, MixtureOfGPExperts, fit_em
from probaff.models.experts.expert_batch import per_expert_fits
from probaff.models.synthetic import regime_features


def purity(assign: np.ndarray, labels: np.ndarray) -> float:
    """Fraction of samples whose cluster's majority label is their own label."""
    return sum(np.bincount(labels[assign == j]).max() for j in np.unique(assign)) / len(labels)


def _experts(args: argparse.Namespace) -> GPOptions:
    """The experts' settings: the mixture's default, the length-scale prior as asked."""
    return dataclasses.replace(MIXTURE_GP, lengthscale_prior=args.lengthscale_prior)


def time_em(
    args: argparse.Namespace, x: torch.Tensor, y: torch.Tensor, labels: np.ndarray
) -> tuple[MixtureOfGPExperts, float]:
    model = MixtureOfGPExperts(
        args.experts,
        groups={"f_x": slice(0, 3)},
        gate_features=("f_x",),
        expert_features=None,
        gp=_experts(args),
    )
    fit_em(model, x[:40], y[:40], max_iter=1)  # warm-up: one-time imports and allocations
    start = time.perf_counter()
    history = fit_em(model, x, y, max_iter=args.em_iter, tol=0.0)
    elapsed = time.perf_counter() - start
    prior = ", length-scale prior" if args.lengthscale_prior else ""
    print(f"EM: M={args.experts}{prior}, {history.n_iter} iterations in {elapsed:.2f} s")
    print("  objective per iteration:", " ".join(f"{v:.1f}" for v in history.objective))
    assign = history.responsibilities.argmax(1).numpy()
    print(f"  assignment purity {purity(assign, labels):.3f}")
    return model, elapsed


def _fit_once(
    args: argparse.Namespace, data: tuple[torch.Tensor, ...], reference: bool
) -> tuple[float, float, float, float]:
    """One EM fit: (wall seconds, CPU seconds, final objective, held-out NLPD)."""
    x_tr, y_tr, x_te, y_te = data
    model = MixtureOfGPExperts(
        args.experts,
        groups={"f_x": slice(0, 3)},
        gate_features=("f_x",),
        gp=_experts(args),
    )
    start, cpu = time.perf_counter(), time.process_time()
    with per_expert_fits() if reference else contextlib.nullcontext():
        history = fit_em(model, x_tr, y_tr, max_iter=args.em_iter, tol=0.0)
        nlpd = -float(model.predict(x_te).log_prob(y_te).mean())
    return time.perf_counter() - start, time.process_time() - cpu, history.best, nlpd


def batched_vs_reference(args: argparse.Namespace) -> None:
    """Time batched EM against the one-expert-at-a-time reference, side by side."""
    sizes = [int(s) for s in args.sizes.split(",")]
    print(f"M={args.experts} D={args.d} E={args.e}, {args.em_iter} EM iterations, 1 thread")
    print("   N | path      | wall s | CPU s  | objective   | NLPD")
    for n in sizes:
        x, y, _ = regime_features(n + args.n_test, args.d, args.e, seed=0)
        data = (x[:n], y[:n], x[n:], y[n:])
        _fit_once(args, (x[:40], y[:40], x[n:], y[n:]), False)  # warm-up
        totals = {False: [0.0, 0.0], True: [0.0, 0.0]}
        for _ in range(args.repeats):
            for reference in (True, False):
                wall, cpu, objective, nlpd = _fit_once(args, data, reference)
                totals[reference][0] += wall
                totals[reference][1] += cpu
                name = "reference" if reference else "batched"
                print(
                    f"{n:4d} | {name:9s} | {wall:6.1f} | {cpu:6.1f} | {objective:11.4f} | "
                    f"{nlpd:.4f}"
                )
        ref, new = totals[True], totals[False]
        print(
            f"{n:4d} | speed-up: {ref[0] / new[0]:.2f}x wall, {ref[1] / new[1]:.2f}x CPU "
            f"(sums over {args.repeats} alternating repeats)"
        )


def _mixture(args: argparse.Namespace, device: torch.device) -> MixtureOfGPExperts:
    """The mixture of the first mode, on `device`."""
    return MixtureOfGPExperts(
        args.experts,
        groups={"f_x": slice(0, 3)},
        gate_features=("f_x",),
        expert_features=None,
        gp=_experts(args),
    ).to(device)


def _fit_on(
    args: argparse.Namespace, data: tuple[torch.Tensor, ...], device: torch.device
) -> tuple[float, list[float], float, float]:
    """One EM fit on `device`: (wall seconds, objective trace, best objective, held-out NLPD)."""
    x_tr, y_tr, x_te, y_te = (t.to(device) for t in data)
    model = _mixture(args, device)
    synchronize(device)
    start = time.perf_counter()
    history = fit_em(model, x_tr, y_tr, max_iter=args.em_iter, tol=0.0)
    synchronize(device)
    wall = time.perf_counter() - start
    nlpd = -float(model.predict(x_te).log_prob(y_te).mean())
    return wall, list(history.objective), history.best, nlpd


def cpu_vs_device(
    args: argparse.Namespace, data: tuple[torch.Tensor, ...], device: torch.device
) -> None:
    """Time the first mode's EM fit on the CPU and on `device`, side by side."""
    cpu = torch.device("cpu")
    name = torch.cuda.get_device_name(device) if device.type == "cuda" else str(device)
    print(
        f"EM: M={args.experts}, {args.em_iter} iterations, float64; CPU on {args.threads} "
        f"thread(s) vs {device} ({name}), best of {args.repeats} alternating repeat(s)"
    )
    x_tr, y_tr = data[0], data[1]
    for dev in (cpu, device):  # warm-up: one-time imports, kernels and allocations
        fit_em(_mixture(args, dev), x_tr[:40].to(dev), y_tr[:40].to(dev), max_iter=1)
    runs: dict[torch.device, list[tuple[float, list[float], float, float]]] = {
        cpu: [],
        device: [],
    }
    for _ in range(args.repeats):
        for dev in (cpu, device):
            runs[dev].append(_fit_on(args, data, dev))
    print(f"  {'device':8s} | wall s | best objective | held-out NLPD")
    for dev in (cpu, device):
        wall = min(run[0] for run in runs[dev])
        _, _, best, nlpd = runs[dev][-1]
        print(f"  {dev!s:8s} | {wall:6.2f} | {best:14.6f} | {nlpd:.6f}")
    cpu_wall, dev_wall = (min(run[0] for run in runs[d]) for d in (cpu, device))
    cpu_trace, dev_trace = runs[cpu][-1][1], runs[device][-1][1]
    if len(cpu_trace) == len(dev_trace):
        diff = max(
            (abs(a - b) / max(abs(a), 1.0) for a, b in zip(cpu_trace, dev_trace, strict=True)),
            default=0.0,
        )
        agree = f"largest relative objective difference over the trace {diff:.1e}"
    else:
        agree = f"traces of different lengths: {len(cpu_trace)} vs {len(dev_trace)} iterations"
    nlpd_diff = abs(runs[cpu][-1][3] - runs[device][-1][3])
    print(
        f"  CPU / {device} = {cpu_wall / dev_wall:.2f}x (wall); {agree}; "
        f"|NLPD difference| {nlpd_diff:.1e}"
    )


def time_sklearn(
    args: argparse.Namespace, x: np.ndarray, y: np.ndarray
) -> tuple[GaussianProcessRegressor, float]:
    d = x.shape[1]
    rbf = RBF(length_scale=np.full(d, math.sqrt(d)), length_scale_bounds=(1e-3, 1e5))
    kernel = ConstantKernel(1.0) * rbf + WhiteKernel(0.1)
    gpr = GaussianProcessRegressor(
        kernel, normalize_y=True, n_restarts_optimizer=args.sklearn_restarts, random_state=0
    )
    start = time.perf_counter()
    gpr.fit(x, y)
    elapsed = time.perf_counter() - start
    print(
        f"sklearn GaussianProcessRegressor (ARD RBF + white noise, "
        f"{args.sklearn_restarts} restarts): {elapsed:.2f} s"
    )
    return gpr, elapsed


def main() -> None:
    """Run the benchmark and print both timings and their ratio."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=321, help="training samples")
    parser.add_argument("--d", type=int, default=101, help="feature columns")
    parser.add_argument("--e", type=int, default=6, help="effect dimensions")
    parser.add_argument("--experts", type=int, default=3)
    parser.add_argument("--em-iter", type=int, default=10)
    parser.add_argument("--sklearn-restarts", type=int, default=0)
    parser.add_argument("--skip-sklearn", action="store_true")
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--n-test", type=int, default=500, help="held-out samples for NLPD")
    parser.add_argument(
        "--lengthscale-prior", action="store_true", help="dimension-scaled length-scale prior"
    )
    parser.add_argument(
        "--batched-vs-reference",
        action="store_true",
        help="time batched EM against fitting the experts one at a time",
    )
    parser.add_argument("--sizes", default="250,500,1000", help="N values (comma-separated)")
    parser.add_argument(
        "--repeats",
        type=int,
        default=None,
        help="alternating repeats per N (default 2), or per device with --device (default 1)",
    )
    parser.add_argument(
        "--device",
        default="cpu",
        help="cuda or cuda:N: time the EM fit on the CPU and on this device side by side",
    )
    args = parser.parse_args()
    device = bench_device(args.device)
    if device.type != "cpu" and args.batched_vs_reference:
        raise InputError("--device compares the CPU with a device; omit --batched-vs-reference.")
    if args.repeats is None:
        args.repeats = 1 if device.type != "cpu" else 2
    if args.repeats < 1:
        raise InputError(f"--repeats must be a positive integer, got {args.repeats}.")
    if args.batched_vs_reference:
        with limit_threads(args.threads), threadpool_limits(args.threads):
            batched_vs_reference(args)
        return

    x, y, labels = regime_features(args.n + args.n_test, args.d, args.e, seed=0)
    scaler = StandardScaler().fit(x[: args.n].numpy())
    xs = torch.as_tensor(scaler.transform(x.numpy()))
    x_tr, y_tr, x_te, y_te = xs[: args.n], y[: args.n], xs[args.n :], y[args.n :]
    print(f"data: N={args.n} D={args.d} E={args.e}, {args.n_test} held-out samples")

    if device.type != "cpu":
        with limit_threads(args.threads), threadpool_limits(args.threads):
            cpu_vs_device(args, (x_tr, y_tr, x_te, y_te), device)
        return
    with limit_threads(args.threads), threadpool_limits(args.threads):
        model, em_time = time_em(args, x_tr, y_tr, labels[: args.n].numpy())
        print(f"  held-out NLPD {-float(model.predict(x_te).log_prob(y_te).mean()):.3f}")
        if args.skip_sklearn:
            return
        gpr, sk_time = time_sklearn(args, x_tr.numpy(), y_tr.numpy())
        mean, std = gpr.predict(x_te.numpy(), return_std=True)
        print(f"  held-out NLPD {-float(norm.logpdf(y_te.numpy(), mean, std).sum(1).mean()):.3f}")
    print(f"EM {em_time:.2f} s vs sklearn {sk_time:.2f} s: EM is {sk_time / em_time:.1f}x faster")


if __name__ == "__main__":
    sys.exit(run_cli(main))
