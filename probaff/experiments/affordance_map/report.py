"""Tables and summary of the affordance-map study: curves over steps, areas, the classifier.

`summarise` turns the maps' results into the per-step curves of each policy (a loop that
stopped early keeps its last state), the rows of ``entropy.csv`` and the summary numbers:
the classifier's precision and recall, Fig. 3.7 as the thesis plots it (`fig_3_7`: the mean
map entropy at steps 1-19 with 95 % intervals over maps, the step where each loop stopped,
and the "falls faster" verdict judged only on the steps where both loops still push), the
areas under the entropy curves with their 95 % intervals over maps (a stopped loop's last
entropy carried flat to ``max_steps``, so an area mixes the fall with the stop), the paired
difference of the two policies' areas, and the steps each needs to reach ``entropy_target``.
`markdown` writes them as ``summary.md``; `fig_3_7_csv` writes Fig. 3.7's table.
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np

from probaff.eval.metrics import mean_halfwidth
from probaff.experiments.affordance_map.config import AffordanceMapConfig
from probaff.grid import DIRECTION_NAMES
from probaff.planning import POLICIES
from probaff.sim import WarehouseSpec

__all__ = [
    "FIG_3_7_STEPS",
    "VERDICTS",
    "fig_3_7",
    "fig_3_7_csv",
    "markdown",
    "pushes_made",
    "steps_to",
    "summarise",
]

FIG_3_7_STEPS = 19
"""Last manipulation step of Fig. 3.7: the thesis plots the mean map entropy at steps 1-19."""

VERDICTS = ("faster", "slower", "unresolved")
"""Values of the Fig. 3.7 verdict: the information-gain loop's entropy falls faster than the
exhaustive loop's (the paired interval lies below zero), slower (above zero), or neither."""

_METRIC = "entropy_mrf"  # Fig. 3.7's quantity: both loops' maps scored by the same MRF


def _curves(results: list[dict[str, Any]], policy: str, key: str, steps: int) -> np.ndarray:
    """(n_maps, steps + 1) values of `key`, each map's last value carried to the end."""
    out = np.full((len(results), steps + 1), np.nan)
    for i, res in enumerate(results):
        values = [
            np.nan if s[key] is None else float(s[key]) for s in res["policies"][policy]["steps"]
        ]
        out[i, : len(values)] = values
        out[i, len(values) :] = values[-1]
    return out


