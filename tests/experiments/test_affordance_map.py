"""The affordance-map study runs end to end on a shrunken configuration and resumes.

Covers probaff.experiments.affordance_map.config, probaff.experiments.affordance_map.demo,
probaff.experiments.affordance_map.figures, probaff.experiments.affordance_map.report,
probaff.experiments.affordance_map.run.
"""

import dataclasses
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from probaff.errors import InputError
from probaff.experiments.affordance_map import AffordanceMapConfig, run, world
from probaff.experiments.affordance_map.demo import demo

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]
FILES = (
    "entropy.csv",
    "summary.md",
    "fig_3_7.csv",
    "fig_3_7.png",
    "entropy_vs_step.png",
    "accuracy_vs_step.png",
    "distance_vs_step.png",
    "mrf_smoothing.png",
    "loop_steps.png",
)


def test_run_writes_everything_and_resumes(tmp_path):
    # The idealised scanner keeps this test of the bookkeeping quick; the script's smoke run
    # below uses the world file's camera.
    cfg = AffordanceMapConfig(
        n_maps=2,
        train_maps=2,
        max_steps=3,
        workers=0,
        out=str(tmp_path / "am"),
        progress=False,
        sensor="scanner",
    )
    first = run(cfg)
    assert first["computed"] == 2
    for name in FILES:
        assert (tmp_path / "am" / name).stat().st_size > 0
    rows = (tmp_path / "am" / "entropy.csv").read_text().splitlines()
    assert rows[0].startswith("policy,step,entropy_mean") and len(rows) == 1 + 2 * 4
    text = (tmp_path / "am" / "summary.md").read_text()
    assert "| information gain |" in text and "| exhaustive |" in text and "| up |" in text
    assert "information gain minus exhaustive, paired by map" in text
    assert "idealised scanner" in text
    assert "J_sym = 0.4 (the up/down and left/right symmetry pairs)" in text
    assert "## Fig. 3.7: map entropy by manipulation step" in text and "tail flat" in text
    fig_rows = (tmp_path / "am" / "fig_3_7.csv").read_text().splitlines()
    assert len(fig_rows) == 1 + 3 and fig_rows[1].startswith("1,")  # steps 1-3
    tasks = sorted((tmp_path / "am" / "tasks").glob("map-*.json"))
    assert len(tasks) == 2
    saved = json.loads(tasks[0].read_text())
    for policy in ("information_gain", "exhaustive"):
        steps = saved["policies"][policy]["steps"]
        assert 1 <= len(steps) <= 4 and steps[0]["step"] == 0
    stamp = [p.stat().st_mtime_ns for p in tasks]
    second = run(cfg)
    assert second["computed"] == 0
    assert [p.stat().st_mtime_ns for p in tasks] == stamp
    assert second["summary"]["policies"] == first["summary"]["policies"]
    # Other settings get their own tasks instead of reusing these.
    assert AffordanceMapConfig(alpha=0.5).fingerprint() != cfg.fingerprint()


def test_bad_config(tmp_path):
    with pytest.raises(InputError, match="alpha"):
        run(AffordanceMapConfig(alpha=1.5, out=str(tmp_path)))
    with pytest.raises(InputError, match="n_maps"):
        run(AffordanceMapConfig(n_maps=0, out=str(tmp_path)))
    with pytest.raises(InputError, match="coupling"):
        run(AffordanceMapConfig(coupling=50.0, out=str(tmp_path)))
    with pytest.raises(InputError, match="symmetry_coupling must be a finite number"):
        run(AffordanceMapConfig(symmetry_coupling=math.nan, out=str(tmp_path / "nan")))
    assert not (tmp_path / "nan").exists()  # refused before any work


def test_demo(tmp_path, capsys):
    out = demo(tmp_path, seed=0, steps=2)
    assert len(out["entropy"]) == len(out["accuracy"]) == len(out["pushes"]) + 1 == 3
    assert out["entropy"][0] > 0.5  # a classifier trained on two maps is unsure of some boxes
    assert out["entropy"][2] < out["entropy"][0]  # the pushes resolve some of it
    assert len(out["moved"]) == 2 and Path(out["figure"]).stat().st_size > 0
    assert "map entropy by step" in capsys.readouterr().out


def test_sensor_choice_is_checked(tmp_path):
    with pytest.raises(InputError, match="sensor must be one of camera, scanner"):
        AffordanceMapConfig(sensor="lidar", out=str(tmp_path)).validate()
    with pytest.raises(InputError, match="scanner's range noise"):
        AffordanceMapConfig(sensor_noise=0.2, out=str(tmp_path)).validate()
    config = AffordanceMapConfig(sensor_noise=0.2, sensor="scanner", out=str(tmp_path))
    assert config.validate().fingerprint() != AffordanceMapConfig(sensor="scanner").fingerprint()
    assert world(0.2, "scanner").sensor_noise == 0.2 and world().sensor_kind == "camera"


def test_script_smoke(tmp_path):
    out = tmp_path / "am"
    script = str(ROOT / "inference/affordance_map.py")
    # the idealised scanner keeps the smoke run quick; test_demo runs the camera end to end
    cmd = [sys.executable, script, "--smoke", "--sensor", "scanner", "--out", str(out)]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=True)
    files = json.loads(proc.stdout)["files"]
    for name in FILES:
        assert str(out / name) in files.values() and (out / name).stat().st_size > 0


def test_steps_to_the_entropy_target():
    from probaff.experiments.affordance_map.report import steps_to as _steps_to

    assert _steps_to(np.array([4.0, 3.0, 2.0, 1.0]), 0.5) == 2.0
    assert math.isnan(_steps_to(np.array([4.0, 3.5, 3.0]), 0.5))
    assert math.isnan(_steps_to(np.array([0.0, 0.0]), 0.5))  # nothing to reduce
    with pytest.raises(InputError, match="entropy_target"):
        AffordanceMapConfig(entropy_target=1.5).validate()
    base = AffordanceMapConfig(sensor="scanner")
    assert dataclasses.replace(base, entropy_target=0.25).fingerprint() == base.fingerprint()
