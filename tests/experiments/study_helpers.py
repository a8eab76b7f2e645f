"""Helpers of the study tests: smoke runs of the study scripts, resumption, saved figures, and
synthetic records of the affordance-map study, a Push-T worker that never shows the T and one
that hides the state."""

from __future__ import annotations

import base64
import contextlib
import io
import json
import runpy
import struct
import subprocess
import sys
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from types import ModuleType
from typing import Any, TypeVar
from unittest import mock

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
PNG = b"\x89PNG\r\n\x1a\n"

T = TypeVar("T")


def run_smoke(script: str, out: Path, *flags: str) -> list[str]:
    """Run ``inference/<script>.py --smoke FLAGS --out OUT`` in a subprocess.

    Args:
        script: The script's name, without ``.py``.
        out: The output folder.
        *flags: More flags of the script.

    Returns:
        The files the script reports on its standard output.
    """
    cmd = [sys.executable, str(ROOT / f"inference/{script}.py"), "--smoke", *flags]
    proc = subprocess.run([*cmd, "--out", str(out)], capture_output=True, text=True, check=True)
    files: list[str] = json.loads(proc.stdout)["files"]
    return files


def rerun_smoke(script: str, out: Path, *flags: str) -> list[str]:
    """Run ``inference/<script>.py --smoke FLAGS --out OUT`` again, in this process.

    For the second run of a resumption check: the script's own code path (``runpy``, as
    ``__main__``), without a new interpreter importing torch and the package again.

    Args:
        script: The script's name, without ``.py``.
        out: The output folder of an earlier run.
        *flags: More flags of the script.

    Returns:
        The files the script reports on its standard output.
    """
    path = str(ROOT / f"inference/{script}.py")
    stdout = io.StringIO()
    argv = [path, "--smoke", *flags, "--out", str(out)]
    with (
        mock.patch.object(sys, "argv", argv),
        contextlib.redirect_stdout(stdout),
        pytest.raises(SystemExit) as exited,
    ):
        runpy.run_path(path, run_name="__main__")
    assert exited.value.code == 0, stdout.getvalue()
    files: list[str] = json.loads(stdout.getvalue())["files"]
    return files


def assert_wrote(files: Sequence[str], out: Path, names: Iterable[str]) -> None:
    """Check that each of `names` under `out` is reported in `files` and is not empty."""
    for name in names:
        assert str(out / name) in files and (out / name).stat().st_size > 0


def assert_resumes(rerun: Callable[[], T], paths: Sequence[Path]) -> T:
    """Run `rerun` and check that it rewrote none of `paths`.

    Returns:
        What `rerun` returned.
    """
    stamp = [p.stat().st_mtime_ns for p in paths]
    result = rerun()
    assert [p.stat().st_mtime_ns for p in paths] == stamp
    return result


def record_saved_figures(monkeypatch: pytest.MonkeyPatch, module: ModuleType) -> list[Any]:
    """Record the figures `module` saves through its ``atomic_save_figure``.

    The files are still written.

    Returns:
        The list the saved figures are appended to, in order.
    """
    figures: list[Any] = []
    real = module.atomic_save_figure

    def save(fig: Any, path: Any, **kw: Any) -> None:
        figures.append(fig)
        real(fig, path, **kw)

    monkeypatch.setattr(module, "atomic_save_figure", save)
    return figures


def is_png(path: str | Path) -> bool:
    """Whether `path` holds a PNG image of more than 1000 bytes."""
    data = Path(path).read_bytes()
    return len(data) > 1000 and data.startswith(PNG)


def output_files(
    out: Path, measured: Iterable[str] = ("timings", "timings.csv")
) -> dict[str, bytes]:
    """Every file under `out` by its relative path, but those under the `measured` names.

    Args:
        out: A study's output folder.
        measured: Top-level names under `out` that hold measurements of a run (wall-clock
            times), which differ from run to run.

    Returns:
        Relative path -> the file's bytes.
    """
    skip = set(measured)
    return {
        str(p.relative_to(out)): p.read_bytes()
        for p in sorted(out.rglob("*"))
        if p.is_file() and p.relative_to(out).parts[0] not in skip
    }


