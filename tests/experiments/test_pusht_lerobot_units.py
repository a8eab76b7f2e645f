"""Push-T scored in LeRobot's units: the environment's own reward, success with its interval.

- `env_reward` against the reward gym-pusht 0.1.8 itself returns, step by step;
- `score` and `reference_row` against Wilson intervals and means written out by hand;
- the planners' table and summary: every row says what it observed, the published goal is a
  row in the same units, and the verdict compares reward with reward.

Covers probaff.experiments.pusht.scoring and probaff.experiments.pusht.report.
"""

import json
import math
import subprocess

import numpy as np
import pytest

from probaff.errors import InputError
from probaff.experiments.pusht import PushTStudyConfig
from probaff.experiments.pusht.report import curve_rows, planner_rows, summary_lines
from probaff.experiments.pusht.scoring import (
    DIFFUSION_POLICY,
    env_reward,
    reference_row,
    score,
)

Z95 = 1.959963984540054  # the standard normal's 97.5 % quantile


def _wilson(k, n, z=Z95):
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return centre - half, centre + half


def test_env_reward_is_gym_pushts_own_reward(pusht_python):
    script = """
import json
import gymnasium as gym
import gym_pusht  # noqa: F401
env = gym.make("gym_pusht/PushT-v0", obs_type="state")
rows = []
for seed in range(3):
    env.reset(seed=seed)
    for target in ([256.0, 300.0], [300.0, 300.0], [250.0, 200.0], [200.0, 260.0]):
        for _ in range(10):
            _, reward, *_, info = env.step(target)
            rows.append([float(reward), float(info["coverage"])])
print(json.dumps(rows))
"""
    proc = subprocess.run([pusht_python, "-c", script], capture_output=True, text=True, check=True)
    rows = np.array(json.loads(proc.stdout))
    assert rows[:, 1].max() > 0  # some steps cover part of the goal
    np.testing.assert_array_equal(env_reward(rows[:, 1]), rows[:, 0])


def test_reward_saturates_and_bad_coverage_is_refused():
    assert env_reward(0.95) == 1.0 and env_reward(1.0) == 1.0
    assert env_reward(0.475) == pytest.approx(0.5)
    for bad in (1.2, -0.1, float("nan"), "a lot"):
        with pytest.raises(InputError, match="coverage"):
            env_reward(bad)


def _records(planner, wins, coverage, observation=None):
    extra = {} if observation is None else {"observation": observation}
    return [
        {
            "planner": planner,
            "episode": i,
            "success": bool(w),
            "max_coverage": c,
            "pushes": 4,
            "steps": 90,
            "error_px": 1.0,
            **extra,
        }
        for i, (w, c) in enumerate(zip(wins, coverage, strict=True))
    ]


def test_score_is_wilson_and_the_mean_of_each_episodes_maximum_reward():
    rs = _records("beam-moe", [1, 1, 0, 1, 0], [0.97, 0.96, 0.60, 0.99, 0.9025])
    s = score(rs)
    assert (s["successes"], s["episodes"], s["observation"]) == (3, 5, "state")
    assert (s["success_low"], s["success_high"]) == pytest.approx(_wilson(3, 5), abs=1e-12)
    # rewards 1, 1, 0.6 / 0.95, 1, 0.95: the environment's, not the coverage
    assert s["max_reward"] == pytest.approx((3 + 0.6 / 0.95 + 0.95) / 5)
    assert s["max_coverage"] == pytest.approx(np.mean([0.97, 0.96, 0.60, 0.99, 0.9025]))
    assert score(_records("p", [1], [0.99], "pixels"))["observation"] == "pixels_agent_pos"
    with pytest.raises(InputError, match="at least one"):
        score([])


def test_the_published_goal_is_a_row_in_the_same_units():
    row = reference_row()
    assert row["observation"] == "pixels_agent_pos" and row["successes"] == 319
    assert (row["success_low"], row["success_high"]) == pytest.approx(_wilson(319, 500))
    assert row["max_reward"] == DIFFUSION_POLICY.avg_max_reward == 0.959
    assert math.isnan(row["max_coverage"])


def test_table_rows_and_verdict_compare_reward_with_reward(tmp_path):
    state = _records("beam-moe", [1] * 9 + [0], [0.99] * 9 + [0.80])
    pixels = _records("beam-moe", [1] * 8 + [0, 0], [0.99] * 8 + [0.90, 0.5], "pixels")
    rows = {r["planner"]: r for r in planner_rows(state)}
    assert rows["beam-moe"]["observation"] == "state"
    assert rows["beam-moe"]["max_reward"] == pytest.approx((9 + 0.80 / 0.95) / 10)
    curve = curve_rows([{**r, "train_pushes": 60} for r in pixels])
    assert curve[0]["observation"] == "pixels_agent_pos"
    assert curve[0]["max_reward"] == pytest.approx((8 + 0.90 / 0.95 + 0.5 / 0.95) / 10)
    config = PushTStudyConfig(out=str(tmp_path))
    text = "\n".join(summary_lines(config, [], planner_rows(state), curve, state, np.zeros(0)))
    assert "| beam-moe | state | 10 | 9 |" in text
    assert "| diffusion policy (LeRobot) | pixels_agent_pos | 500 | 319 |" in text
    # reward 0.984 > 0.959 (met) although the interval (59.6-98.2 %) is not above 63.8 %
    assert "mean maximum reward 0.984 (raw coverage 0.971)" in text
    assert "interval above 63.8 % (not met), mean maximum reward above 0.959 (met)" in text
