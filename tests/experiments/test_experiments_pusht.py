"""The Push-T study runs end to end in gym-pusht on its smoke sizes, and resumes.

It needs the Push-T environment: $PROBAFF_PUSHT_PYTHON, else ``.venv-pusht`` at the repository
root, which the session fixture creates (``python -m probaff.experiments.pusht.env``, from the
package index) when it is missing.

Covers probaff.experiments.pusht.run, probaff.experiments.pusht.data,
probaff.experiments.pusht._worker and inference/pusht.py.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from probaff.experiments import STUDIES
from probaff.experiments.pusht.data import chunk_rng, push_dataset, record_chunk
from probaff.experiments.pusht.env import DEFAULT_VENV, ENV_VAR, PushTWorker, create_env
from probaff.experiments.pusht.geometry import PX, cog_pose
from probaff.experiments.pusht.models import push_effects, push_features
from probaff.experiments.pusht.primitives import PrimitiveSettings

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def pusht_python():
    """The Push-T environment's Python, created at the repository root when missing."""
    given = os.environ.get(ENV_VAR)
    if given:
        return given
    python = ROOT / DEFAULT_VENV / "bin" / "python"
    if not python.is_file():
        create_env(ROOT / DEFAULT_VENV)
    return str(python)


def test_worker_copies_states_exactly(pusht_python):
    w = PushTWorker(pusht_python)
    try:
        assert w.versions["gym-pusht"] == "0.1.8" and w.versions["pymunk"].startswith("6.")
        start = w.ask("reset", seed=3)
        assert np.allclose(start["obs"][:2], start["agent"])  # the state observation
        moved = w.ask("step", actions=[[200.0, 200.0]] * 15)
        state = {k: moved[k] for k in ("agent", "agent_vel", "block")}
        more = [[300.0, 250.0]] * 10
        copy = w.ask("rollout", state=state, sequences=[more])["results"][0]
        real = w.ask("step", actions=more)
        assert np.allclose(copy["block"], real["block"]) and np.allclose(
            copy["agent"], real["agent"]
        )
        assert moved["steps"] == 15 and real["steps"] == 25
    finally:
        w.close()


def test_recorded_pushes_are_a_push_dataset(pusht_python):
    s = PrimitiveSettings()
    a = record_chunk("train", 0, 5, 6, settings=s, python=pusht_python)
    b = record_chunk("train", 0, 5, 6, settings=s, python=pusht_python)
    assert a == b  # deterministic per seed
    ds = push_dataset([a], seed=5)
    assert ds.arrays["state_before"].shape == (6, 1, 3) and "mass" not in ds.arrays
    assert np.allclose(ds.arrays["state_before"][:, 0, :2] / PX, np.array(a["before"])[:, :2])
    X, Y = push_features(ds), push_effects(ds)
    assert X.shape == (6, 5) and Y.shape == (6, 3)
    assert np.all(X[:, 4] > 0) and np.allclose(np.hypot(X[:, 2], X[:, 3]), 1)
    # most pushes move the block forwards along the push (dz_p > 0)
    assert np.mean(Y[:, 1] > 0) >= 0.5
    assert chunk_rng(5, "test", 0).integers(1000) != chunk_rng(5, "train", 0).integers(1000)
    assert cog_pose(np.array([0.0, 0.0, 0.0]))[1] == 45.0


@pytest.mark.slow
def test_smoke_runs_and_resumes(tmp_path, pusht_python):
    out = tmp_path / "pusht"
    env = {**os.environ, ENV_VAR: pusht_python, "OMP_NUM_THREADS": "1"}
    cmd = [sys.executable, str(ROOT / "inference/pusht.py"), "--smoke", "--out", str(out)]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=True, env=env)
    files = json.loads(proc.stdout)["files"]
    for name in ("models.csv", "planners.csv", "summary.md", "episodes.png", "models.png"):
        assert str(out / name) in files and (out / name).stat().st_size > 0
    text = (out / "summary.md").read_text()
    assert "63.8 %" in text and "| beam-moe | 2 |" in text and "| random | 1 |" in text
    tasks = sorted((out / "tasks").glob("*.json"))
    assert len(tasks) == 2 + 3 * 1  # beam-moe's two episodes, one of each other planner
    records = {p.name: json.loads(p.read_text()) for p in tasks}
    assert all(0 <= r["max_coverage"] <= 1 and 0 < r["steps"] <= 300 for r in records.values())
    assert {r["seed"] for r in records.values()} == {0, 1}  # the same seeded episodes
    assert any(r["success"] for r in records.values() if r["planner"] == "beam-analytic")
    assert list((out / "data").iterdir())  # the recorded pushes as probaff datasets
    # resume: one episode lost; it is run again, the others are kept as they were
    lost = tasks[0]
    stamps = {p: p.stat().st_mtime_ns for p in tasks[1:]}
    lost.unlink()
    subprocess.run(cmd, capture_output=True, text=True, check=True, env=env)
    again, before = json.loads(lost.read_text()), records[lost.name]
    assert again.keys() == before.keys()
    for key, value in before.items():
        if key == "plan_seconds":  # how long planning took: the only thing that differs
            continue
        if isinstance(value, float):  # coverage: shapely's areas may differ in the last bit
            assert again[key] == pytest.approx(value, rel=1e-9), key
        else:
            assert again[key] == value, key
    assert all(p.stat().st_mtime_ns == t for p, t in stamps.items())
    assert "pusht" in STUDIES
