"""Chapter 6's stepped push model against the whole-push model, on held-out two-object pushes.

On one push dataset of a two-object chapter 6 push scene (``--scene``: ``modular_push`` by
default, o1 pushed 35 cm, o2 ahead; ``resistance_push`` for heavy boxes pushed into others;
generated under ``--out``/data with ``--hand``, or read from ``--data``), the first ``--train``
pushes are fitted and the last ``--test`` predicted, side by side in one run:

* the whole-push model (the baseline): one GP on the whole-push rows (the hand on o1 and o1 on
  o2, `push_interactions`), chained over the two objects (`ModularTransitionModel`, mean of
  ``--chain-samples`` samples), without and with its backward component (on the hand's
  deviation at the commanded end point);
* the stepped model (`fit_stepped`): forward and backward GPs on steps of ``--step-length``
  of hand travel, rolled out step by step with and without the backward components; and
  the forward models alone fitted on the planned actions (the hand's steps from its
  commanded poses, as a rollout without reactions places it).

With ``--ablation`` the stepped model is also rolled out with the hand's reaction alone and
with the object link's reaction alone.

Reported: final-pose errors of o1 and o2 along and across the push (mean absolute and mean
signed, cm), the paired difference of the stepped model's Euclidean errors without minus with
the backward components (mean and a 95 % t interval, cm), the backward models' calibration on
the held-out steps (90 % interval coverage and NLPD per dimension, beside the forward models'
NLPD), and the share of the dataset's pushes whose hand reaction (actual minus commanded
position along the recorded path) exceeds 1 cm. Everything goes to ``--out``/stepped_push.json,
a table to ``--out``/stepped_push.md, the predicted final poses to
``--out``/stepped_push_finals.npz.

Usage: python benchmarks/stepped_push.py [--out results/ch6_stepped] [--data DIR]
    [--scene modular_push] [--n 240] [--train 160] [--test 80] [--step-length 0.025]
    [--hand compliant]
    [--gp-max-iter 50] [--max-rows 1500] [--chain-samples 64] [--seed 0] [--ablation]
"""

import argparse
import dataclasses
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from probaff._cli_errors import run_cli
from probaff._threads import limit_threads
from probaff.data.generation import GenerateConfig, generate
from probaff.data.schema import PushDataset
from probaff.data.store import load_dataset
from probaff.errors import InputError
from probaff.experiments.modular.trials import geometry_for, stepped_calibration
from probaff.features.ch6_push import PLANAR_EFFECT_COLUMNS, push_interactions
from probaff.features.ch6_scenes import push_scenes
from probaff.features.ch6_stepped import fit_stepped
from probaff.features.ch6_steps import StepOptions, StepTrajectories, step_trajectories
from probaff.models import (
    TRANSITION_GP,
    GPOptions,
    ModularTransitionModel,
    SkillTransitionModel,
    fit_transition,
)
from probaff.models.transitions.stepped_transition import (
    SteppedModelOptions,
    SteppedPushModel,
    rollout,
)
from probaff.sim.tabletop_config import load_scene

GROUPS = ("pose", "action")  # the chapter 6 study's push feature groups
SCENE = "modular_push"


def _args(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    ap.add_argument("--out", default="results/ch6_stepped")
    ap.add_argument("--data", default=None, help="an existing two-object push dataset")
    ap.add_argument("--scene", default=SCENE, help="two-object push scene to generate")
    ap.add_argument("--n", type=int, default=240, help="pushes to generate without --data")
    ap.add_argument("--train", type=int, default=160)
    ap.add_argument("--test", type=int, default=80)
    ap.add_argument("--step-length", type=float, default=0.025)
    ap.add_argument("--hand", default="compliant", choices=("stiff", "compliant"))
    ap.add_argument("--gp-max-iter", type=int, default=50)
    ap.add_argument("--max-rows", type=int, default=1500)
    ap.add_argument("--chain-samples", type=int, default=64)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--ablation", action="store_true", help="also roll out with one reaction model alone"
    )
    return ap.parse_args(argv)


def _gp(args: argparse.Namespace) -> GPOptions:
    """The GP settings of every model: `TRANSITION_GP` with the length-scale prior, and
    ``--gp-max-iter`` L-BFGS iterations per fit."""
    return dataclasses.replace(TRANSITION_GP, max_iter=args.gp_max_iter, lengthscale_prior=True)


def _check(args: argparse.Namespace) -> None:
    """Refuse bad settings before any work."""
    StepOptions(args.step_length)
    for name in ("n", "train", "test", "gp_max_iter", "chain_samples"):
        if getattr(args, name) < 1:
            raise InputError(f"--{name.replace('_', '-')} must be a positive integer.")
    if args.chain_samples < 2:
        raise InputError("--chain-samples must be at least 2.")
    if args.data is None and len(load_scene(args.scene).objects) != 2:
        raise InputError(
            f"--scene {args.scene} places {len(load_scene(args.scene).objects)} objects; the "
            "comparison needs a two-object push scene (modular_push, resistance_push)."
        )
    if args.data is None and args.train + args.test > args.n:
        raise InputError(
            f"--train {args.train} plus --test {args.test} exceed the --n {args.n} pushes; "
            "raise --n or lower them."
        )
    SteppedModelOptions(gp=_gp(args), max_rows=args.max_rows, seed=args.seed)


