"""Tables and summary of the chapter 6 study: errors and coverage over trials, with intervals.

Each ``summarise_*`` turns the trials' records into the rows of one table: the backward
component (o1 under the hand's push), modular against monolithic on two-object scenes, pick
and place split by the simulator's verdict, and chains of 3 to 5 objects. Means are over
trials, with the half-width of their 95 % Student-t interval. `report` writes the summary.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from probaff.eval.metrics import mean_and_halfwidth
from probaff.eval.tables import markdown_table
from probaff.experiments.modular.config import THESIS, TRAININGS, ModularStudyConfig
from probaff.experiments.modular.trials import (
    LEVEL,
    PUSH_MODELS,
    SKILL_MODELS,
    STEPPED_COMPONENTS,
    STEPPED_MODELS,
)

__all__ = [
    "report",
    "summarise_backward",
    "summarise_chains",
    "summarise_skills",
    "summarise_stepped",
    "summarise_stepped_calibration",
    "summarise_stepped_paired",
    "summarise_two_objects",
]

_STILL = 0.01  # m; an object that moved less than this is "stayed put"

_BACKWARD_COLUMNS = [
    "n_train",
    "model",
    "trials",
    "along_cm",
    "along_ci",
    "off_cm",
    "off_ci",
    "turn_rad",
    "nlpd",
    "coverage90",
    "reaction_mm",
    "reaction_path_mm",
]

_TWO_COLUMNS = [
    "n_train",
    "model",
    "object",
    "axis",
    "trials",
    "error_cm",
    "error_ci",
    "coverage90",
    "still_motion_cm",
]

_SKILL_COLUMNS = [
    "skill",
    "n_train",
    "model",
    "case",
    "n",
    "predicted_cm",
    "true_cm",
    "error_cm",
    "error_ci",
    "turn_rad",
    "nlpd",
    "coverage90",
    "misjudged",
]

_CHAIN_COLUMNS = [
    "training",
    "n_train",
    "n_objects",
    "object",
    "trials",
    "error_cm",
    "error_ci",
    "along_cm",
    "coverage90",
    "coverage_ci",
    "touched",
    "moved",
    "seconds",
]


_STEPPED_COLUMNS = [
    "n_train",
    "model",
    "object",
    "trials",
    "along_cm",
    "along_ci",
    "off_cm",
    "off_ci",
    "error_cm",
    "error_ci",
]

_PAIRED_COLUMNS = ["n_train", "comparison", "object", "trials", "diff_cm", "diff_ci"]

_CALIBRATION_COLUMNS = [
    "n_train",
    "component",
    "trials",
    "rows",
    "nlpd",
    "nlpd_ci",
    "coverage90",
    "coverage_ci",
]

_STEPPED_BASELINES = ("stepped_forward", "stepped_planned")


def _by(records: list[dict[str, Any]], part: str) -> dict[int, list[dict[str, Any]]]:
    """Records of `part` grouped by training size."""
    out: dict[int, list[dict[str, Any]]] = {}
    for r in records:
        if r["part"] == part:
            out.setdefault(int(r["n_train"]), []).append(r)
    return dict(sorted(out.items()))


def summarise_backward(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per (training size, push model): o1's effect errors under the hand's push.

    Returns:
        Rows with ``n_train``, ``model``, ``trials``, ``along_cm`` / ``off_cm`` (mean
        absolute error of dy and dx) and ``turn_rad`` with their ``*_ci`` half-widths,
        ``nlpd`` (summed over the three effects), ``coverage90``, ``reaction_mm`` (the
        hand's mean deviation from its commanded end in training) and ``reaction_path_mm``
        (the mean of its largest deviation along the push; NaN for records without it).
    """
    rows = []
    for n, rs in _by(records, "push").items():
        for model in PUSH_MODELS:
            err = [
                np.abs(np.array(r["hand"][model]["mean"]) - np.array(r["hand"]["true"])).mean(0)
                for r in rs
            ]
            along, along_ci = mean_and_halfwidth([100 * e[1] for e in err])
            off, off_ci = mean_and_halfwidth([100 * e[0] for e in err])
            turn, turn_ci = mean_and_halfwidth([e[2] for e in err])
            rows.append(
                {
                    "n_train": n,
                    "model": model,
                    "trials": len(rs),
                    "along_cm": along,
                    "along_ci": along_ci,
                    "off_cm": off,
                    "off_ci": off_ci,
                    "turn_rad": turn,
                    "turn_ci": turn_ci,
                    "nlpd": float(np.mean([sum(r["hand"][model]["nlpd"]) for r in rs])),
                    "coverage90": float(np.mean([r["hand"][model]["coverage"] for r in rs])),
                    "reaction_mm": float(np.mean([r["reaction_mm"] for r in rs])),
                    "reaction_path_mm": float(
                        np.mean([r.get("reaction_path_mm", math.nan) for r in rs])
                    ),
                }
            )
    return rows