def _nan_stats(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-step mean and standard deviation over maps, skipping NaN (all-NaN gives NaN)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmean(v, 0), np.nanstd(v, 0)


THESIS_PRECISION_RECALL: dict[str, tuple[float, float]] = {
    "up/down": (0.815, 0.797),
    "left/right": (0.731, 0.741),
}
"""The thesis's per-cell precision and recall (chapter 3, 10-fold CV), by direction pair."""


def _precision_recall(
    results: list[dict[str, Any]], pairs: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """Precision and recall per direction (4,), or per direction pair (2,) if `pairs`."""
    counts = [
        np.sum([r["classifier"][k] for r in results], 0).astype(float) for k in ("tp", "fp", "fn")
    ]
    if pairs:  # up + down, left + right
        counts = [c.reshape(2, 2).sum(1) for c in counts]
    tp, fp, fn = counts
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(tp + fp > 0, tp / (tp + fp), 0.0), np.where(
            tp + fn > 0, tp / (tp + fn), 0.0
        )


def _auc(curve: np.ndarray) -> float:
    """Area under a per-step curve (trapezoid rule, one unit per step)."""
    c = np.asarray(curve, dtype=float)
    return float(np.sum(0.5 * (c[1:] + c[:-1]))) if c.size > 1 else float(c.sum())


def steps_to(curve: np.ndarray, target: float) -> float:
    """First step at which a map's curve falls to `target` times its start; NaN if never."""
    reached = np.flatnonzero(curve <= target * curve[0])
    return float(reached[0]) if reached.size and curve[0] > 0 else math.nan


def _mean_ci(values: list[float]) -> tuple[float | None, float | None]:
    """Mean and 95 % Student-t half-width of the finite values (None when there are none)."""
    v = [x for x in values if math.isfinite(x)]
    if not v:
        return None, None
    return float(np.mean(v)), (mean_halfwidth(v) if len(v) > 1 else None)


def pushes_made(results: list[dict[str, Any]], policy: str) -> np.ndarray:
    """(n_maps,) int pushes each map's loop made: the step of its last state, where it stopped.

    Args:
        results: The maps' results (`map_task`).
        policy: One of `POLICIES`.

    Returns:
        Per map, the number of recorded steps after step 0.
    """
    return np.array([len(r["policies"][policy]["steps"]) - 1 for r in results], dtype=int)


def _verdict(mean: float | None, ci: float | None) -> str | None:
    """One of `VERDICTS` for a paired difference (info gain minus exhaustive); None unjudged."""
    if mean is None or ci is None:
        return None
    if mean + ci < 0:
        return "faster"
    return "slower" if mean - ci > 0 else "unresolved"


def fig_3_7(
    results: list[dict[str, Any]], curves: dict[str, dict[str, np.ndarray]], max_steps: int
) -> dict[str, Any]:
    """Fig. 3.7 as the thesis plots it, and its verdict judged where both loops still push.

    The map entropy is the MRF's (``entropy_mrf``: both loops' beliefs scored by the same
    model, so a difference comes from the pushes chosen). Per step ``t`` in 1 ..
    ``min(FIG_3_7_STEPS, max_steps)``: each loop's mean over all maps with its 95 % Student-t
    half-width (a stopped loop's last entropy carried flat, as the curves hold it), the maps
    whose loop is still pushing (made at least ``t`` pushes), and the paired difference of
    the entropy drops ``(H_ig(t) - H_ig(0)) - (H_ex(t) - H_ex(0))`` over the maps where
    both loops still push at ``t``. The verdict takes one number per map, the mean of that
    difference over the steps ``1 .. min(pushes_ig, pushes_ex)`` where both loops push (maps
    where either made no push drop out), and judges its 95 % interval over maps: below zero
    is "faster", above zero "slower", else "unresolved" (None with fewer than two maps).

    Args:
        results: The maps' results (`map_task`).
        curves: Policy -> quantity -> ``(n_maps, max_steps + 1)`` curves (`summarise`).
        max_steps: Most pushes per map and policy.

    Returns:
        ``steps``; ``metric`` (the per-step quantity); per policy (``policies``): ``mean``,
        ``ci`` (None with one map) and ``pushing`` per step, and ``stops``: the pushes of
        each map (``per_map``), their ``median``, ``min`` and ``max``; ``paired``: ``mean``,
        ``ci`` and ``pairs`` per step;
        ``window``: the per-map means (``per_map``, None where no step is shared), their
        ``mean``, ``ci`` and ``maps``, and the steps where the per-step interval lies
        below (``steps_below``) or above (``steps_above``) zero; ``verdict``.
    """
    ig, ex = POLICIES
    last = min(FIG_3_7_STEPS, max_steps)
    steps = list(range(1, last + 1))
    made = {p: pushes_made(results, p) for p in POLICIES}
    drop = {p: curves[p][_METRIC] - curves[p][_METRIC][:, :1] for p in POLICIES}
    out: dict[str, Any] = {"steps": steps, "metric": _METRIC, "policies": {}}
    for p in POLICIES:
        stats = [_mean_ci(curves[p][_METRIC][:, t].tolist()) for t in steps]
        pushes = made[p]
        out["policies"][p] = {
            "mean": [m for m, _ in stats],
            "ci": [c for _, c in stats],
            "pushing": [int((pushes >= t).sum()) for t in steps],
            "stops": {
                "per_map": pushes.tolist(),
                "median": float(np.median(pushes)) if pushes.size else None,
                "min": int(pushes.min()) if pushes.size else None,
                "max": int(pushes.max()) if pushes.size else None,
            },
        }
    paired: dict[str, list[Any]] = {"mean": [], "ci": [], "pairs": []}
    for t in steps:
        both = (made[ig] >= t) & (made[ex] >= t)
        m, c = _mean_ci((drop[ig][both, t] - drop[ex][both, t]).tolist())
        paired["mean"].append(m)
        paired["ci"].append(c)
        paired["pairs"].append(int(both.sum()))
    out["paired"] = paired
    per_map: list[float | None] = []
    for i, shared in enumerate(np.minimum(made[ig], made[ex]).tolist()):
        d = drop[ig][i, 1 : shared + 1] - drop[ex][i, 1 : shared + 1]
        per_map.append(float(np.mean(d)) if shared > 0 else None)
    judged = [x for x in per_map if x is not None]
    mean, ci = _mean_ci(judged)
    out["window"] = {
        "per_map": per_map,
        "mean": mean,
        "ci": ci,
        "maps": len(judged),
        "steps_below": [
            t
            for t, m, c in zip(steps, paired["mean"], paired["ci"], strict=True)
            if m is not None and c is not None and m + c < 0
        ],
        "steps_above": [
            t
            for t, m, c in zip(steps, paired["mean"], paired["ci"], strict=True)
            if m is not None and c is not None and m - c > 0
        ],
    }
    out["verdict"] = _verdict(mean, ci)
    return out


def fig_3_7_csv(fig: dict[str, Any]) -> str:
    """Fig. 3.7's table as CSV text.

    Args:
        fig: What `fig_3_7` returned.

    Returns:
        One row per step: each loop's mean, 95 % half-width and maps still pushing, and the
        paired difference over the maps where both push; an empty cell is not defined.
    """
    ig, ex = POLICIES

    def cell(v: Any) -> str:
        return "" if v is None else f"{v:.6f}" if isinstance(v, float) else str(v)

    rows = [
        "step,"
        + ",".join(f"{p}_mean,{p}_ci,{p}_pushing" for p in (ig, ex))
        + ",paired_mean,paired_ci,pairs"
    ]
    for k, t in enumerate(fig["steps"]):
        row = [str(t)]
        for p in (ig, ex):
            d = fig["policies"][p]
            row += [cell(d["mean"][k]), cell(d["ci"][k]), cell(d["pushing"][k])]
        pr = fig["paired"]
        row += [cell(pr["mean"][k]), cell(pr["ci"][k]), cell(pr["pairs"][k])]
        rows.append(",".join(row))
    return "\n".join(rows) + "\n"


def summarise(
    config: AffordanceMapConfig, results: list[dict[str, Any]], training: dict[str, Any] | None
) -> tuple[dict[str, Any], str, dict[str, dict[str, np.ndarray]]]:
    """The summary numbers, the CSV text and the per-map curves of every policy."""
    steps = config.max_steps
    curves = {
        p: {
            k: _curves(results, p, k, steps)
            for k in ("entropy", "entropy_mrf", "accuracy", "distance")
        }
        for p in POLICIES
    }
    precision, recall = _precision_recall(results)
    pair_p, pair_r = _precision_recall(results, pairs=True)
    csv = [
        "policy,step,entropy_mean,entropy_std,entropy_mrf_mean,entropy_mrf_std,"
        "accuracy_mean,accuracy_std,distance_mean,distance_std,active_maps"
    ]
    means: dict[str, dict[str, np.ndarray]] = {}
    for p in POLICIES:
        stats = {k: _nan_stats(v) for k, v in curves[p].items()}
        means[p] = {k: s[0] for k, s in stats.items()}
        active = np.array(
            [[len(r["policies"][p]["steps"]) > t for t in range(steps + 1)] for r in results]
        ).sum(0)
        for t in range(steps + 1):
            row = [p, str(t)]
            for k in ("entropy", "entropy_mrf", "accuracy", "distance"):
                row += [f"{stats[k][0][t]:.6f}", f"{stats[k][1][t]:.6f}"]
            csv.append(",".join([*row, str(int(active[t]))]))
    summary: dict[str, Any] = {
        "maps": len(results),
        "classifier": {
            "precision": precision.tolist(),
            "recall": recall.tolist(),
            "pairs": {
                name: [float(pair_p[k]), float(pair_r[k])]
                for k, name in enumerate(THESIS_PRECISION_RECALL)
            },
            "training": training,
        },
        "world": {
            "blocks_per_map": float(np.mean([len(r["boxes"]) for r in results])),
            "wall_blocks_per_map": float(np.mean([len(r.get("walls", [])) for r in results])),
        },
        "policies": {},
    }
    for p in POLICIES:
        pushes = [s for r in results for s in r["policies"][p]["steps"][1:]]
        real = [s for s in pushes if s["real_box"]]
        summary["policies"][p] = {
            "entropy": means[p]["entropy"].tolist(),
            "entropy_mrf": means[p]["entropy_mrf"].tolist(),
            "accuracy": means[p]["accuracy"].tolist(),
            "distance": means[p]["distance"].tolist(),
            "entropy_auc": _auc(means[p]["entropy"]),
            "entropy_mrf_auc": _auc(means[p]["entropy_mrf"]),
            "pushes_per_map": len(pushes) / len(results),
            "moved_share": (sum(bool(s["moved"]) for s in real) / len(real)) if real else None,
            "detection_agreement": (sum(s["moved"] == s["observed"] for s in real) / len(real))
            if real
            else None,
            "phantom_pushes": len(pushes) - len(real),
            "stops": {
                reason: sum(r["policies"][p]["stop"] == reason for r in results)
                for reason in ("no_gain", "no_candidate", "max_steps")
            },
        }
    per_map_auc = {p: [_auc(c) for c in curves[p]["entropy_mrf"]] for p in POLICIES}
    for p in POLICIES:
        reach = [steps_to(c, config.entropy_target) for c in curves[p]["entropy_mrf"]]
        _, auc_ci = _mean_ci(per_map_auc[p])  # the mean is the AUC of the mean curve
        steps_mean, steps_ci = _mean_ci(reach)
        summary["policies"][p].update(
            {
                "entropy_mrf_auc_ci": auc_ci,
                # steps of the AUC window after the loop stopped, its last entropy carried
                "flat_steps_per_map": float(np.mean(steps - pushes_made(results, p))),
                "steps_to_target": steps_mean,
                "steps_to_target_ci": steps_ci,
                "reached_target": int(sum(math.isfinite(x) for x in reach)),
            }
        )
    diff = [a - b for a, b in zip(*(per_map_auc[p] for p in POLICIES), strict=True)]
    summary["auc_difference"] = dict(zip(("mean", "ci"), _mean_ci(diff), strict=True))
    summary["auc_difference"]["per_map"] = diff
    summary["fig_3_7"] = fig_3_7(results, curves, steps)
    # Fig. 3.7 holds when, on the steps where both loops still push, the paired difference's
    # whole 95 % interval lies below zero (the AUC's flat tails do not enter it).
    verdict = summary["fig_3_7"]["verdict"]
    summary["fig_3_7_holds"] = None if verdict is None else verdict == "faster"
    summary["task_seconds"] = float(sum(r["seconds"] for r in results))
    return summary, "\n".join(csv) + "\n", curves


def _fmt(v: Any, digits: int = 3) -> str:
    return "n/a" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.{digits}f}"


def _classifier_lines(c: dict[str, Any]) -> list[str]:
    """The classifier's section: precision and recall per direction and per pair (thesis's)."""
    lines = [
        "",
        "## Classifier (initial predictions on the test maps' blocks, threshold 0.5)",
        "",
        "| direction | precision | recall | thesis precision | thesis recall |",
        "|---|---|---|---|---|",
    ]
    for k, name in enumerate(DIRECTION_NAMES):
        lines.append(f"| {name} | {100 * c['precision'][k]:.1f} | {100 * c['recall'][k]:.1f} | | |")
    for name, (tp, tr) in THESIS_PRECISION_RECALL.items():
        p_, r_ = c["pairs"][name]
        lines.append(
            f"| {name} | {100 * p_:.1f} | {100 * r_:.1f} | {100 * tp:.1f} | {100 * tr:.1f} |"
        )
    return lines


def _pm(mean: float | None, ci: float | None, digits: int = 2) -> str:
    """``mean ± ci``, or just the mean without an interval, or n/a."""
    if mean is None:
        return "n/a"
    return _fmt(mean, digits) + ("" if ci is None else f" ± {_fmt(ci, digits)}")


def _stops_text(stops: dict[str, Any]) -> str:
    """Where a loop stopped over the maps: median, range and each map's pushes."""
    per_map = ", ".join(str(n) for n in stops["per_map"])
    return (
        f"median {_fmt(stops['median'], 1)}, range {stops['min']}-{stops['max']} "
        f"(per map: {per_map})"
    )


_VERDICT_TEXT = {
    "faster": "Fig. 3.7's finding holds: while both loops push, the information-gain loop's "
    "entropy falls faster (the interval lies below zero).",
    "slower": "Fig. 3.7's finding is refuted here: while both loops push, the information-gain "
    "loop's entropy falls slower (the interval lies above zero).",
    "unresolved": "Fig. 3.7's finding is not resolved: the interval holds zero.",
    None: "Fig. 3.7's finding is not judged: too few maps where both loops push for an interval.",
}


def _fig_3_7_lines(fig: dict[str, Any], maps: int) -> list[str]:
    """The Fig. 3.7 section: mean entropy by step with intervals, the stops, the verdict."""
    ig, ex = (fig["policies"][p] for p in POLICIES)
    steps = fig["steps"]
    w, pr = fig["window"], fig["paired"]
    lines = [
        "",
        "## Fig. 3.7: map entropy by manipulation step (as the thesis plots it)",
        "",
        f"Mean map entropy under the MRF over the {maps} maps at steps "
        f"{steps[0] if steps else 0}-{steps[-1] if steps else 0}, ± 95 % Student-t "
        "half-width over maps (figure: fig_3_7.png). A loop that stopped keeps its last "
        "entropy (carried flat); 'pushing' counts the maps whose loop made at least that many "
        "pushes. The paired difference is the information-gain loop's entropy drop since "
        "step 0 minus the exhaustive loop's, over the maps where both still push.",
        "",
        f"Stop step (pushes made) of the information-gain loop: {_stops_text(ig['stops'])}.",
        f"Stop step of the exhaustive loop: {_stops_text(ex['stops'])}.",
        "",
        "| step | H (MRF) info gain | pushing | H (MRF) exhaustive | pushing | "
        "paired difference, both pushing | pairs |",
        "|---|---|---|---|---|---|---|",
    ]
    for k, t in enumerate(steps):
        lines.append(
            f"| {t} | {_pm(ig['mean'][k], ig['ci'][k])} | {ig['pushing'][k]} | "
            f"{_pm(ex['mean'][k], ex['ci'][k])} | {ex['pushing'][k]} | "
            f"{_pm(pr['mean'][k], pr['ci'][k])} | {pr['pairs'][k]} |"
        )
    below = ", ".join(str(t) for t in w["steps_below"]) or "none"
    above = ", ".join(str(t) for t in w["steps_above"]) or "none"
    lines += [
        "",
        "Judged only where both loops push (per map, steps 1 to the earlier stop; the flat "
        "tails do not enter): mean over those steps of the paired difference, information "
        f"gain minus exhaustive, {_pm(w['mean'], w['ci'])} nats over {w['maps']} maps. "
        f"Steps whose paired interval lies below zero: {below}; above zero: {above}. "
        + _VERDICT_TEXT[fig["verdict"]],
    ]
    return lines


def _per_step_lines(s: dict[str, Any], steps: int) -> list[str]:
    """The per-step table: each policy's means over maps and the maps still pushing."""
    ig, ex = s["policies"]["information_gain"], s["policies"]["exhaustive"]
    lines = [
        "",
        "## Per step (means over maps; a stopped loop's last state carried flat)",
        "",
        "| step | H info gain | H exhaustive | H (MRF) info gain | H (MRF) exhaustive | "
        "acc info gain | acc exhaustive | dist info gain | dist exhaustive | "
        "maps pushing: info gain / exhaustive |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    made = {p: np.asarray(s["fig_3_7"]["policies"][p]["stops"]["per_map"]) for p in POLICIES}
    for t in range(steps + 1):
        lines.append(
            f"| {t} | {_fmt(ig['entropy'][t])} | {_fmt(ex['entropy'][t])} | "
            f"{_fmt(ig['entropy_mrf'][t])} | {_fmt(ex['entropy_mrf'][t])} | "
            f"{_fmt(ig['accuracy'][t])} | {_fmt(ex['accuracy'][t])} | "
            f"{_fmt(ig['distance'][t], 1)} | {_fmt(ex['distance'][t], 1)} | "
            f"{int((made['information_gain'] >= t).sum())} / "
            f"{int((made['exhaustive'] >= t).sum())} |"
        )
    return lines


def markdown(
    config: AffordanceMapConfig, spec: WarehouseSpec, s: dict[str, Any], steps: int
) -> str:
    """The summary's Markdown: the settings, the classifier, each policy's numbers by step."""
    ig, ex = s["policies"]["information_gain"], s["policies"]["exhaustive"]
    noise = (
        f"the head camera ({spec.camera_pans} views of {spec.camera.width} x "
        f"{spec.camera.height} pixels per scan, worlds/camera.yaml's noise model)"
        if spec.camera is not None and spec.sensor_kind == "camera"
        else f"the idealised scanner, range noise {spec.sensor_noise} m"
    )
    mrf = config.mrf
    lines = [
        "# Affordance map by interactive manipulation (chapter 3)",
        "",
        f"{s['maps']} test maps, classifier trained on {config.train_maps} other maps, seed "
        f"{config.seed}; alpha = {mrf.alpha}, J = {mrf.coupling}, J_along = "
        f"{mrf.along_coupling if mrf.along_coupling is not None else mrf.coupling}, "
        "J_sym = "
        + (
            "off (no symmetry pairs)"
            if mrf.symmetry_coupling is None
            else f"{mrf.symmetry_coupling} (the up/down and left/right symmetry pairs)"
        )
        + f", at most {config.max_steps} pushes; sensor: {noise}; "
        + (
            "the information-gain loop stops when every G < 0."
            if config.stop_at_no_gain
            else "the information-gain loop keeps pushing its best candidate even when G < 0."
        ),
        "Entropies are whole-map sums of marginal entropies (nats). The information-gain policy "
        "is scored on the MRF; the exhaustive baseline on independent unaries (coupling 0); "
        "'H (MRF)' scores both on the MRF. A loop that stopped keeps its last state.",
        f"World: {s['world']['blocks_per_map']:.1f} blocks per test map, of which "
        f"{s['world']['wall_blocks_per_map']:.1f} are interior wall blocks (as the sensor sees "
        f"them, alike); {spec.wall_segments[0]}-{spec.wall_segments[1]} wall segments of "
        f"{spec.wall_length[0]}-{spec.wall_length[1]} blocks ({', '.join(spec.wall_layouts)}), "
        f"{spec.box_row_share:g} of the boxes in rows.",
        *_classifier_lines(s["classifier"]),
        *_fig_3_7_lines(s["fig_3_7"], s["maps"]),
        "",
        "## Summary",
        "",
        f"Areas (AUC) run from step 0 to step {steps}: a loop that stopped earlier keeps its "
        "last entropy flat to the end, so an area adds that flat tail to the fall and is not "
        "a rate of fall (Fig. 3.7 above judges that).",
        "",
        f"| policy | H step 0 | H final | AUC H to step {steps}, tail flat | "
        f"AUC H (MRF) to step {steps}, tail flat | steps carried flat per map | accuracy 0 | "
        "accuracy final | distance | pushes/map | moved | detection agrees | "
        "stops (no gain / none / max) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for p, d in (("information gain", ig), ("exhaustive", ex)):
        st = d["stops"]
        lines.append(
            f"| {p} | {_fmt(d['entropy'][0])} | {_fmt(d['entropy'][-1])} | "
            f"{_fmt(d['entropy_auc'], 2)} | {_fmt(d['entropy_mrf_auc'], 2)} | "
            f"{_fmt(d['flat_steps_per_map'], 1)} | {_fmt(d['accuracy'][0])} | "
            f"{_fmt(d['accuracy'][-1])} | {_fmt(d['distance'][-1], 1)}"
            f" | {_fmt(d['pushes_per_map'], 1)} | {_fmt(d['moved_share'], 2)} | "
            f"{_fmt(d['detection_agreement'], 3)} | {st['no_gain']} / {st['no_candidate']} / "
            f"{st['max_steps']} |"
        )
    diff = s["auc_difference"]
    lines += [
        "",
        f"Per map, under the MRF (± 95 % Student-t half-width over maps): area under the "
        f"entropy curve to step {steps} (a stopped loop's last entropy carried flat) and "
        f"steps until the map entropy falls to {config.entropy_target:g} of its start (over "
        "the maps that got there).",
        "",
        f"| policy | AUC H (MRF) to step {steps}, tail flat | steps carried flat per map | "
        "steps to target | maps reaching it |",
        "|---|---|---|---|---|",
    ]
    for p, d in (("information gain", ig), ("exhaustive", ex)):
        lines.append(
            f"| {p} | {_fmt(d['entropy_mrf_auc'], 2)} ± {_fmt(d['entropy_mrf_auc_ci'], 2)} | "
            f"{_fmt(d['flat_steps_per_map'], 1)} | "
            f"{_fmt(d['steps_to_target'], 1)} ± {_fmt(d['steps_to_target_ci'], 1)} | "
            f"{d['reached_target']} / {s['maps']} |"
        )
    lines += [
        "",
        f"AUC H (MRF) to step {steps}, information gain minus exhaustive, paired by map: "
        f"{_fmt(diff['mean'], 2)} ± {_fmt(diff['ci'], 2)}. The information-gain loop carries "
        f"its last entropy flat for {_fmt(ig['flat_steps_per_map'], 1)} of these steps per "
        f"map, the exhaustive loop for {_fmt(ex['flat_steps_per_map'], 1)}: this difference "
        "weighs when each loop stopped, not how fast its entropy fell.",
    ]
    lines += _per_step_lines(s, steps)
    lines += ["", f"Task time (sum over maps): {s['task_seconds']:.1f} s."]
    if "runtime_s" in s:
        lines.append(f"Wall time of this run: {s['runtime_s']:.1f} s.")
    return "\n".join(lines) + "\n"