def _dataset(args: argparse.Namespace) -> PushDataset:
    if args.data is not None:
        ds = load_dataset(args.data)
    else:
        path = Path(args.out) / "data" / f"{args.scene}_{args.hand}_n{args.n}_s{args.seed}"
        config = GenerateConfig(scene=args.scene, n=args.n, seed=args.seed, hand=args.hand)
        ds = generate(config, path, workers=0, resume=path.exists(), progress=True)
    if ds.n_objects != 2:
        raise InputError(f"--data must hold two-object pushes, it holds {ds.n_objects} objects.")
    if args.train + args.test > len(ds):
        raise InputError(
            f"--train {args.train} plus --test {args.test} exceed the dataset's {len(ds)} pushes."
        )
    return ds


def _push_frame(yaw: np.ndarray, d: np.ndarray) -> np.ndarray:
    """(n, K, 2) world offsets `d (n, K, 2)` as (along, across) the push."""
    u = np.stack([np.cos(yaw), np.sin(yaw)], 1)[:, None]
    v = np.stack([-np.sin(yaw), np.cos(yaw)], 1)[:, None]
    return np.stack([(d * u).sum(-1), (d * v).sum(-1)], -1)


def _errors(yaw: np.ndarray, pred: np.ndarray, true: np.ndarray) -> dict[str, Any]:
    """Mean absolute final-position errors (cm) of o1 and o2 along and across the push."""
    e = _push_frame(yaw, pred[..., :2] - true[..., :2])
    out: dict[str, Any] = {}
    for k, name in enumerate(("o1", "o2")):
        out[name] = {
            "along_cm": 100 * float(np.abs(e[:, k, 0]).mean()),
            "across_cm": 100 * float(np.abs(e[:, k, 1]).mean()),
            "euclid_cm": 100 * float(np.linalg.norm(e[:, k], axis=1).mean()),
            "along_bias_cm": 100 * float(e[:, k, 0].mean()),
            "across_bias_cm": 100 * float(e[:, k, 1].mean()),
        }
    out["euclid_per_push_cm"] = (100 * np.linalg.norm(e, axis=2)).tolist()
    return out


def _stepped(
    model: SteppedPushModel, planned: SteppedPushModel, test: StepTrajectories, ablation: bool
) -> dict:
    """Final poses (n, 2, 3) of the test pushes rolled out by each stepped variant."""
    full = model.components(backward=True)
    variants = {
        "stepped_forward": full.without_backward(),
        "stepped_forward_planned": planned.components(),
        "stepped_backward": full,
    }
    if ablation:
        variants["stepped_hand_reaction_only"] = dataclasses.replace(full, link_backward=None)
        variants["stepped_link_reaction_only"] = dataclasses.replace(full, hand_backward=None)
    out = {}
    for name, comps in variants.items():
        parts = []
        for lo in tqdm(range(0, len(test), 10), desc=name):
            part = test.subset(np.arange(lo, min(lo + 10, len(test)))).scenes()
            parts.append(rollout(comps, model.geometry, part).final)
        out[name] = np.concatenate(parts)
    return out


def _whole_push(ds: PushDataset, train: np.ndarray, test: np.ndarray, args: Any) -> dict:
    """Final poses (n, 2, 3) of the test pushes under the whole-push chain, per variant."""
    geo = geometry_for(GROUPS)
    hand = push_interactions(ds, "hand", geometry=geo, reaction="end")
    obj = push_interactions(ds, "objects", geometry=geo, reaction="end")
    cols = list(PLANAR_EFFECT_COLUMNS)
    use, use_o = np.isin(hand.push, train), np.isin(obj.push, train)
    X = np.concatenate([hand.features[use], obj.features[use_o]])
    Y = np.concatenate([hand.effect[use][:, cols], obj.effect[use_o][:, cols]])
    R = np.concatenate([hand.reaction[use], obj.reaction[use_o]])
    scenes = push_scenes(ds, geometry=geo)
    out = {}
    for backward in (False, True):
        model = SkillTransitionModel("push", backward=backward, gp=_gp(args))
        fit_transition(model, X, Y, R if backward else None)
        chain = ModularTransitionModel({"push": model}, geo)
        final = []
        for j, i in enumerate(tqdm(test, desc=f"whole push (backward={backward})")):
            scene = scenes.chain_scene(i)
            pred = chain.predict_chain(scene, n_samples=args.chain_samples, seed=args.seed + j)
            final.append(pred.planar.mean(0))
        out["backward" if backward else "forward"] = np.array(final)
    return out


