"""Dask drills: a study on a real ``dask scheduler`` with two ``dask worker`` processes.

Everything listens on 127.0.0.1 (free ports). The study is the Push-T smoke study, the smallest
and quickest of the study smoke runs (about 15 s serially; it needs the Push-T environment of
the `pusht_python` fixture):

* a worker process killed (SIGKILL) while it runs a study task: the study finishes, its files
  are identical byte for byte to an uninterrupted run's, and every task completes exactly once
  (the killed worker's task runs again on the other worker; nothing finished runs twice: each
  result is released once saved, and the drill kills a worker that holds no finished result).
  The one repeat a kill cannot rule out is allowed: a task that finished on the killed worker
  within a second of the signal (between the drill's look at the cluster and the kill), whose
  result died with the worker before the study fetched it;
* the scheduler killed once the first episode is saved (the pushes recorded, the models
  fitted): one line on stderr naming the scheduler and the way out, exit status 2; a rerun on
  a restarted cluster keeps every saved result and finishes with the same files.

Covers probaff._dask.run_batch on an existing scheduler, probaff.eval.tasks.run_tasks and
inference/pusht.py's ``--scheduler``.
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import time
from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from study_helpers import assert_same_outputs

from probaff.experiments.pusht.env import ENV_VAR

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]
STUDY = ROOT / "inference" / "pusht.py"
TASKS = {"record_chunk": 3, "episode_task": 5}  # the smoke study's tasks: 3 chunks, 5 episodes


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def _wait(done: Callable[[], bool], what: str, timeout: float = 120.0) -> None:
    deadline = time.monotonic() + timeout
    while not done():
        assert time.monotonic() < deadline, f"{what}: not within {timeout} s"
        time.sleep(0.05)


class Cluster:
    """A ``dask scheduler`` and two ``dask worker`` processes on 127.0.0.1.

    Args:
        folder: Working folder of the processes (their logs go there).
        env: Their environment.
    """

    def __init__(self, folder: Path, env: dict[str, str]) -> None:
        folder.mkdir(parents=True, exist_ok=True)
        self.folder, self.env = folder, env
        self.port = _free_port()
        self.address = f"tcp://127.0.0.1:{self.port}"
        self.scheduler = self._start("scheduler", "--port", str(self.port))
        self.workers: dict[str, subprocess.Popen[bytes]] = {}
        for i in range(2):
            port = _free_port()
            args = (self.address, "--nthreads", "1", "--no-nanny", "--worker-port", str(port))
            self.workers[f"tcp://127.0.0.1:{port}"] = self._start(f"worker{i}", *args)

    def _start(self, name: str, *args: str) -> subprocess.Popen[bytes]:
        kind = "scheduler" if name == "scheduler" else "worker"
        with (self.folder / f"{name}.log").open("wb") as log:
            cmd = [sys.executable, "-m", "dask", kind, *args]
            return subprocess.Popen(
                [*cmd, "--host", "127.0.0.1", "--no-dashboard"],
                cwd=self.folder,
                env=self.env,
                stdout=log,
                stderr=subprocess.STDOUT,
            )

    def client(self) -> Any:
        """A client of the scheduler, once both workers have joined it."""
        from distributed import Client

        client = Client(self.address, timeout=60)
        client.wait_for_workers(2, timeout=120)
        return client

    def close(self) -> None:
        """Kill every process this cluster started."""
        for proc in [*self.workers.values(), self.scheduler]:
            if proc.poll() is None:
                proc.kill()
            proc.wait()


@pytest.fixture
def env(pusht_python: str) -> dict[str, str]:
    """Environment of the study and the cluster: the Push-T Python, one thread each."""
    return {**os.environ, ENV_VAR: pusht_python, "OMP_NUM_THREADS": "1"}


@pytest.fixture
def clusters(tmp_path: Path, env: dict[str, str]) -> Iterator[Callable[[], Cluster]]:
    """Start clusters on demand (``clusters()``); every one started is killed afterwards."""
    started: list[Cluster] = []

    def start() -> Cluster:
        started.append(Cluster(tmp_path / f"cluster{len(started)}", env))
        return started[-1]

    yield start
    for cluster in started:
        cluster.close()


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory, pusht_python: str) -> Path:
    """An uninterrupted serial smoke run of the study: the files every drill must match."""
    out = tmp_path_factory.mktemp("reference") / "pusht"
    env = {**os.environ, ENV_VAR: pusht_python, "OMP_NUM_THREADS": "1"}
    cmd = [sys.executable, str(STUDY), "--smoke", "--out", str(out)]
    subprocess.run(cmd, capture_output=True, check=True, env=env)
    return out


def _study(out: Path, address: str, env: dict[str, str]) -> subprocess.Popen[str]:
    cmd = [sys.executable, str(STUDY), "--smoke", "--out", str(out), "--scheduler", address]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)


def _saved(out: Path) -> list[Path]:
    return sorted([*out.glob("chunks/*.json"), *out.glob("tasks/*.json")])


def test_a_killed_worker_loses_nothing_and_repeats_nothing(
    tmp_path: Path, env: dict[str, str], clusters: Callable[[], Cluster], reference: Path
) -> None:
    cluster = clusters()
    out = tmp_path / "pusht"
    with contextlib.closing(cluster.client()) as client:
        client.get_task_stream()  # the scheduler records every task that finishes from now
        study = _study(out, cluster.address, env)
        killed: list[str] = []
        kill_times: list[float] = []

        def kill_a_busy_worker() -> bool:
            assert study.poll() is None, study.communicate()
            if not _saved(out):
                return False
            study_keys = lambda keys: any(str(k).startswith(tuple(TASKS)) for k in keys)  # noqa: E731
            # A worker that still holds a finished result (fetched, not yet released) would
            # have to run it again: the drill kills a worker that holds none.
            holding = {worker for worker, keys in client.has_what().items() if study_keys(keys)}
            busy = {worker for worker, keys in client.processing().items() if study_keys(keys)}
            busy -= holding
            for address in sorted(busy & set(cluster.workers)):
                kill_times.append(time.time())
                cluster.workers[address].send_signal(signal.SIGKILL)
                killed.append(address)
                return True
            return False

        _wait(kill_a_busy_worker, "a worker running a study task once a result was saved")
        _, stderr = study.communicate(timeout=300)
        assert study.returncode == 0, stderr
        assert cluster.workers[killed[0]].wait(timeout=10) == -signal.SIGKILL
        stream = client.get_task_stream()
    runs = Counter(str(t["key"]) for t in stream)
    assert_same_outputs(out, reference)
    done = {name: [k for k in runs if k.startswith(f"{name}-")] for name in TASKS}
    assert {name: len(keys) for name, keys in done.items()} == TASKS
    twice = {k: n for k, n in runs.items() if k.startswith(tuple(TASKS)) and n != 1}
    raced = {  # finished on the killed worker within a second of the kill: lost with it
        str(t["key"])
        for t in stream
        if t["worker"] == killed[0]
        and any(abs(s["stop"] - kill_times[0]) < 1.0 for s in t["startstops"])
    }
    assert set(twice) <= raced and set(twice.values()) <= {2}, (
        f"study tasks that completed more than once: {twice} (lost with the killed worker "
        f"at the kill: {sorted(raced)})"
    )


def test_a_dead_scheduler_is_one_line_and_a_rerun_resumes(
    tmp_path: Path, env: dict[str, str], clusters: Callable[[], Cluster], reference: Path
) -> None:
    cluster = clusters()
    out = tmp_path / "pusht"
    with contextlib.closing(cluster.client()):
        study = _study(out, cluster.address, env)
        episodes = lambda: list(out.glob("tasks/*.json"))  # noqa: E731
        _wait(lambda: study.poll() is not None or bool(episodes()), "a saved episode", 180)
        assert study.poll() is None, study.communicate()
        cluster.scheduler.send_signal(signal.SIGKILL)
        _, stderr = study.communicate(timeout=120)
    assert study.returncode == 2, stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr  # no traceback, no Dask log
    assert lines[0].startswith(
        f"pusht.py: error: the Dask scheduler {cluster.address} went away during the batch"
    )
    assert "rerun the same command" in lines[0] and "--workers K" in lines[0]
    saved = {p: p.stat().st_mtime_ns for p in [*_saved(out), *out.glob("models/*.pt")]}
    assert len(list(out.glob("tasks/*.json"))) < sum(TASKS.values()) - TASKS["record_chunk"]
    assert not (out / "planners.csv").exists()

    cluster.close()
    again = clusters()
    with contextlib.closing(again.client()):
        rerun = _study(out, again.address, env)
        _, stderr = rerun.communicate(timeout=300)
    assert rerun.returncode == 0, stderr
    assert {p: p.stat().st_mtime_ns for p in saved} == saved  # kept, not computed again
    assert_same_outputs(out, reference)
