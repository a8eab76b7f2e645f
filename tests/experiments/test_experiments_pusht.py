"""The Push-T study runs end to end in gym-pusht on its smoke sizes, and resumes.

It needs the Push-T environment: $PROBAFF_PUSHT_PYTHON, else ``.venv-pusht`` at the repository
root, which the session fixture `pusht_python` (conftest.py) creates (``python -m
probaff.experiments.pusht.env``, from the package index) when it is missing.

Covers probaff.experiments.pusht.run, probaff.experiments.pusht.data,
probaff.experiments.pusht._worker and inference/pusht.py. The smoke study repeats to the last
bit: a run, and a second run killed mid-way and rerun, write the same files byte for byte (the
planning-time measurements under ``timings`` aside; the Dask drills repeat it once more against
a serial run).
"""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from study_helpers import assert_same_outputs, png_chunks

from probaff.experiments import STUDIES
from probaff.experiments.pusht.data import chunk_rng, push_dataset, record_chunk
from probaff.experiments.pusht.env import ENV_VAR, PushTWorker
from probaff.experiments.pusht.geometry import PX, cog_pose
from probaff.experiments.pusht.models import push_effects, push_features
from probaff.experiments.pusht.primitives import PrimitiveSettings

ROOT = Path(__file__).resolve().parents[2]


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


def test_worker_coverage_is_the_environments_in_a_fixed_order(pusht_python):
    """The worker's coverage is what gym-pusht reports, for one fixed order of the T's shapes.

    gym-pusht orders the shapes by their memory addresses (a Python set), which differs from
    process to process and changes its coverage in the last bit.
    """
    script = """
import json, sys
sys.path.insert(0, sys.argv[1])
import numpy as np
from _worker import Worker, _coverage
from gym_pusht.envs.pusht import pymunk_to_shapely
w = Worker()
u = w.env.unwrapped
rows = []
for seed in range(4):
    w.reset({"seed": seed})
    for target in ([200.0, 200.0], [300.0, 250.0], [250.0, 320.0]):
        w.step({"actions": [target] * 12})
        shapes = list(u.block.shapes)
        orders = []
        for ordered in (shapes, shapes[::-1]):
            goal = pymunk_to_shapely(u.get_goal_pose_body(u.goal_pose), ordered)
            block = pymunk_to_shapely(u.block, ordered)
            orders.append(goal.intersection(block).area / goal.area)
        rows.append([_coverage(u), u._get_coverage(), *orders])
print(json.dumps(rows))
"""
    folder = str(ROOT / "probaff/experiments/pusht")
    cmd = [pusht_python, "-c", script, folder]
    runs = [json.loads(subprocess.run(cmd, capture_output=True, text=True, check=True).stdout)]
    runs.append(json.loads(subprocess.run(cmd, capture_output=True, text=True, check=True).stdout))
    assert [r[0] for r in runs[0]] == [r[0] for r in runs[1]]  # the same in every process
    for ours, env, forward, backward in runs[0] + runs[1]:
        assert env in (forward, backward)  # the environment's value: one of the two orders
        assert ours in (forward, backward) and abs(ours - env) <= 4e-16
    assert any(r[0] > 0 for r in runs[0])  # some episodes cover part of the goal


@pytest.mark.slow
def test_smoke_runs_resumes_and_repeats_bit_for_bit(tmp_path, pusht_python):
    """A run, and a second run killed mid-way and rerun, write the same files byte for byte."""
    out = tmp_path / "pusht"
    env = {**os.environ, ENV_VAR: pusht_python, "OMP_NUM_THREADS": "1"}
    script = str(ROOT / "inference/pusht.py")

    def command(folder: Path) -> list[str]:
        return [sys.executable, script, "--smoke", "--out", str(folder)]

    cmd = command(out)
    proc = subprocess.run(cmd, capture_output=True, text=True, check=True, env=env)
    files = json.loads(proc.stdout)["files"]
    names = ("models.csv", "planners.csv", "timings.csv", "summary.md", "episodes.png")
    for name in (*names, "models.png"):
        assert str(out / name) in files and (out / name).stat().st_size > 0
    text = (out / "summary.md").read_text()
    assert "63.8 %" in text and "| beam-moe | state | 2 |" in text
    assert "| random | state | 1 |" in text and "| pixels_agent_pos | 500 | 319 |" in text
    tasks = sorted((out / "tasks").glob("*.json"))
    assert len(tasks) == 2 + 3 * 1  # beam-moe's two episodes, one of each other planner
    records = {p.name: json.loads(p.read_text()) for p in tasks}
    assert all(0 <= r["max_coverage"] <= 1 and 0 < r["steps"] <= 300 for r in records.values())
    assert {r["seed"] for r in records.values()} == {0, 1}  # the same seeded episodes
    assert any(r["success"] for r in records.values() if r["planner"] == "beam-analytic")
    assert all("plan_seconds" not in r for r in records.values())  # kept apart: timings/
    timing = {p.name: json.loads(p.read_text()) for p in (out / "timings/tasks").iterdir()}
    assert timing.keys() == records.keys()
    assert all(t["plan_seconds"] > 0 for t in timing.values())
    assert "plan_seconds" in (out / "timings.csv").read_text().splitlines()[0]
    assert list((out / "data").iterdir())  # the recorded pushes as probaff datasets
    for png in ("episodes.png", "models.png"):  # nothing time-dependent in the metadata
        kinds = {kind for kind, _ in png_chunks((out / png).read_bytes())}
        assert b"tIME" not in kinds and kinds <= {b"IHDR", b"IDAT", b"IEND", b"tEXt", b"pHYs"}
        assert all(
            body.startswith(b"Software\0")
            for kind, body in png_chunks((out / png).read_bytes())
            if kind == b"tEXt"
        )

    # a second run, killed once its first episode is saved, then rerun: every file the same,
    # byte for byte, whether a process computed it before the kill or after
    killed = tmp_path / "killed"
    with subprocess.Popen(
        command(killed), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env
    ) as run:
        deadline = time.monotonic() + 300
        while run.poll() is None and not list((killed / "tasks").glob("*.json")):
            assert time.monotonic() < deadline, "no episode was saved in 300 s"
            time.sleep(0.05)
        run.send_signal(signal.SIGKILL)
    assert run.returncode == -signal.SIGKILL  # killed, not finished
    assert not (killed / "planners.csv").exists()
    assert len(list((killed / "tasks").glob("*.json"))) < len(tasks)
    subprocess.run(command(killed), capture_output=True, text=True, check=True, env=env)
    assert_same_outputs(killed, out)

    # resume: one episode lost; it is run again, the others are kept as they were
    lost = tasks[0]
    stamps = {p: p.stat().st_mtime_ns for p in tasks[1:]}
    before = lost.read_bytes()
    lost.unlink()
    subprocess.run(cmd, capture_output=True, text=True, check=True, env=env)
    assert lost.read_bytes() == before  # the same record, to the last bit
    assert all(p.stat().st_mtime_ns == t for p, t in stamps.items())
    assert_same_outputs(out, killed)
    assert "pusht" in STUDIES