def _reaction_share(ds: PushDataset, steps: StepTrajectories) -> dict[str, float]:
    """Share of pushes whose hand reaction exceeds 1 cm: on the path, at step ends, at its end."""
    dev = np.asarray(ds["traj_hand"], np.float64) - np.asarray(ds["traj_commanded"], np.float64)
    peak = np.linalg.norm(dev[..., :2], axis=2).max(axis=1)
    at_steps = np.linalg.norm(steps.hand[..., :2] - steps.commanded[..., :2], axis=2).max(1)
    end = np.linalg.norm(dev[:, -1, :2], axis=1)
    return {
        "share_path_over_1cm": float((peak > 0.01).mean()),
        "share_steps_over_1cm": float((at_steps > 0.01).mean()),
        "share_end_over_1cm": float((end > 0.01).mean()),
        "median_peak_mm": 1000 * float(np.median(peak)),
        "p90_peak_mm": 1000 * float(np.percentile(peak, 90)),
        "max_peak_mm": 1000 * float(peak.max()),
    }


def _paired(a: list[list[float]], b: list[list[float]]) -> dict[str, list[float]]:
    """Mean and 95 % t interval of ``a - b`` per object (cm)."""
    d = np.asarray(a) - np.asarray(b)
    n = d.shape[0]
    mean, se = d.mean(0), d.std(0, ddof=1) / math.sqrt(n)
    z = 1.99 if n > 60 else 2.1
    return {"mean": mean.tolist(), "lo": (mean - z * se).tolist(), "hi": (mean + z * se).tolist()}


def _table(r: dict[str, Any]) -> str:
    lines = [
        "| model | o1 along | o1 across | o2 along | o2 across | o1 | o2 |",
        "|---|---|---|---|---|---|---|",
    ]
    for name, e in r["errors"].items():
        cells = [e[o][c] for o in ("o1", "o2") for c in ("along_cm", "across_cm")]
        cells += [e["o1"]["euclid_cm"], e["o2"]["euclid_cm"]]
        lines.append(f"| {name} | " + " | ".join(f"{c:.2f}" for c in cells) + " |")
    lines.append("")
    lines.append("| component | rows | NLPD per dim | 90 % coverage |")
    lines.append("|---|---|---|---|")
    for name, c in r["calibration"].items():
        nl = ", ".join(f"{v:.2f}" for v in c["nlpd"])
        cov = ", ".join(f"{v:.2f}" for v in c["coverage"])
        lines.append(f"| {name} | {c['rows']} | {nl} | {cov} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Run the comparison; the flags as in the module docstring."""
    args = _args(argv)
    _check(args)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    ds = _dataset(args)
    geo = geometry_for(GROUPS)
    steps = step_trajectories(ds, StepOptions(args.step_length), geometry=geo, reaction=True)
    n = len(ds)
    train, test = np.arange(args.train), np.arange(n - args.test, n)
    yaw, true = ds["push_yaw"][test], ds["state_after"][test]
    t0 = time.perf_counter()
    with limit_threads(1):
        options = SteppedModelOptions(gp=_gp(args), max_rows=args.max_rows, seed=args.seed)
        print("fitting the stepped model ...", file=sys.stderr)
        model = fit_stepped(steps.subset(train), geo, options, backward=True)
        planned = fit_stepped(steps.subset(train), geo, options, backward=False)
        finals = _stepped(model, planned, steps.subset(test), args.ablation)
        whole = _whole_push(ds, train, test, args)
        finals["whole_push_forward"] = whole["forward"]
        finals["whole_push_backward"] = whole["backward"]
        calibration = stepped_calibration(model, steps.subset(test))
    errors = {name: _errors(yaw, f, true) for name, f in finals.items()}
    result = {
        "command": " ".join(["python", "benchmarks/stepped_push.py", *(argv or sys.argv[1:])]),
        "dataset": {
            "pushes": n,
            "train": args.train,
            "test": args.test,
            "hand": args.hand,
            "scene": ds.meta.get("scene"),
        },
        "step_length": args.step_length,
        "steps_per_push": steps.n_steps,
        "seconds": time.perf_counter() - t0,
        "errors": {
            k: {o: v for o, v in e.items() if o != "euclid_per_push_cm"} for k, e in errors.items()
        },
        "stepped_forward_minus_backward_cm": _paired(
            errors["stepped_forward"]["euclid_per_push_cm"],
            errors["stepped_backward"]["euclid_per_push_cm"],
        ),
        "stepped_forward_planned_minus_backward_cm": _paired(
            errors["stepped_forward_planned"]["euclid_per_push_cm"],
            errors["stepped_backward"]["euclid_per_push_cm"],
        ),
        "calibration": calibration,
        "reaction": _reaction_share(ds, steps),
    }
    (out / "stepped_push.json").write_text(json.dumps(result, indent=1))
    np.savez(out / "stepped_push_finals.npz", rows=test, true=true, **finals)
    (out / "stepped_push.md").write_text(_table(result))
    print(_table(result))
    keys = [k for k in result if k.endswith("_cm") or k == "reaction"]
    print(json.dumps({k: result[k] for k in keys}))
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main))