def assert_same_outputs(out: Path, ref: Path) -> None:
    """Check that `out` holds exactly the files of `ref`, each identical byte for byte.

    The planning-time measurements (``timings.csv``, ``timings/``) are left out of the
    comparison; their files must still be there, one per task result.
    """
    mine, theirs = output_files(out), output_files(ref)
    assert sorted(mine) == sorted(theirs)
    differ = [name for name in theirs if mine[name] != theirs[name]]
    assert not differ, f"files of {out} that differ from {ref}: {differ}"
    timings = sorted(p.name for p in (ref / "timings" / "tasks").glob("*.json"))
    assert timings == sorted(p.name for p in (out / "timings" / "tasks").glob("*.json"))
    assert timings == sorted(p.name for p in (ref / "tasks").glob("*.json"))


def png_chunks(data: bytes) -> list[tuple[bytes, bytes]]:
    """The ``(type, body)`` chunks of a PNG file's bytes."""
    assert data.startswith(PNG)
    chunks, i = [], len(PNG)
    while i < len(data):
        (length,) = struct.unpack(">I", data[i : i + 4])
        chunks.append((data[i + 4 : i + 8], data[i + 8 : i + 8 + length]))
        i += 12 + length
    return chunks


def loop_steps(curve: Sequence[float]) -> list[dict[str, Any]]:
    """The step records of one affordance-map loop whose map entropy follows `curve`.

    Step 0 is the map before any push; every later step pushes a real box that does not move.
    """
    return [
        {
            "step": t,
            "entropy": h,
            "entropy_mrf": h,
            "accuracy": 0.8,
            "distance": float(t),
            "real_box": True if t else None,
            "moved": False if t else None,
            "observed": False if t else None,
        }
        for t, h in enumerate(curve)
    ]


def map_result(
    index: int,
    ig_curve: Sequence[float],
    ex_curve: Sequence[float],
    counts: dict[str, list[int]],
    boxes: list[list[int]],
    walls: list[list[int]],
) -> dict[str, Any]:
    """One test map's result of the affordance-map study, as its run records it.

    The information-gain loop follows `ig_curve` and stops for lack of gain; the exhaustive
    loop follows `ex_curve` and stops at its step budget.
    """
    curves = {"information_gain": ig_curve, "exhaustive": ex_curve}
    stop = {"information_gain": "no_gain", "exhaustive": "max_steps"}
    return {
        "index": index,
        "boxes": boxes,
        "walls": walls,
        "seconds": 1.0,
        "classifier": counts,
        "policies": {p: {"steps": loop_steps(c), "stop": stop[p]} for p, c in curves.items()},
    }


class BlankPushTWorker:
    """A Push-T worker whose camera shows an empty floor: no T is ever perceived.

    Attributes:
        resets: How many times it was reset.
        steps: Control steps taken since it was made.
    """

    def __init__(self) -> None:
        self.resets = 0
        self.steps = 0
        self.image = base64.b64encode(np.full((96, 96, 3), 255, np.uint8).tobytes()).decode()

    def ask(self, cmd: str, **fields: Any) -> dict[str, Any]:
        """Answer a reset or a step call as the worker process would."""
        state = {"agent": [100.0, 100.0], "agent_vel": [0.0, 0.0], "block": [256.0, 300.0, 0.0]}
        seen = {"pixels_shape": [96, 96, 3], "obs": [[100.0, 100.0, 256.0, 300.0, 0.0]]}
        if cmd == "reset":
            self.resets += 1
            return {**state, **seen, "pixels": self.image, "agent_pos": [100.0, 100.0],
                    "obs": seen["obs"][0], "coverage": 0.0, "goal": [0.0, 0.0, 0.0]}  # fmt: skip
        n = len(fields["actions"])
        self.steps += n
        return {**state, **seen, "pixels": [self.image] * n, "agent_pos": [[100.0, 100.0]] * n,
                "obs": seen["obs"] * n, "coverage": [0.0] * n, "terminated": False,
                "truncated": False, "steps": self.steps}  # fmt: skip


class PoisonedPushTWorker:
    """A Push-T worker whose answers carry no usable state, around a real one.

    The state's fields (`STATE`: the block's pose, the agent's state, the goal and the state
    observation) are NaN; the observation (``pixels``, ``agent_pos``) and the environment's
    own flags are kept, so that what a planner plans on must be perceived.
    """

    STATE = ("block", "agent", "agent_vel", "goal", "obs")

    def __init__(self, worker: Any) -> None:
        self.worker = worker

    def ask(self, cmd: str, **fields: Any) -> dict[str, Any]:
        """The wrapped worker's answer, its state fields replaced by NaN."""
        answer: dict[str, Any] = self.worker.ask(cmd, **fields)
        for key in self.STATE:
            if key in answer:
                answer[key] = np.full(np.shape(answer[key]), np.nan).tolist()
        return answer
