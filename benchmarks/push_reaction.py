"""How far the hand falls behind its command in chapter 6's push scenes, per scene and hand.

For every ``--scene`` and ``--hand`` the script generates ``--n`` pushes (seed ``--seed``,
under ``--out``/data, resumed when already there), or it reads the datasets given with
``--data``. Each push's hand reaction is the hand's actual minus its commanded position in the
table plane (world x, y; m), taken from the recorded ``traj_hand`` and ``traj_commanded``:

* ``path``: its largest norm along the recorded push (every sample at the record rate);
* ``end``: its norm at the last sample, once the command has stopped and the scene settled.

Per dataset it reports the share of pushes whose reaction exceeds ``--threshold`` (1 cm),
and the median, 90th percentile and largest reaction (mm), for all pushes and split by the
pushed object and by what the pushed object met: nothing (``free``), another object
(``object``) or a wall (``wall``); pushes whose hand never touched the object are ``missed``.
Everything goes to ``--out``/push_reaction.json, a table to ``--out``/push_reaction.md.

Usage: python benchmarks/push_reaction.py [--out results/ch6_resistance]
    [--scene resistance_push resistance_wall] [--hand compliant stiff] [--n 240] [--seed 0]
    [--threshold 0.01] [--data DIR ...]
"""

import argparse
import json
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from probaff._cli_errors import run_cli
from probaff.data.generation import GenerateConfig, generate
from probaff.data.schema import PushDataset
from probaff.data.store import load_dataset
from probaff.errors import InputError
from probaff.sim.tabletop_config import load_scene

__all__ = [
    "ReactionOptions",
    "ReactionStats",
    "main",
    "push_reactions",
    "reaction_stats",
    "reaction_summary",
]

HANDS = ("compliant", "stiff")
MET = ("free", "object", "wall", "missed")
"""What the pushed object met, in the order of the tables."""


@dataclass(frozen=True)
class ReactionOptions:
    """How reactions are summarised.

    Attributes:
        threshold_m: Reaction (m) above which a push counts as one where the hand met
            resistance; 0.01 (1 cm) by default.

    Raises:
        InputError: Naming ``--threshold``, for a threshold that is not a finite number > 0.
    """

    threshold_m: float = 0.01

    def __post_init__(self) -> None:
        t = self.threshold_m
        if isinstance(t, bool) or not isinstance(t, (int, float)) or not math.isfinite(t) or t <= 0:
            raise InputError(
                f"--threshold must be a positive finite length in metres (e.g. 0.01 for 1 cm), "
                f"got {t!r}."
            )
        object.__setattr__(self, "threshold_m", float(t))


@dataclass(frozen=True)
class ReactionStats:
    """Reactions of a group of pushes.

    Attributes:
        pushes: Pushes in the group.
        share_over: Share of them whose reaction exceeds the threshold (nan for none).
        median_mm: Median reaction (mm).
        p90_mm: 90th percentile (mm).
        max_mm: Largest reaction (mm).
    """

    pushes: int
    share_over: float
    median_mm: float
    p90_mm: float
    max_mm: float


def push_reactions(ds: PushDataset) -> dict[str, np.ndarray]:
    """Every push's hand reaction, along the path and at the end (m).

    Args:
        ds: A tabletop push dataset with trajectories (``traj_hand``, ``traj_commanded``).

    Returns:
        ``{"path": (N,), "end": (N,)}``: the largest planar norm of actual minus commanded hand
        position along the recording, and its norm at the last recorded sample (m, world).

    Raises:
        InputError: For a dataset without the trajectories, or with a push whose recording
            holds no finite sample.
    """
    for name in ("traj_hand", "traj_commanded"):
        if name not in ds.arrays:
            raise InputError(
                f"the dataset has no {name}; generate it with trajectories (without "
                "--no-trajectories)."
            )
    dev = np.asarray(ds["traj_hand"], np.float64) - np.asarray(ds["traj_commanded"], np.float64)
    norm = np.linalg.norm(dev[..., :2], axis=2)  # (N, T); padding is nan
    finite = np.isfinite(norm)
    if not finite.any(axis=1).all():
        row = int(np.flatnonzero(~finite.any(axis=1))[0])
        raise InputError(f"push {row} of the dataset has no finite trajectory sample.")
    last = finite.shape[1] - 1 - np.argmax(finite[:, ::-1], axis=1)
    path = np.where(finite, norm, -np.inf).max(axis=1)
    return {"path": path, "end": norm[np.arange(len(norm)), last]}


def reaction_stats(values: np.ndarray, options: ReactionOptions) -> ReactionStats:
    """Share over the threshold and the distribution of reactions `values` (m, any count)."""
    v = np.asarray(values, np.float64)
    if v.size == 0:
        return ReactionStats(0, math.nan, math.nan, math.nan, math.nan)
    return ReactionStats(
        pushes=int(v.size),
        share_over=float((v > options.threshold_m).mean()),
        median_mm=1000 * float(np.median(v)),
        p90_mm=1000 * float(np.percentile(v, 90)),
        max_mm=1000 * float(v.max()),
    )