def _coverage(true: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(K,) fraction of the (off, along) coordinates of each object inside its interval."""
    inside = (lo[..., :2] <= true[..., :2]) & (true[..., :2] <= hi[..., :2])
    return inside.mean(axis=(0, 2))


def summarise_two_objects(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per (training size, model, object, axis) of the two-object test scenes.

    Returns:
        Rows with ``n_train``, ``model`` (``"modular"`` or ``"monolithic"``), ``object``
        (1-based), ``axis`` (``"along"``, ``"off"``), ``trials``, ``error_cm`` and
        ``error_ci``, ``coverage90`` of the object's (off, along) intervals, and
        ``still_motion_cm``: the mean predicted ``|along|`` motion of objects that truly moved
        less than 1 cm (NaN when none did).
    """
    rows = []
    for n, rs in _by(records, "push").items():
        for model in ("modular", "monolithic"):
            per: dict[tuple[int, str], list[float]] = {}
            cover: dict[int, list[float]] = {}
            still: dict[int, list[float]] = {}
            for r in rs:
                true = np.array(r["two"]["true"])
                pred = r["two"][model]
                mean = np.array(pred["mean"])
                err = np.abs(mean - true).mean(0)  # (K, 3)
                cov = _coverage(true, np.array(pred["lo"]), np.array(pred["hi"]))
                for k in range(true.shape[1]):
                    per.setdefault((k, "along"), []).append(100 * err[k, 1])
                    per.setdefault((k, "off"), []).append(100 * err[k, 0])
                    cover.setdefault(k, []).append(float(cov[k]))
                    put = np.linalg.norm(true[:, k, :2], axis=1) < _STILL
                    still.setdefault(k, []).extend((100 * np.abs(mean[put, k, 1])).tolist())
            for (k, axis), values in per.items():
                e, ci = mean_and_halfwidth(values)
                rows.append(
                    {
                        "n_train": n,
                        "model": model,
                        "object": k + 1,
                        "axis": axis,
                        "trials": len(rs),
                        "error_cm": e,
                        "error_ci": ci,
                        "coverage90": float(np.mean(cover[k])),
                        "still_motion_cm": float(np.mean(still[k])) if still[k] else math.nan,
                    }
                )
    return rows


def summarise_skills(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per (skill, training size, model, case) of the pick and place tests.

    Cases: ``"all"``, ``"succeeded"`` (lifted, placed) and ``"failed"``; for records that
    carry the simulator's ``"slipped"`` flags (picks, see `run`), the failed picks split
    into ``"slipped"`` (closed on but too heavy to hold: no geometric feature sees a mass)
    and ``"not grasped"`` (too wide for the span).

    Returns:
        Rows with ``skill``, ``n_train``, ``model``, ``case``, ``n`` (test cases over all
        trials), ``predicted_cm`` and ``true_cm`` (mean norm of the predicted and the
        observed displacement), ``error_cm`` and its ``error_ci`` over trials (mean norm of
        the position error), ``turn_rad`` (mean absolute turn error), ``nlpd`` and
        ``coverage90`` (all cases only) and, for picks, ``misjudged`` (cases whose
        predicted lift is on the other side of half the lift from the observed one).
    """
    rows = []
    for skill in ("pick", "place"):
        for n, rs in _by(records, skill).items():
            for model in SKILL_MODELS:
                for case in ("all", "succeeded", "failed", "slipped", "not grasped"):
                    pred_norm, true_norm, turn, per_trial = [], [], [], []
                    misjudged = 0
                    for r in rs:
                        true = np.array(r["true"])
                        mean = np.array(r[model]["mean"])
                        ok = np.array(r["success"], dtype=bool)
                        slipped = np.array(r.get("slipped", np.zeros_like(ok)), dtype=bool)
                        sel = {
                            "all": np.ones_like(ok),
                            "succeeded": ok,
                            "failed": ~ok,
                            "slipped": ~ok & slipped,
                            "not grasped": ~ok & ~slipped,
                        }[case]
                        if case in ("slipped", "not grasped") and "slipped" not in r:
                            continue
                        if not sel.any():
                            continue
                        pred_norm += np.linalg.norm(mean[sel, :2], axis=1).tolist()
                        true_norm += np.linalg.norm(true[sel, :2], axis=1).tolist()
                        err = np.linalg.norm(mean[sel, :2] - true[sel, :2], axis=1)
                        per_trial.append(float(100 * err.mean()))
                        turn += np.abs(mean[sel, 2] - true[sel, 2]).tolist()
                        half = 0.5 * np.abs(true[ok, 0]).mean() if ok.any() else math.inf
                        misjudged += int(((np.abs(mean[sel, 0]) > half) != ok[sel]).sum())
                    if not per_trial:
                        continue
                    e, ci = mean_and_halfwidth(per_trial)
                    row: dict[str, Any] = {
                        "skill": skill,
                        "n_train": n,
                        "model": model,
                        "case": case,
                        "n": len(pred_norm),
                        "predicted_cm": 100 * float(np.mean(pred_norm)),
                        "true_cm": 100 * float(np.mean(true_norm)),
                        "error_cm": e,
                        "error_ci": ci,
                        "turn_rad": float(np.mean(turn)),
                        "nlpd": (
                            float(np.mean([sum(r[model]["nlpd"]) for r in rs]))
                            if case == "all"
                            else math.nan
                        ),
                        "coverage90": (
                            float(np.mean([r[model]["coverage"] for r in rs]))
                            if case == "all"
                            else math.nan
                        ),
                        "misjudged": misjudged if skill == "pick" else "",
                    }
                    rows.append(row)
    return rows


def summarise_chains(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per (training, training size, chain length, object) of the test chains.

    Returns:
        Rows with ``training`` (`TRAININGS`: the push model of the two-object scenes, or
        the extension's with the three-object rows added), ``n_train`` (two-object
        pushes), ``n_objects``, ``object`` (1-based place in the chain),
        ``trials``, ``error_cm`` / ``error_ci`` (distance between the mean predicted and
        the observed final position), ``along_cm``, ``coverage90`` / ``coverage_ci`` (of
        the object's off and along intervals), ``touched`` (fraction of samples in which
        the object was pushed), ``moved`` (fraction of scenes in which it truly moved by
        1 cm or more) and ``seconds`` (mean time of one chained prediction).
    """
    rows = []
    for part, training in TRAININGS.items():
        rows += _chain_rows(records, part, training)
    return rows


def _chain_rows(records: list[dict[str, Any]], part: str, training: str) -> list[dict[str, Any]]:
    rows = []
    for n, rs in _by(records, part).items():
        lengths = sorted({int(k) for r in rs for k in r["chains"]})
        for k in lengths:
            recs = [r["chains"][str(k)] for r in rs]
            for obj in range(k):
                err, along, cov, touched, moved = [], [], [], [], []
                for c in recs:
                    true, mean = np.array(c["true"]), np.array(c["mean"])
                    d = np.linalg.norm(mean[:, obj, :2] - true[:, obj, :2], axis=1)
                    err.append(100 * float(d.mean()))
                    along.append(100 * float(np.abs(mean[:, obj, 1] - true[:, obj, 1]).mean()))
                    cov.append(float(_coverage(true, np.array(c["lo"]), np.array(c["hi"]))[obj]))
                    touched.append(float(np.mean(np.array(c["touched"])[:, obj])))
                    moved.append(float(np.mean(np.linalg.norm(true[:, obj, :2], axis=1) >= _STILL)))
                e, e_ci = mean_and_halfwidth(err)
                c90, c_ci = mean_and_halfwidth(cov)
                rows.append(
                    {
                        "training": training,
                        "n_train": n,
                        "n_objects": k,
                        "object": obj + 1,
                        "trials": len(recs),
                        "error_cm": e,
                        "error_ci": e_ci,
                        "along_cm": float(np.mean(along)),
                        "coverage90": c90,
                        "coverage_ci": c_ci,
                        "touched": float(np.mean(touched)),
                        "moved": float(np.mean(moved)),
                        "seconds": float(np.mean([np.mean(c["seconds"]) for c in recs])),
                    }
                )
    return rows


def _stepped_errors(r: dict[str, Any], model: str) -> np.ndarray:
    """(n, K, 3) per test scene: |off|, |along| and Euclidean final-position errors (m).

    `model` is one of `STEPPED_MODELS`, or ``"whole_push"`` (the modular chain of the
    whole-push model, from the record's two-object predictions).
    """
    true = np.array(r["stepped"]["true"])
    pred = np.array(r["two"]["modular"]["mean"] if model == "whole_push" else r["stepped"][model])
    d = pred[..., :2] - true[..., :2]
    return np.concatenate([np.abs(d), np.linalg.norm(d, axis=-1, keepdims=True)], axis=-1)


def summarise_stepped(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per (training size, model, object) of the stepped rollouts of the test scenes.

    Models: `STEPPED_MODELS` and ``"whole_push"`` (the whole-push model chained, the
    baseline). Empty for records without stepped rollouts.

    Returns:
        Rows with ``n_train``, ``model``, ``object`` (1-based), ``trials``, and the mean
        absolute final-position errors (cm) ``along_cm``, ``off_cm`` and the Euclidean
        ``error_cm``, each with its ``*_ci`` half-width over trials.
    """
    rows = []
    for n, rs in _by(records, "push").items():
        rs = [r for r in rs if "stepped" in r]
        if not rs:
            continue
        for model in (*STEPPED_MODELS, "whole_push"):
            errs = [_stepped_errors(r, model).mean(0) for r in rs]  # (K, 3) per trial
            for k in range(errs[0].shape[0]):
                along, along_ci = mean_and_halfwidth([100 * e[k, 1] for e in errs])
                off, off_ci = mean_and_halfwidth([100 * e[k, 0] for e in errs])
                euclid, euclid_ci = mean_and_halfwidth([100 * e[k, 2] for e in errs])
                rows.append(
                    {
                        "n_train": n,
                        "model": model,
                        "object": k + 1,
                        "trials": len(rs),
                        "along_cm": along,
                        "along_ci": along_ci,
                        "off_cm": off,
                        "off_ci": off_ci,
                        "error_cm": euclid,
                        "error_ci": euclid_ci,
                    }
                )
    return rows


def summarise_stepped_paired(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Paired differences of the stepped rollouts' Euclidean errors, per object.

    Each comparison is ``A - stepped_backward`` for A among ``stepped_forward``,
    ``stepped_planned`` and ``whole_push``: positive means the stepped model with its
    backward components is the better. Each trial gives the mean difference over its test
    scenes; the interval is over trials.

    Returns:
        Rows with ``n_train``, ``comparison``, ``object``, ``trials``, ``diff_cm`` and its
        ``diff_ci`` half-width.
    """
    rows = []
    for n, rs in _by(records, "push").items():
        rs = [r for r in rs if "stepped" in r]
        for model in (*_STEPPED_BASELINES, "whole_push"):
            diffs = [
                (_stepped_errors(r, model) - _stepped_errors(r, "stepped_backward"))[..., 2].mean(0)
                for r in rs
            ]
            for k in range(diffs[0].shape[0] if diffs else 0):
                d, ci = mean_and_halfwidth([100 * float(v[k]) for v in diffs])
                rows.append(
                    {
                        "n_train": n,
                        "comparison": f"{model} - stepped_backward",
                        "object": k + 1,
                        "trials": len(rs),
                        "diff_cm": d,
                        "diff_ci": ci,
                    }
                )
    return rows


def summarise_stepped_calibration(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per (training size, component): the stepped model's held-out calibration.

    Returns:
        Rows with ``n_train``, ``component`` (`STEPPED_COMPONENTS`), ``trials``, ``rows``
        (held-out steps over all trials), ``nlpd`` (mean per output dimension) and
        ``coverage90`` (of the central 90 % intervals, mean over dimensions), each with its
        half-width over trials.
    """
    rows = []
    for n, rs in _by(records, "push").items():
        cals = [r["stepped"]["calibration"] for r in rs if "stepped" in r]
        for name in STEPPED_COMPONENTS:
            got = [c[name] for c in cals if name in c and c[name]["rows"]]
            if not got:
                continue
            nl, nl_ci = mean_and_halfwidth([float(np.mean(c["nlpd"])) for c in got])
            cov, cov_ci = mean_and_halfwidth([float(np.mean(c["coverage"])) for c in got])
            rows.append(
                {
                    "n_train": n,
                    "component": name,
                    "trials": len(got),
                    "rows": int(sum(c["rows"] for c in got)),
                    "nlpd": nl,
                    "nlpd_ci": nl_ci,
                    "coverage90": cov,
                    "coverage_ci": cov_ci,
                }
            )
    return rows


def _fmt(rows: list[dict[str, Any]], columns: list[str]) -> str:
    return markdown_table(rows, columns, digits=3)


def report(
    config: ModularStudyConfig,
    backward: list[dict[str, Any]],
    two: list[dict[str, Any]],
    skills: list[dict[str, Any]],
    chains: list[dict[str, Any]],
    stepped: dict[str, list[dict[str, Any]]] | None = None,
) -> str:
    """The summary's Markdown: each table with the thesis's numbers beside it.

    `stepped` holds the rows of `summarise_stepped` (``"rows"``), `summarise_stepped_paired`
    (``"paired"``) and `summarise_stepped_calibration` (``"calibration"``); its section is
    left out when it is ``None`` or holds no rows.
    """
    fwd, bwd = THESIS["backward_along_cm"]
    mod, mono = THESIS["modular_along_cm"], THESIS["monolithic_along_cm"]
    md = [
        "# Chapter 6: modular transition models",
        "",
        f"Hand: {config.hand} (how the simulated hand follows its command); push scene: "
        f"`{config.push_scene}`. "
        f"{config.trials} trials per training size; each trial fits on its own draw of the "
        f"training pool and predicts its own {config.test_scenes} test scenes per skill. "
        "`*_ci`: half-width of the 95 % Student-t interval of the mean over trials; "
        f"coverage: fraction of observations inside the central {LEVEL:.0%} interval.",
        "",
        "## The backward component (o1 under the hand's push)",
        "",
        f"Thesis: push-along error {fwd} cm without, {bwd} cm with the backward component. "
        "`reaction_mm`: the simulated hand's mean deviation from its commanded end point; "
        "`reaction_path_mm`: the mean of its largest deviation along the push; the backward "
        f"component learns the reaction `{config.settings.reaction}` "
        "(`end`: the end point; `path`: the end point and the mean along the push).",
        "",
        _fmt(backward, _BACKWARD_COLUMNS),
        "",
        "## Modular against monolithic (two-object scenes)",
        "",
        f"Thesis, along the push: modular {mod[0]} vs monolithic {mono[0]} cm for o1, "
        f"{mod[1]} vs {mono[1]} cm for o2; the monolithic model was better off the axis. "
        "`still_motion_cm`: mean predicted motion along the push of objects that truly "
        "moved less than 1 cm.",
        "",
        _fmt(two, _TWO_COLUMNS),
        "",
        "## Pick and place",
        "",
        "Effects in the action frame: up (along the lift or the lowering), x, the turn. "
        "Thesis: cases that cannot be picked are predicted at about zero displacement; two "
        "graspable objects were predicted not pickable.",
        "",
        _fmt(skills, _SKILL_COLUMNS),
        "",
        "## Chains of 3 to 5 objects",
        "",
        "The monolithic model cannot predict these scenes (another number of objects); the "
        "modular model chains its push model through them. `training`: the push model of the "
        "two-object scenes (the thesis's), or the same model with the hand and object rows of "
        f"{config.chain_train} three-object `chain_3` pushes added (so the 4- and 5-object "
        "chains are longer than any it saw). `touched`: share of samples in which the object "
        "was pushed; `moved`: share of scenes in which it truly moved by 1 cm or more.",
        "",
        _fmt(chains, _CHAIN_COLUMNS),
        "",
    ]
    if stepped and stepped.get("rows"):
        md += [
            "## The stepped push model (two-object scenes)",
            "",
            f"Each push cut into steps of {100 * config.settings.step_length:g} cm of "
            "commanded hand travel and rolled out step by step: predict the step's effect, "
            "then its reaction, move the object, set the hand to its command plus the "
            "reaction (thesis section 6.3.1). `stepped_backward`: with the backward "
            "components; `stepped_forward`: the same forward models, the hand kept on its "
            "command; `stepped_planned`: forward models fitted on the planned actions, as a "
            "rollout without reactions places the hand (the fair baseline); `whole_push`: "
            f"the whole-push chain above. Thesis: {fwd} cm without, {bwd} cm with the "
            "backward component (o1 along the push). Final-position errors:",
            "",
            _fmt(stepped["rows"], _STEPPED_COLUMNS),
            "",
            "Paired differences of the Euclidean error (positive: the stepped model with "
            "its backward components is the better), mean over trials of each trial's mean "
            "over its test scenes:",
            "",
            _fmt(stepped["paired"], _PAIRED_COLUMNS),
            "",
            "The components on the held-out steps (goal: backward 90 % intervals cover "
            "85-95 %, backward NLPD within 2 nats of the forward model's):",
            "",
            _fmt(stepped["calibration"], _CALIBRATION_COLUMNS),
            "",
        ]
    return "\n".join(md)
