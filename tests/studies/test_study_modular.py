"""The chapter 6 study runs end to end on a shrunken configuration, resumes, and its
summaries compute what the records hold."""

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from probaff.errors import InputError
from probaff.studies.modular import (
    ModularStudyConfig,
    run,
    summarise_chains,
    summarise_skills,
    summarise_two_objects,
)
from probaff.studies.modular_trials import TrialSettings

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_script_smoke_and_resume(tmp_path):
    out = tmp_path / "modular"
    cmd = [sys.executable, str(ROOT / "inference/modular.py"), "--smoke", "--out", str(out)]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=True)
    files = json.loads(proc.stdout)["files"]
    for name in (
        "backward.csv",
        "two_objects.csv",
        "pick_place.csv",
        "chains.csv",
        "summary.md",
        "tabletop_predictions.png",
        "sideview_predictions.png",
        "chain_errors.png",
        "modular_vs_monolithic.png",
        "learning_curves.png",
    ):
        assert str(out / name) in files and (out / name).stat().st_size > 0
    text = (out / "summary.md").read_text()
    assert "5.8 cm without, 2.57 cm with" in text and "| monolithic | 2 | along |" in text
    tasks = sorted((out / "tasks").glob("*.json"))
    assert len(tasks) == 4 * 2  # (push, pick, place, chained) x 2 trials at one scale
    records = [json.loads(p.read_text()) for p in tasks]
    push = [r for r in records if r["part"] == "push"]
    assert {tuple(r["test_rows"]) for r in push} == {(0, 1), (2, 3)}  # disjoint test slices
    for r in push:
        assert np.asarray(r["two"]["modular"]["mean"]).shape == (2, 2, 3)
        assert np.asarray(r["chains"]["3"]["lo"]).shape == (2, 3, 3)
        lo, hi = np.asarray(r["chains"]["3"]["lo"]), np.asarray(r["chains"]["3"]["hi"])
        assert np.all(lo <= hi)
    stamp = [p.stat().st_mtime_ns for p in tasks]
    subprocess.run(cmd, capture_output=True, text=True, check=True)  # resumes: no reruns
    assert [p.stat().st_mtime_ns for p in tasks] == stamp


def _push_record(trial, true, modular, mono):
    def block(mean):
        mean = np.asarray(mean, dtype=float)
        return {"mean": mean.tolist(), "lo": (mean - 0.01).tolist(), "hi": (mean + 0.01).tolist()}

    chain = block(np.asarray(modular)[:, [0, 1, 1]])
    return {
        "part": "push",
        "n_train": 10,
        "test_rows": [trial],
        "two": {
            "rows": [trial],
            "true": true,
            "modular": block(modular),
            "monolithic": block(mono),
        },
        "chains": {
            "3": {
                **chain,
                "true": np.asarray(true)[:, [0, 1, 1]].tolist(),
                "touched": [[1.0, 1.0, 0.5]],
                "seconds": [0.2],
            }
        },
    }


def test_two_object_and_chain_summaries_score_the_means():
    true = [[[0.0, 0.10, 0.0], [0.0, 0.0, 0.0]]]  # o1 moved 10 cm along, o2 stayed put
    recs = [
        _push_record(
            0, true, [[[0.01, 0.12, 0.0], [0.0, 0.005, 0.0]]], [[[0.0, 0.06, 0], [0, 0.03, 0]]]
        ),
        _push_record(
            1, true, [[[0.03, 0.10, 0.0], [0.0, 0.015, 0.0]]], [[[0.0, 0.08, 0], [0, 0.01, 0]]]
        ),
    ]
    rows = {(r["model"], r["object"], r["axis"]): r for r in summarise_two_objects(recs)}
    assert rows["modular", 1, "along"]["error_cm"] == pytest.approx(1.0)  # (2 + 0) / 2 cm
    assert rows["modular", 1, "off"]["error_cm"] == pytest.approx(2.0)  # (1 + 3) / 2 cm
    assert rows["monolithic", 1, "along"]["error_cm"] == pytest.approx(3.0)  # (4 + 2) / 2 cm
    assert rows["monolithic", 2, "along"]["still_motion_cm"] == pytest.approx(2.0)
    assert rows["modular", 2, "along"]["still_motion_cm"] == pytest.approx(1.0)
    # t interval of the two per-trial errors 2 and 0: 12.706 * sd / sqrt(2)
    assert rows["modular", 1, "along"]["error_ci"] == pytest.approx(
        12.706 * math.sqrt(2) / math.sqrt(2), rel=1e-3
    )
    chains = summarise_chains(recs)
    assert [r["object"] for r in chains] == [1, 2, 3]
    assert chains[0]["error_cm"] == pytest.approx(np.mean([np.hypot(1, 2), 3.0]))
    assert chains[2]["touched"] == 0.5 and chains[0]["moved"] == 1.0 and chains[1]["moved"] == 0.0


def test_skill_summary_splits_by_the_simulators_verdict():
    true = [[0.2, 0.0, 0.0], [0.0, 0.0, 0.0], [0.2, 0.0, 0.0]]
    pred = [[0.18, 0.0, 0.0], [0.01, 0.0, 0.0], [0.05, 0.0, 0.0]]  # the third judged a failure
    score = {"mean": pred, "sd": [[0.01] * 3] * 3, "nlpd": [1.0, 2.0, 3.0], "coverage": [1, 1, 1]}
    rec = {
        "part": "pick",
        "n_train": 5,
        "test_rows": [0, 1, 2],
        "true": true,
        "success": [True, False, True],
        **{m: score for m in ("forward", "backward", "mixture")},
    }
    rows = {(r["model"], r["case"]): r for r in summarise_skills([rec])}
    ok, failed = rows["forward", "succeeded"], rows["forward", "failed"]
    assert ok["n"] == 2 and failed["n"] == 1
    assert failed["predicted_cm"] == pytest.approx(1.0) and failed["true_cm"] == 0.0
    assert ok["error_cm"] == pytest.approx((2.0 + 15.0) / 2)
    assert rows["forward", "all"]["misjudged"] == 1 and rows["forward", "all"]["nlpd"] == 6.0
    assert ("forward", "slipped") not in rows  # no slip flags, no split
    rows = {(r["model"], r["case"]): r for r in summarise_skills([{**rec, "slipped": [0, 1, 0]}])}
    assert rows["forward", "slipped"]["n"] == 1 and ("forward", "not grasped") not in rows


def test_bad_config():
    with pytest.raises(InputError, match="trials must be a positive integer"):
        run(ModularStudyConfig(trials=0))
    with pytest.raises(InputError, match="scales must be finite numbers >= 1"):
        run(ModularStudyConfig(scales=(0.5,)))
    with pytest.raises(InputError, match="chain_lengths may hold 3, 4 and 5"):
        run(ModularStudyConfig(chain_lengths=(7,)))
    # TrialSettings checks itself when it is built, before any study sees it.
    with pytest.raises(InputError, match="push_groups: unknown feature groups"):
        TrialSettings(push_groups=("colour",))
    with pytest.raises(InputError, match="chain_samples must be an integer >= 2"):
        TrialSettings(chain_samples=1)
    with pytest.raises(InputError, match="settings must be a TrialSettings"):
        run(ModularStudyConfig(settings="fast"))  # type: ignore[arg-type]
