"""The Push-T worker: the unmodified gym-pusht environment behind JSON lines on stdin/stdout.

This file runs in the Push-T environment's own Python (``probaff pusht-env`` creates it), not in
probaff's: it imports only the standard library, numpy, gymnasium and gym_pusht, never probaff.
`probaff.experiments.pusht.env.PushTWorker` starts it as a subprocess and speaks to it one JSON
object per line. Every request is ``{"cmd": NAME, ...}``; every answer is ``{"ok": true, ...}`` or
``{"ok": false, "error": TEXT}``.

Commands:
    hello: the versions of gym_pusht, gymnasium, pymunk and numpy.
    reset(seed, obs_type): reset the episode's environment (``gym.make("gym_pusht/PushT-v0")``,
        its own 300-step limit) with `seed`; its state. `obs_type` is the environment's own
        observation type: ``"state"`` (the default) or ``"pixels_agent_pos"``, the diffusion
        policy's (a 96 x 96 RGB image and the agent's position). With the latter, the answers
        of reset and step also hold ``pixels`` (the image's bytes, row-major uint8 of shape
        ``pixels_shape``, ``[96, 96, 3]``, in base64) and ``agent_pos``, exactly as the
        environment returned them (a step's: one per step taken), beside the state (``obs``,
        the state observation's five numbers), which is kept for scoring.
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

import base64
import json
import sys
import traceback
from importlib import metadata

import gym_pusht  # noqa: F401  (registers gym_pusht/PushT-v0)
import gymnasium as gym
import numpy as np
from gym_pusht.envs.pusht import pymunk_to_shapely

ENV_ID = "gym_pusht/PushT-v0"
OBS_TYPES = ("state", "pixels_agent_pos")


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


def _state_obs(env) -> list[float]:
    """The state observation (``obs_type="state"``): agent x, y, block x, y, angle mod 2 pi."""
    u = env.unwrapped
    angle = float(u.block.angle) % (2 * np.pi)
    return [*(float(v) for v in u.agent.position), *(float(v) for v in u.block.position), angle]


def _observation(env, obs, obs_type: str) -> dict:
    """One step's observation as JSON: the state, and the image and agent position if asked.

    With ``obs_type="state"`` the environment's own observation is the state; otherwise the
    state is read off the environment (`_state_obs`) beside the image it returned.
    """
    if obs_type == "state":
        return {"obs": [float(v) for v in obs]}
    pixels = np.ascontiguousarray(obs["pixels"], dtype=np.uint8)
    return {
        "obs": _state_obs(env),
        "pixels": base64.b64encode(pixels.tobytes()).decode("ascii"),
        "pixels_shape": list(pixels.shape),
        "agent_pos": [float(v) for v in obs["agent_pos"]],
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
        self.obs_type = "state"
        self.env = gym.make(ENV_ID, obs_type=self.obs_type)
        self.model = gym.make(ENV_ID, obs_type="state")
        self.model.reset(seed=0)
        self.steps = 0

    def hello(self, msg: dict) -> dict:
        return {"versions": _versions(), "max_episode_steps": self.env.spec.max_episode_steps}

    def reset(self, msg: dict) -> dict:
        obs_type = str(msg.get("obs_type", "state"))
        if obs_type not in OBS_TYPES:
            raise ValueError(f"obs_type {obs_type!r} is not one of {list(OBS_TYPES)}")
        if obs_type != self.obs_type:  # the same environment, observed otherwise
            self.env.close()
            self.env = gym.make(ENV_ID, obs_type=obs_type)
            self.obs_type = obs_type
        obs, info = self.env.reset(seed=int(msg["seed"]))
        self.steps = 0
        u = self.env.unwrapped
        return {
            **_observation(self.env, obs, obs_type),
            "coverage": _coverage(u),
            "goal": [float(v) for v in info["goal_pose"]],
            **_full_state(self.env),
        }

    def step(self, msg: dict) -> dict:
        coverage, terminated, truncated = [], False, False
        seen: dict[str, list] = {"obs": []}
        u = self.env.unwrapped
        for action in msg["actions"]:
            obs, _, terminated, truncated, _ = self.env.step(np.asarray(action, dtype=np.float64))
            self.steps += 1
            for key, value in _observation(self.env, obs, self.obs_type).items():
                seen.setdefault(key, []).append(value)
            coverage.append(_coverage(u))
            if terminated or truncated:
                break
        if "pixels_shape" in seen:  # one shape for every image
            seen["pixels_shape"] = seen["pixels_shape"][0]
        return {
            **seen,
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