def _met(ds: PushDataset) -> np.ndarray:
    """(N,) what the pushed object (object 0) met: an index into `MET`."""
    hand = np.asarray(ds["hand_contact"], bool)[:, 0]
    objects = np.asarray(ds["object_contact"], bool)[:, 0].any(axis=1)
    wall = np.asarray(ds["wall_contact"], bool).any(axis=1)
    return np.select([~hand, wall, objects], [3, 2, 1], default=0)


def reaction_summary(ds: PushDataset, options: ReactionOptions) -> dict[str, Any]:
    """The reactions of a dataset's pushes: all, by pushed object and by what it met.

    Args:
        ds: A tabletop push dataset with trajectories and contact flags.
        options: The threshold.

    Returns:
        ``{"all": {...}, "by_object": {name: {...}}, "by_met": {met: {...}}}``, each entry
        ``{"path": ReactionStats as a dict, "end": ...}``.
    """
    react = push_reactions(ds)
    pushed = np.asarray(ds["object_ids"])[:, 0]
    met = _met(ds)

    def group(mask: np.ndarray) -> dict[str, Any]:
        return {k: reaction_stats(v[mask], options).__dict__ for k, v in react.items()}

    by_object = {ds.object_names[i]: group(pushed == i) for i in np.unique(pushed) if i >= 0}
    by_met = {m: group(met == j) for j, m in enumerate(MET) if (met == j).any()}
    return {"all": group(np.ones(len(ds), bool)), "by_object": by_object, "by_met": by_met}


def _args(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    ap.add_argument("--out", default="results/ch6_resistance")
    ap.add_argument("--scene", nargs="+", default=["resistance_push", "resistance_wall"])
    ap.add_argument("--hand", nargs="+", default=["compliant"], choices=HANDS)
    ap.add_argument("--n", type=int, default=240, help="pushes per scene and hand")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threshold", type=float, default=0.01, help="m (1 cm)")
    ap.add_argument("--data", nargs="+", default=None, help="existing push datasets instead")
    return ap.parse_args(argv)


def _datasets(args: argparse.Namespace) -> dict[str, PushDataset]:
    """The datasets by label ``SCENE/HAND`` (generated or resumed), or by folder name."""
    if args.data is not None:
        return {Path(d).name: load_dataset(d) for d in args.data}
    out = {}
    for scene in args.scene:
        for hand in args.hand:
            path = Path(args.out) / "data" / f"{scene}_{hand}_n{args.n}_s{args.seed}"
            config = GenerateConfig(scene=scene, n=args.n, seed=args.seed, hand=hand)
            out[f"{scene}/{hand}"] = generate(
                config, path, workers=0, resume=path.exists(), progress=True
            )
    return out


def _check(args: argparse.Namespace) -> ReactionOptions:
    """Refuse bad settings before any work."""
    options = ReactionOptions(args.threshold)
    if args.n < 1:
        raise InputError(f"--n must be a positive integer (pushes per scene), got {args.n}.")
    if args.seed < 0:
        raise InputError(f"--seed must be an integer >= 0, got {args.seed}.")
    if args.data is None:
        for scene in args.scene:
            load_scene(scene)  # ConfigError naming the available scenes
            GenerateConfig(scene=scene, n=args.n, seed=args.seed).validate()
    return options


def _row(label: str, group: str, s: dict[str, Any]) -> str:
    p, e = s["path"], s["end"]
    return (
        f"| {label} | {group} | {p['pushes']} | {100 * p['share_over']:.1f} | "
        f"{p['median_mm']:.1f} | {p['p90_mm']:.1f} | {p['max_mm']:.1f} | "
        f"{100 * e['share_over']:.1f} | {e['median_mm']:.1f} | {e['p90_mm']:.1f} |"
    )


def _table(result: dict[str, Any]) -> str:
    t = 100 * result["threshold_m"]
    lines = [
        f"| data | pushes of | n | path > {t:g} cm (%) | path median (mm) | path p90 (mm) | "
        f"path max (mm) | end > {t:g} cm (%) | end median (mm) | end p90 (mm) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for label, summary in result["datasets"].items():
        lines.append(_row(label, "all", summary["all"]))
        for group in ("by_object", "by_met"):
            for name, s in summary[group].items():
                lines.append(_row(label, name, s))
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Measure the reactions; the flags as in the module docstring."""
    args = _args(argv)
    options = _check(args)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    datasets = _datasets(args)
    result = {
        "command": " ".join(["python", "benchmarks/push_reaction.py", *(argv or sys.argv[1:])]),
        "threshold_m": options.threshold_m,
        "hands": {label: ds.meta.get("hand") for label, ds in datasets.items()},
        "datasets": {label: reaction_summary(ds, options) for label, ds in datasets.items()},
    }
    (out / "push_reaction.json").write_text(json.dumps(result, indent=1))
    (out / "push_reaction.md").write_text(_table(result))
    print(_table(result))
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main))
