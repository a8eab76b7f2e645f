"""The Push-T worker: the unmodified gym-pusht environment behind JSON lines on stdin/stdout.

This file runs in the Push-T environment's own Python (``probaff pusht-env`` creates it), not in
probaff's: it imports only the standard library, numpy, gymnasium and gym_pusht, never probaff.
`probaff.experiments.pusht.env.PushTWorker` starts it as a subprocess and speaks to it one JSON
object per line. Every request is ``{"cmd": NAME, ...}``; every answer is ``{"ok": true, ...}`` or
``{"ok": false, "error": TEXT}``.

Commands:
    hello: the versions of gym_pusht, gymnasium, pymunk and numpy.
    reset(seed): reset the episode's environment (``gym.make("gym_pusht/PushT-v0")``, its own
        300-step limit) with `seed`; its state.
    step(actions, stop): step the episode's environment through the agent targets `actions`
        (a list of ``[x, y]``), stopping early when it terminates (coverage > 95 %) or is
        truncated; the observation, coverage and flags after every step taken.
    state: the full state (agent position and velocity, block pose, steps taken).
    rollout(state, sequences): copy `state` into a second environment instance and run each
        action sequence from it; for each, the final state and the maximum coverage.

The environment is never edited: states are set through gym-pusht's own
``reset(options={"reset_to_state": ...})`` (whose block position is corrected for the rotation
about the block's centre of gravity that it applies) and the agent's velocity attribute.
"""

from __future__ import annotations

import json
import sys
import traceback
from importlib import metadata

import gym_pusht  # noqa: F401  (registers gym_pusht/PushT-v0)
import gymnasium as gym
import numpy as np
from gym_pusht.envs.pusht import pymunk_to_shapely

ENV_ID = "gym_pusht/PushT-v0"


def _versions() -> dict:
    return {name: metadata.version(name) for name in ("gym-pusht", "gymnasium", "pymunk", "numpy")}


def _coverage(u) -> float:
    """The environment's coverage, computed as its ``_get_coverage`` does, shapes in a fixed order.

    gym-pusht builds the T's polygons from ``block.shapes``, a Python set of pymunk shapes that
    iterates in the order of their memory addresses, which changes from process to process.
    GEOS then sums the two bars' areas in another order and the coverage changes in the last
    bit (up to 1.1e-16), so two runs of one seeded episode would differ. Here the same
    polygons, by the environment's own `pymunk_to_shapely`, are taken in the order of their
    vertices: the value is one of those the environment reports, the same in every process.
    The environment's own rule (terminated when its coverage > 95 %) is left as it is.
    """
    shapes = sorted(u.block.shapes, key=lambda s: [tuple(v) for v in s.get_vertices()])
    goal = pymunk_to_shapely(u.get_goal_pose_body(u.goal_pose), shapes)
    block = pymunk_to_shapely(u.block, shapes)
    return float(goal.intersection(block).area / goal.area)


def _full_state(env) -> dict:
    u = env.unwrapped
    return {
        "agent": [float(v) for v in u.agent.position],
        "agent_vel": [float(v) for v in u.agent.velocity],
        "block": [float(u.block.position[0]), float(u.block.position[1]), float(u.block.angle)],
    }


def _set_full_state(env, state: dict) -> None:
    """Put `state` into `env` through its own reset option, undoing its rotation about the cog."""
    u = env.unwrapped
    x, y, angle = (float(v) for v in state["block"])
    u.reset(options={"reset_to_state": [0.0, 0.0, 0.0, 0.0, 0.0]})
    cog = np.array(u.block.center_of_gravity, dtype=float)
    c, s = np.cos(angle), np.sin(angle)
    rotated = np.array([c * cog[0] - s * cog[1], s * cog[0] + c * cog[1]])
    position = np.array([x, y]) - cog + rotated
    agent = [float(v) for v in state["agent"]]
    u.reset(options={"reset_to_state": [*agent, float(position[0]), float(position[1]), angle]})
    u.agent.velocity = tuple(float(v) for v in state.get("agent_vel", (0.0, 0.0)))


class Worker:
    """The episode's environment and the model's copy."""

    def __init__(self) -> None:
        self.env = gym.make(ENV_ID, obs_type="state")
        self.model = gym.make(ENV_ID, obs_type="state")
        self.model.reset(seed=0)
        self.steps = 0

    def hello(self, msg: dict) -> dict:
        return {"versions": _versions(), "max_episode_steps": self.env.spec.max_episode_steps}

    def reset(self, msg: dict) -> dict:
        obs, info = self.env.reset(seed=int(msg["seed"]))
        self.steps = 0
        u = self.env.unwrapped
        return {
            "obs": [float(v) for v in obs],
            "coverage": _coverage(u),
            "goal": [float(v) for v in info["goal_pose"]],
            **_full_state(self.env),
        }

    def step(self, msg: dict) -> dict:
        obs_list, coverage, terminated, truncated = [], [], False, False
        u = self.env.unwrapped
        for action in msg["actions"]:
            obs, _, terminated, truncated, _ = self.env.step(np.asarray(action, dtype=np.float64))
            self.steps += 1
            obs_list.append([float(v) for v in obs])
            coverage.append(_coverage(u))
            if terminated or truncated:
                break
        return {
            "obs": obs_list,
            "coverage": coverage,
            "terminated": bool(terminated),
            "truncated": bool(truncated),
            "steps": self.steps,
            **_full_state(self.env),
        }

    def state(self, msg: dict) -> dict:
        return {"steps": self.steps, **_full_state(self.env)}

    def rollout(self, msg: dict) -> dict:
        u = self.model.unwrapped
        results = []
        for actions in msg["sequences"]:
            _set_full_state(self.model, msg["state"])
            best = _coverage(u)
            for action in actions:
                _, _, terminated, _, _ = u.step(np.asarray(action, dtype=np.float64))
                best = max(best, _coverage(u))
                if terminated:
                    break
            results.append({"max_coverage": best, **_full_state(self.model)})
        return {"results": results}


def main() -> int:
    worker = Worker()
    for line in sys.stdin:
        if not line.strip():
            continue
        try:
            msg = json.loads(line)
            cmd = msg.get("cmd")
            if cmd == "close":
                print(json.dumps({"ok": True}), flush=True)
                return 0
            handler = getattr(worker, str(cmd), None)
            if cmd not in ("hello", "reset", "step", "state", "rollout") or handler is None:
                raise ValueError(f"unknown command {cmd!r}")
            answer = {"ok": True, **handler(msg)}
        except Exception as exc:  # reported to probaff, which raises a ProbaffError
            answer = {"ok": False, "error": f"{type(exc).__name__}: {exc}"}
            traceback.print_exc(file=sys.stderr)
        print(json.dumps(answer), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
