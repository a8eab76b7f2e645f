"""How often the default EM start finds RAND HIE's spikes, seed by seed and split by split.

The target of statsmodels' RAND HIE data (``log1p(mdvis)``, see ``mixture_scale.py``) has
spikes at 0 and 1 visit beside a long tail. A mixture that gives the 1-visit spike an expert
of its own scores about -0.5 to -0.65 nats per held-out point; one that misses it scores
about 0. Whether the fit finds it depends on its start: the Gaussian mixture of the effects
(`probaff.models.initialization`) must put a component on the spike, and that depends on how
its restarts are seeded (`EMOptions.n_init`: the first from k-means, the others from rows
drawn from the data).

For every split (``--splits``: the rows shuffled by that seed; the first ``--test`` rows
held out, the next ``--n`` train) and every fit seed (``--seeds``), each ``--n-init`` setting
fits `MixtureOfGPExperts(M)` by `fit_em` (defaults otherwise) on one thread, side by side in
the same process, and records the held-out NLPD per point and the fit's CPU seconds.
``--n-init 1`` is k-means alone (the seeding before drawn restarts). A cell counts as found
when its NLPD is at most ``--goal``.

Each cell is written atomically as ``<out>/split<S>_seed<s>_ninit<k>.json`` and reused when
it holds the same setup, so an interrupted run resumes. The table (per split and setting:
found / seeds, mean NLPD with a 95 % Student-t interval over the seeds, worst NLPD, mean CPU
seconds) is printed and written as ``starts.md`` and ``starts.csv``, with ``starts.png``
(NLPD of every cell against the fit seed, one panel per split).

Usage::

    python benchmarks/mixture_starts.py --splits 0,1,2 --seeds 0,1,2,3,4 --n-init 1,5,20 \
        --out results/mixture_starts
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch
from matplotlib.figure import Figure
from mixture_scale import load_randhie
from scipy import stats
from threadpoolctl import threadpool_limits

from probaff._cli_errors import report_error, run_cli
from probaff._io import atomic_save_figure, atomic_write_text
from probaff._threads import limit_threads
from probaff.eval.metrics import nlpd, rmse
from probaff.models import MixtureOfGPExperts, fit_em


def _ints(text: str, flag: str, least: int) -> list[int]:
    """Comma-separated integers >= `least`; ValueError names the flag."""
    values = []
    for part in (t.strip() for t in text.split(",")):
        if not part.lstrip("-").isdigit() or int(part) < least:
            raise ValueError(f"{flag} takes integers >= {least} separated by commas, got {part!r}")
        values.append(int(part))
    return list(dict.fromkeys(values))


def run_cell(split: int, seed: int, n_init: int, args: argparse.Namespace) -> dict[str, Any]:
    """Fit on split `split` with fit seed `seed` and `n_init` restarts; score held-out rows."""
    data = load_randhie(args.n, args.test, argparse.Namespace(seed=split))
    em: dict[str, Any] = {"seed": seed, "n_init": n_init}
    if args.max_iter is not None:
        em["max_iter"] = args.max_iter
    with limit_threads(1), threadpool_limits(1):
        start = time.process_time()
        model = MixtureOfGPExperts(args.n_experts)
        history = fit_em(model, data.x, data.y, **em)
        cpu = time.process_time() - start
        with torch.no_grad():
            pred = model.predict(data.x_test)
    return {
        "split": split,
        "seed": seed,
        "n_init": n_init,
        "setup": _setup(args),
        "nlpd": float(nlpd(pred, data.y_test).sum()),
        "rmse": float(rmse(pred, data.y_test).mean()),
        "objective": float(history.best),
        "fit_cpu_s": cpu,
    }


def _setup(args: argparse.Namespace) -> dict[str, Any]:
    return {k: getattr(args, k) for k in ("n", "test", "n_experts", "max_iter")}


def summarise(cells: list[dict[str, Any]], goal: float) -> list[dict[str, Any]]:
    """One row per (split, n_init): found count, mean NLPD and interval, worst, mean CPU."""
    rows = []
    for split in sorted({c["split"] for c in cells}):
        for k in sorted({c["n_init"] for c in cells}):
            mine = [c for c in cells if c["split"] == split and c["n_init"] == k]
            if not mine:
                continue
            values = np.array([c["nlpd"] for c in mine])
            half = float("nan")
            if len(values) > 1:
                scale = values.std(ddof=1) / np.sqrt(len(values))
                half = float(stats.t.ppf(0.975, len(values) - 1) * scale)
            rows.append(
                {
                    "split": split,
                    "n_init": k,
                    "found": int((values <= goal).sum()),
                    "seeds": len(values),
                    "nlpd_mean": float(values.mean()),
                    "nlpd_half_width": half,
                    "nlpd_worst": float(values.max()),
                    "cpu_mean_s": float(np.mean([c["fit_cpu_s"] for c in mine])),
                }
            )
    return rows


def table_markdown(rows: list[dict[str, Any]], goal: float) -> str:
    """The summary as a Markdown table."""
    lines = [
        f"Found: held-out NLPD <= {goal} nats per point. Interval: 95 % Student t over seeds.",
        "",
        "| split | n_init | found | NLPD mean ± | worst NLPD | fit CPU s |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['split']} | {r['n_init']} | {r['found']}/{r['seeds']} | "
            f"{r['nlpd_mean']:.3f} ± {r['nlpd_half_width']:.3f} | {r['nlpd_worst']:.3f} | "
            f"{r['cpu_mean_s']:.1f} |"
        )
    return "\n".join(lines) + "\n"


def table_csv(rows: list[dict[str, Any]]) -> str:
    """The summary as CSV."""
    keys = list(rows[0]) if rows else []
    body = [",".join(keys)] + [",".join(str(r[k]) for k in keys) for r in rows]
    return "\n".join(body) + "\n"


def plot(cells: list[dict[str, Any]], goal: float, path: Path) -> None:
    """NLPD of every cell against the fit seed, one panel per split, one marker per n_init."""
    splits = sorted({c["split"] for c in cells})
    fig = Figure(figsize=(4 * len(splits), 3.2))
    axes = fig.subplots(1, len(splits), squeeze=False)[0]
    for ax, split in zip(axes, splits, strict=True):
        for k in sorted({c["n_init"] for c in cells}):
            mine = [c for c in cells if c["split"] == split and c["n_init"] == k]
            mine.sort(key=lambda c: c["seed"])
            ax.plot([c["seed"] for c in mine], [c["nlpd"] for c in mine], "o-", label=f"n_init={k}")
        ax.axhline(goal, color="grey", ls="--", lw=0.8)
        ax.set(title=f"split {split}", xlabel="fit seed", ylabel="held-out NLPD (nats/point)")
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    atomic_save_figure(fig, path, dpi=120)


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """Command-line options."""
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0])
    ap.add_argument("--splits", default="0,1,2")
    ap.add_argument("--seeds", default="0,1,2,3,4")
    ap.add_argument("--n-init", default="1,5,20", help="EMOptions.n_init settings compared")
    ap.add_argument("--n", type=int, default=2000, help="training rows")
    ap.add_argument("--test", type=int, default=2000, help="held-out rows")
    ap.add_argument("--n-experts", type=int, default=3)
    ap.add_argument("--max-iter", type=int, default=None, help="fit_em max_iter (default)")
    ap.add_argument("--goal", type=float, default=-0.48, help="NLPD that counts as found")
    ap.add_argument("--out", default="results/mixture_starts")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    """Run every missing cell, print the summary and write its tables and figure."""
    args = parse_args(argv)
    try:
        splits = _ints(args.splits, "--splits", 0)
        seeds = _ints(args.seeds, "--seeds", 0)
        settings = _ints(args.n_init, "--n-init", 1)
        for flag in ("n", "test", "n_experts"):
            if getattr(args, flag) <= 0:
                raise ValueError(f"--{flag.replace('_', '-')} must be a positive integer")
        if args.n + args.test > 20190:
            raise ValueError("--n plus --test must be at most RAND HIE's 20,190 rows")
        if not np.isfinite(args.goal):
            raise ValueError(f"--goal must be a finite number, got {args.goal}")
    except ValueError as exc:
        return report_error("mixture_starts", exc)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    cells = []
    for split in splits:
        for seed in seeds:
            for k in settings:
                path = out / f"split{split}_seed{seed}_ninit{k}.json"
                cell = json.loads(path.read_text()) if path.exists() else None
                if cell is None or cell.get("setup") != _setup(args):
                    cell = run_cell(split, seed, k, args)
                    atomic_write_text(path, json.dumps(cell, indent=1) + "\n")
                    print(
                        f"split {split} seed {seed} n_init {k}: NLPD {cell['nlpd']:.3f}, "
                        f"{cell['fit_cpu_s']:.1f} CPU s",
                        flush=True,
                    )
                cells.append(cell)
    rows = summarise(cells, args.goal)
    text = table_markdown(rows, args.goal)
    atomic_write_text(out / "starts.md", text)
    atomic_write_text(out / "starts.csv", table_csv(rows))
    plot(cells, args.goal, out / "starts.png")
    print(text, end="")
    print(f"wrote {out / 'starts.md'}, {out / 'starts.csv'} and {out / 'starts.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main, prog="mixture_starts"))
