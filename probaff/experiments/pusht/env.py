"""The Push-T environment in its own Python: creating it, and the worker probaff talks to.

gym-pusht 0.1.8 pins ``pymunk<7`` while probaff uses pymunk 7, so the environment lives in a
virtual environment of its own, made by one command from the repository root::

    python -m probaff.experiments.pusht.env            # creates .venv-pusht
    python -m probaff.experiments.pusht.env --path DIR # elsewhere

(``python -m venv DIR`` and ``DIR/bin/pip install gym-pusht==0.1.8 numpy``). `PushTWorker`
starts that Python on the standalone worker script ``_worker.py`` of this folder (it imports
only gym_pusht, gymnasium and numpy) and speaks JSON lines with it. Which Python: the
config's ``python`` (``--python``), else the ``PROBAFF_PUSHT_PYTHON`` environment variable,
else ``.venv-pusht/bin/python`` under the working folder (`pusht_python`).
"""

from __future__ import annotations

import argparse
import base64
import binascii
import contextlib
import json
import os
import subprocess
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from probaff.errors import ProbaffError

__all__ = [
    "DEFAULT_VENV",
    "ENV_VAR",
    "GYM_PUSHT_VERSION",
    "PushTEnvError",
    "PushTWorker",
    "create_env",
    "pixel_observations",
    "pusht_python",
]

GYM_PUSHT_VERSION = "0.1.8"
"""The gym-pusht release the benchmark runs (its physics, start distribution and rule)."""
ENV_VAR = "PROBAFF_PUSHT_PYTHON"
"""Environment variable naming the Push-T environment's Python."""
DEFAULT_VENV = ".venv-pusht"
"""The Push-T virtual environment's folder, under the working folder, by default."""
_WORKER = Path(__file__).resolve().with_name("_worker.py")
_CREATE = f"python -m probaff.experiments.pusht.env (creates {DEFAULT_VENV})"


class PushTEnvError(ProbaffError, RuntimeError):
    """The Push-T environment is missing, of another version, or its worker died."""


def pusht_python(python: str | None = None) -> Path:
    """The Python of the Push-T environment.

    Args:
        python: Its path; None for ``PROBAFF_PUSHT_PYTHON``, else
            ``.venv-pusht/bin/python`` under the working folder.

    Returns:
        The interpreter's path.

    Raises:
        PushTEnvError: If it does not exist, with the command that creates it.
    """
    chosen = python or os.environ.get(ENV_VAR)
    path = Path(chosen) if chosen else Path.cwd() / DEFAULT_VENV / "bin" / "python"
    if not path.is_file():
        source = "python" if python else (f"${ENV_VAR}" if chosen else "default")
        raise PushTEnvError(
            f"the Push-T environment's Python {str(path)!r} ({source}) does not exist; create it "
            f"with `{_CREATE}` or set {ENV_VAR} to the Python of an environment with "
            f"gym-pusht=={GYM_PUSHT_VERSION}."
        )
    return path


