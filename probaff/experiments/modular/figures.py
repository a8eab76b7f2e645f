"""Figures of the chapter 6 study, drawn from its task records, summaries and test datasets.

The drawing itself lives in `probaff.experiments.modular.drawing` and
`probaff.experiments.modular.charts`; this module turns the study's records (effects in
action frames) back into world poses for them:

* ``tabletop_predictions.png``: the first test scenes of the first trial at the smallest
  training size, two-object scenes and the first chain, observed against chained samples
  (and the monolithic prediction where it exists);
* ``sideview_predictions.png``: the first test picks and places of that trial;
* ``chain_errors.png``, ``modular_vs_monolithic.png``, ``learning_curves.png``: from the
  summary rows.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from probaff.data.store import load_dataset, load_skill_dataset
from probaff.experiments.modular.charts import (
    plot_chain_errors,
    plot_learning_curves,
    plot_modular_vs_monolithic,
)
from probaff.experiments.modular.config import THESIS, TRAININGS
from probaff.experiments.modular.drawing import plot_sideview_predictions, plot_tabletop_predictions
from probaff.experiments.modular.trials import TrialSettings, skill_rows
from probaff.features.action_frame import apply_effect, planar_pose_from_sideview
from probaff.features.ch6_pick import SIDEVIEW_EFFECT_COLUMNS
from probaff.features.ch6_scenes import push_scenes

__all__ = ["study_figures"]

_SHOWN_CASES = 5  # picks and places drawn per skill


def _first(records: list[dict[str, Any]], part: str) -> dict[str, Any] | None:
    """The record of `part` with the smallest training size and the first test slice."""
    rs = [r for r in records if r["part"] == part]
    if not rs:
        return None
    return min(rs, key=lambda r: (r["n_train"], r["test_rows"][0]))


def _tabletop_scenes(
    path: str, block: dict[str, Any], mono: dict[str, Any] | None, label: str
) -> list[dict[str, Any]]:
    """Figure inputs of the kept scenes of one test set."""
    ds = load_dataset(path)
    scenes = push_scenes(ds)
    out = []
    samples = np.asarray(block["samples"])
    for j, i in enumerate(block["rows"][: len(samples)]):
        yaw = ds["push_yaw"][i]
        start = ds["state_before"][i]
        origin = ds["push_origin"][i]
        end = origin + ds["push_distance"][i] * np.array([np.cos(yaw), np.sin(yaw)])
        mono_final = None
        if mono is not None:
            d = np.asarray(mono["mean"])[j]  # (K, 3) off, along, turn in A
            R = scenes.T_world_action[i][:2, :2]
            mono_final = start + np.column_stack([d[:, :2] @ R.T, d[:, 2]])
        out.append(
            {
                "sizes": scenes.sizes[i],
                "start": start,
                "true_final": ds["state_after"][i],
                "true_path": ds["traj_objects"][i] if ds.has_trajectories else None,
                "samples": samples[j],
                "hand_start": origin,
                "hand_end": end,
                "monolithic_final": mono_final,
                "label": f"{label}, scene {i}",
            }
        )
    return out


def _sideview_cases(
    skill: str, path: str, record: dict[str, Any], settings: TrialSettings
) -> list[dict[str, Any]]:
    """Figure inputs of the first test cases of one pick or place record."""
    ds = load_skill_dataset(path)
    rows = skill_rows(path, skill, settings.skill_groups)
    cases = []
    n_test = len(record["true"])
    for j in range(min(_SHOWN_CASES, n_test)):
        i = int(record["test_rows"][j])
        effect = np.zeros(6)
        effect[list(SIDEVIEW_EFFECT_COLUMNS)] = record["forward"]["mean"][j]
        origin = rows.T_world_before[i]
        pred = planar_pose_from_sideview(
            apply_effect(rows.T_world_action[i][None], origin[None], effect[None])
        )[0]
        sd = np.asarray(record["forward"]["sd"][j])
        present = ds.present[i]
        length = int(ds["traj_length"][i])
        cases.append(
            {
                "skill": skill,
                "success": bool(record["success"][j]),
                "label": f"test {i}",
                "sizes": ds["size"][i][present][:, [0, 2]],
                "start": ds["state_before"][i][present],
                "true_final": ds["state_after"][i][present],
                "target": int(np.flatnonzero(present).tolist().index(int(ds["target"][i]))),
                "pred_final": pred,
                "pred_sd": np.array([sd[1], sd[0], sd[2]]),
                "tcp_commanded": ds["ee_commanded"][i, :length, :2],
                "tcp_actual": ds["ee_actual"][i, :length, :2],
            }
        )
    return cases


def _curves(
    backward: list[dict[str, Any]],
    two: list[dict[str, Any]],
    skills: list[dict[str, Any]],
    chains: list[dict[str, Any]],
) -> list[dict[str, Any]]:
    def point(panel: str, series: str, r: dict[str, Any], value: str, ci: str) -> dict[str, Any]:
        return {
            "panel": panel,
            "series": series,
            "train_size": r["n_train"],
            "value": r[value],
            "ci": r[ci],
        }

    rows = [
        point("o1 along the push, hand rows (cm)", r["model"], r, "along_cm", "along_ci")
        for r in backward
    ]
    rows += [
        point(
            f"o{r['object']} along the push, two objects (cm)",
            r["model"],
            r,
            "error_cm",
            "error_ci",
        )
        for r in two
        if r["axis"] == "along"
    ]
    rows += [
        point(f"{r['skill']} position error (cm)", r["model"], r, "error_cm", "error_ci")
        for r in skills
        if r["case"] == "all"
    ]
    for r in chains:
        if r["object"] == r["n_objects"]:
            extra = "" if r["training"] == TRAININGS["push"] else f", {r['training']}"
            series = f"{r['n_objects']} objects{extra}"
            rows.append(point("last object of a chain (cm)", series, r, "error_cm", "error_ci"))
    return rows


def study_figures(
    settings: TrialSettings,
    paths: dict[str, str],
    records: list[dict[str, Any]],
    tables: dict[str, list[dict[str, Any]]],
    out: Path,
) -> list[str]:
    """Draw every figure of the study into `out`.

    Args:
        settings: The trials' settings (the feature groups of the pick and place rows).
        paths: The study's datasets by name (``push_test``, ``chain_3``, ...).
        records: The trials' records.
        tables: The summary rows by table: ``backward``, ``two``, ``skills``, ``chains``.
        out: Output folder.

    Returns:
        The written paths.
    """
    backward, two, skills, chains = (tables[k] for k in ("backward", "two", "skills", "chains"))
    files = []
    first = _first(records, "push")
    if first is not None:
        scenes = _tabletop_scenes(
            paths["push_test"],
            first["two"]["modular"] | {"rows": first["two"]["rows"]},
            first["two"]["monolithic"],
            "two objects",
        )
        for k, block in sorted(first["chains"].items()):
            scenes += _tabletop_scenes(paths[f"chain_{k}"], block, None, f"{k} objects")[:1]
        files.append(
            plot_tabletop_predictions(
                scenes,
                out / "tabletop_predictions.png",
                title="Pushes: observed (green) against chained samples (blue)",
            )
        )
    cases = []
    for skill in ("pick", "place"):
        rec = _first(records, skill)
        if rec is not None:
            cases += _sideview_cases(skill, paths[f"{skill}_test"], rec, settings)
    if cases:
        files.append(
            plot_sideview_predictions(
                cases,
                out / "sideview_predictions.png",
                title="Pick and place: observed (green) against predicted (blue)",
            )
        )
    for part, name in (("push", "chain_errors.png"), ("chained", "chain_errors_extended.png")):
        shown = [r for r in chains if r["training"] == TRAININGS[part]]
        smallest = min((r["n_train"] for r in shown), default=None)
        if smallest is not None:
            files.append(
                plot_chain_errors(
                    [r for r in shown if r["n_train"] == smallest],
                    out / name,
                    title=f"Chained predictions, push model of {TRAININGS[part]} "
                    f"({smallest} two-object pushes)",
                )
            )
    smallest = min((r["n_train"] for r in two), default=None)
    if smallest is not None:
        mod, mono = THESIS["modular_along_cm"], THESIS["monolithic_along_cm"]
        thesis = {
            ("modular", 1, "along"): mod[0],
            ("modular", 2, "along"): mod[1],
            ("monolithic", 1, "along"): mono[0],
            ("monolithic", 2, "along"): mono[1],
        }
        files.append(
            plot_modular_vs_monolithic(
                [r for r in two if r["n_train"] == smallest],
                out / "modular_vs_monolithic.png",
                thesis=thesis,
                title=f"Two-object scenes ({smallest} training pushes)",
            )
        )
    curves = _curves(backward, two, skills, chains)
    if curves:
        files.append(
            plot_learning_curves(
                curves, out / "learning_curves.png", title="Errors against training-set size"
            )
        )
    return files