class PushTWorker:
    """A gym-pusht worker process: the episode's environment and a copy for rollouts.

    Args:
        python: The Push-T environment's Python (see `pusht_python`).

    Raises:
        PushTEnvError: If the environment is missing, its gym-pusht is not
            `GYM_PUSHT_VERSION`, or the worker does not start.
    """

    def __init__(self, python: str | None = None) -> None:
        self._proc: subprocess.Popen[str] | None = None
        self.python = pusht_python(python)
        self.versions: dict[str, str] = {}
        self.start()

    def start(self) -> None:
        """(Re)start the worker process and check its gym-pusht version."""
        self.close()
        self._proc = subprocess.Popen(
            [str(self.python), str(_WORKER)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
            bufsize=1,
        )
        self.versions = dict(self.ask("hello")["versions"])
        found = self.versions.get("gym-pusht")
        if found != GYM_PUSHT_VERSION:
            self.close()
            raise PushTEnvError(
                f"the Push-T environment at {str(self.python)!r} has gym-pusht {found}, but the "
                f"benchmark runs gym-pusht=={GYM_PUSHT_VERSION}; recreate it with `{_CREATE}`."
            )

    @property
    def alive(self) -> bool:
        """Whether the worker process is running."""
        return self._proc is not None and self._proc.poll() is None

    def ask(self, cmd: str, **fields: Any) -> dict[str, Any]:
        """Send one command and return its answer.

        Raises:
            PushTEnvError: If the worker is dead or dies, or answers with an error.
        """
        proc = self._proc
        line = ""
        if proc is not None and proc.stdin is not None and proc.stdout is not None:
            try:
                proc.stdin.write(json.dumps({"cmd": cmd, **fields}) + "\n")
                proc.stdin.flush()
                line = proc.stdout.readline()
            except (BrokenPipeError, OSError):
                line = ""
        if not line:
            code = None
            if proc is not None:
                try:
                    code = proc.wait(timeout=2)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    code = proc.wait()
            raise PushTEnvError(
                f"the Push-T worker ({str(self.python)!r}) died (exit status {code}) during "
                f"{cmd!r}; if it does not start at all, recreate the environment with "
                f"`{_CREATE}`."
            )
        answer = json.loads(line)
        if not answer.get("ok"):
            raise PushTEnvError(f"the Push-T worker refused {cmd!r}: {answer.get('error')}")
        return dict(answer)

    def close(self) -> None:
        """Stop the worker process (if running)."""
        proc, self._proc = self._proc, None
        if proc is None:
            return
        if proc.poll() is None:
            try:
                if proc.stdin is not None:
                    proc.stdin.write('{"cmd": "close"}\n')
                    proc.stdin.flush()
                proc.wait(timeout=5)
            except (BrokenPipeError, OSError, subprocess.TimeoutExpired):
                proc.kill()
                proc.wait()
        for stream in (proc.stdin, proc.stdout):
            if stream is not None:
                with contextlib.suppress(OSError):  # a dead worker's pipe
                    stream.close()

    def __del__(self) -> None:
        if hasattr(self, "_proc"):
            self.close()


def pixel_observations(answer: Mapping[str, Any]) -> list[dict[str, np.ndarray]]:
    """The ``pixels_agent_pos`` observations in a worker's ``reset`` or ``step`` answer.

    Args:
        answer: The answer of ``reset`` (one observation) or ``step`` (one per step taken) of
            an episode reset with ``obs_type="pixels_agent_pos"``.

    Returns:
        One dict per observation, as the environment returned it: ``pixels``, the (H, W, 3)
        uint8 RGB image (96 x 96 by default; row i, column j), and ``agent_pos``, the (2,)
        agent position in world units. The state (``obs``) is not in it.

    Raises:
        PushTEnvError: If the answer holds no images (an episode observed as ``"state"``) or
            an image that does not decode to its shape.
    """
    if "pixels" not in answer or "agent_pos" not in answer:
        raise PushTEnvError(
            "the worker's answer holds no images: reset the episode with "
            "obs_type='pixels_agent_pos' to observe it as the diffusion policy does."
        )
    single = isinstance(answer["pixels"], str)
    images = [answer["pixels"]] if single else list(answer["pixels"])
    agents = [answer["agent_pos"]] if single else list(answer["agent_pos"])
    shape = tuple(int(v) for v in answer["pixels_shape"]) if images else ()
    out = []
    for text, agent in zip(images, agents, strict=True):
        try:
            raw = np.frombuffer(base64.b64decode(text, validate=True), dtype=np.uint8)
            pixels = raw.reshape(shape).copy()
        except (binascii.Error, ValueError) as exc:
            raise PushTEnvError(f"the worker sent an image that does not decode: {exc}") from exc
        out.append({"pixels": pixels, "agent_pos": np.asarray(agent, dtype=float)})
    return out


def create_env(
    path: str | os.PathLike[str] = DEFAULT_VENV, *, pip_args: Sequence[str] = ()
) -> Path:
    """Create the Push-T virtual environment: ``python -m venv`` and gym-pusht with pip.

    Args:
        path: The environment's folder.
        pip_args: Extra arguments for ``pip install`` (e.g. ``--find-links DIR``).

    Returns:
        The environment's Python.

    Raises:
        PushTEnvError: If ``venv`` or ``pip`` fails.
    """
    folder = Path(path)
    python = folder / "bin" / "python"
    steps = [
        [sys.executable, "-m", "venv", str(folder)],
        [str(python), "-m", "pip", "install", "--quiet", *pip_args,
         f"gym-pusht=={GYM_PUSHT_VERSION}", "numpy"],
    ]  # fmt: skip
    for cmd in steps:
        done = subprocess.run(cmd, capture_output=True, text=True, check=False)
        if done.returncode:
            raise PushTEnvError(
                f"creating the Push-T environment failed at `{' '.join(cmd)}`:\n"
                f"{done.stderr[-2000:]}"
            )
    return python


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m probaff.experiments.pusht.env [--path DIR] [--pip-arg ARG ...]``.

    An environment that already runs gym-pusht `GYM_PUSHT_VERSION` is kept as it is.
    """
    parser = argparse.ArgumentParser(description="Create the Push-T environment (gym-pusht).")
    parser.add_argument("--path", default=DEFAULT_VENV, help=f"folder (default {DEFAULT_VENV})")
    parser.add_argument("--pip-arg", action="append", default=[], help="extra pip argument")
    args = parser.parse_args(argv)
    python = Path(args.path) / "bin" / "python"
    try:
        try:
            worker = PushTWorker(str(python))
        except PushTEnvError:  # missing, broken or of another version: (re)install
            python = create_env(args.path, pip_args=args.pip_arg)
            worker = PushTWorker(str(python))
        print(json.dumps({"python": str(python), "versions": worker.versions}))
        worker.close()
    except ProbaffError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
