"""A bad flag to a study script or to `probaff generate` prints one line and exits 2.

The study scripts (inference/affordance_map.py, inference/push_models.py,
inference/planning.py, inference/point_cloud_labels.py, inference/modular.py) run in this
process through `runpy`, with the studies' first heavy step replaced by a tripwire: every case
must be refused before any work starts, with and without ``--smoke`` (whose sizes never
replace or hide a value the user typed). One case runs in a real subprocess.
"""

import re
import runpy
import subprocess
import sys
from pathlib import Path

import pytest

from probaff._cli_errors import check_output_flags, report_error, run_cli
from probaff.cli import main as probaff_main
from probaff.errors import DatasetError, InputError

ROOT = Path(__file__).resolve().parents[1]
AFFORDANCE = ROOT / "inference" / "affordance_map.py"
PUSH_MODELS = ROOT / "inference" / "push_models.py"
PLANNING = ROOT / "inference" / "planning.py"
POINT_CLOUD = ROOT / "inference" / "point_cloud_labels.py"
MODULAR = ROOT / "inference" / "modular.py"
FILE = "<a regular file>"  # replaced by a file in tmp_path

CASES = [
    (AFFORDANCE, ["--seed", "-1"], "seed must be an integer >= 0, got -1"),
    (AFFORDANCE, ["--workers", "-2"], "workers must be None or an integer >= 0, got -2"),
    (AFFORDANCE, ["--out", f"{FILE}/x"], "--out .* lies under .*, which is a file"),
    (AFFORDANCE, ["--alpha", "5"], r"alpha must lie in \[0, 1\]"),
    (AFFORDANCE, ["--sensor-noise", "-1"], "sensor_noise must be a number >= 0"),
    (AFFORDANCE, ["--n-maps", "0"], "n_maps must be a positive integer, got 0"),
    (AFFORDANCE, ["--sensor", "lidar"], "sensor must be one of camera, scanner, got 'lidar'"),
    (AFFORDANCE, ["--sensor-noise", "0.2"], "sensor_noise sets the idealised scanner's range"),
    (AFFORDANCE, ["--symmetry-coupling", "nan"], r"symmetry_coupling must be a finite number"),
    (AFFORDANCE, ["--symmetry-coupling", "inf"], r"symmetry_coupling must be a finite number"),
    (POINT_CLOUD, ["--n-scenes", "0"], "n_scenes must be an integer >= 2, got 0"),
    (POINT_CLOUD, ["--min-gains", "-1"], "min_gains must be finite numbers >= 0"),
    (POINT_CLOUD, ["--merge-proximities", "foo"], "merge_proximities must hold distinct names"),
    (PUSH_MODELS, ["--seed", "-1"], "seed must be an integer >= 0, got -1"),
    (PUSH_MODELS, ["--workers", "-2"], "workers must be None or an integer >= 0, got -2"),
    (PUSH_MODELS, ["--methods", "foo"], "unknown method 'foo'"),
    (PUSH_MODELS, ["--gate", "bar"], "unknown gate 'bar'"),
    (PUSH_MODELS, ["--out", FILE], "--out .* is a file, not a folder"),
    (PLANNING, ["--trials", "0"], "trials must be a positive integer, got 0"),
    (PLANNING, ["--planners", "astar-lstm"], "planners: unknown or no planners"),
    (PLANNING, ["--train-pushes", "3"], "train_pushes must be at least 10"),
    (PLANNING, ["--workers", "-2"], "workers must be None or an integer >= 0, got -2"),
    (PLANNING, ["--out", FILE], "--out .* is a file, not a folder"),
    (PLANNING, ["--tool-planners", "teleport"], "tool_planners"),
    (POINT_CLOUD, ["--n-splits", "1"], "n_splits must be an integer >= 2, got 1"),
    (MODULAR, ["--n-experts", "0"], "n_experts must be a positive integer, got 0"),
    (MODULAR, ["--em-max-iter", "0"], "em_max_iter must be a positive integer, got 0"),
    (MODULAR, ["--push-groups", "pose,pose"], r"push_groups names \['pose'\] more than once"),
    (MODULAR, ["--skill-groups", "pose,colour"], r"skill_groups: unknown feature groups"),
    (MODULAR, ["--trials", "0"], "trials must be a positive integer, got 0"),
    (MODULAR, ["--chain-lengths", "7"], "chain_lengths may hold 3, 4 and 5"),
    (MODULAR, ["--scheduler", "garbage"], "scheduler 'garbage' is not a Dask scheduler address"),
    (PUSH_MODELS, ["--em-init", "nan"], "em_init: unknown initialisation 'nan'"),
    (PUSH_MODELS, ["--scheduler", "foo://x:1"], "scheduler 'foo://x:1' is not a Dask scheduler"),
]
SMOKE_CASES = [
    pytest.param(script, [*args, "--smoke"], message, id=f"{script.stem}{''.join(args)}--smoke")
    for script, args, message in CASES
    if "--out" not in args
]


@pytest.fixture(scope="module")
def _studies():
    import importlib

    import probaff.experiments.base as base

    # The module, not the package's `run` function of the same name.
    return importlib.import_module("probaff.experiments.affordance_map.run"), base


@pytest.fixture
def tripwire(monkeypatch, _studies):
    """Fail the test if a study gets past its validation into real work."""
    am, base = _studies

    def work(*args, **kwargs):
        raise AssertionError("a bad flag passed validation and the study started")

    monkeypatch.setattr(am, "train_classifier", work)
    for name in ("run_tasks", "generate"):  # every study's first work
        monkeypatch.setattr(base, name, work)


def _run_script(monkeypatch, script, args):
    monkeypatch.setattr(sys, "argv", [str(script), *args])
    with pytest.raises(SystemExit) as info:
        runpy.run_path(str(script), run_name="__main__")
    return info.value.code


def _case_id(case):
    script, args = (case.values if hasattr(case, "values") else case)[:2]
    return script.stem + "".join(args)


@pytest.mark.parametrize(
    ("script", "args", "message"),
    CASES + SMOKE_CASES,
    ids=[_case_id(c) for c in CASES + SMOKE_CASES],
)
def test_bad_flag_prints_one_line_and_exits_2(
    monkeypatch, capsys, tmp_path, tripwire, script, args, message
):
    regular = tmp_path / "file"
    regular.write_text("not a folder")
    args = [a.replace(FILE, str(regular)) for a in args]
    if "--out" not in args:
        args += ["--out", str(tmp_path / "out")]
    code = _run_script(monkeypatch, script, args)
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert err.startswith(f"{script.name}: error: ")
    assert re.search(message, err), err


def test_argparse_errors_still_exit_2(monkeypatch, capsys, tripwire):
    assert _run_script(monkeypatch, PUSH_MODELS, ["--seed", "abc"]) == 2
    assert "argument --seed: invalid int value: 'abc'" in capsys.readouterr().err


def test_a_script_in_a_subprocess(tmp_path):
    proc = subprocess.run(
        [sys.executable, str(PUSH_MODELS), "--gate", "bar", "--out", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
    )
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr == (
        "push_models.py: error: unknown gate 'bar'; use 'linear' or 'fourier'.\n"
    )
    assert not (tmp_path / "out").exists()


def test_guard_helpers():
    def boom():
        raise InputError("two\nlines")

    assert run_cli(boom, prog="tool") == 2
    assert run_cli(lambda: None) == 0
    with pytest.raises(ZeroDivisionError):  # a bug keeps its traceback
        run_cli(lambda: 1 / 0)
    check_output_flags(["--out"], ["--out"])  # left to the script's own parser
    with pytest.raises(InputError, match="--out /etc/passwd/x lies under /etc/passwd"):
        check_output_flags(["--out"], ["--smoke", "--out=/etc/passwd/x"])
    assert report_error("tool", DatasetError("a\n b")) == 2


# 5. `probaff generate --out` under a regular file


@pytest.mark.parametrize("resume", [False, True])
def test_generate_out_under_a_file(capsys, tmp_path, resume):
    regular = tmp_path / "file"
    regular.write_text("x")
    argv = ["generate", "--scene", "single_free", "--n", "2", "--out", str(regular / "ds")]
    assert probaff_main(argv + (["--resume"] if resume else [])) == 2
    err = capsys.readouterr().err
    assert err == (
        f"probaff generate: error: --out {regular / 'ds'} lies under {regular}, which "
        "is a file, not a folder; choose an output path whose parents are folders "
        "(or do not exist yet).\n"
    )


def test_generate_out_is_a_file_with_resume(capsys, tmp_path):
    regular = tmp_path / "file"
    regular.write_text("x")
    argv = ["generate", "--scene", "single_free", "--n", "2", "--out", str(regular), "--resume"]
    assert probaff_main(argv) == 2
    assert capsys.readouterr().err == (
        f"probaff generate: error: --out {regular} is a file, "
        "not a folder; choose a folder path for the output.\n"
    )


@pytest.mark.parametrize("resume", [False, True])
def test_generate_api_out_under_a_file(tmp_path, resume):
    from probaff.data.generation import GenerateConfig, generate

    regular = tmp_path / "file"
    regular.write_text("x")
    with pytest.raises(InputError, match=r"^out .* lies under .*, which is a file"):
        generate(
            GenerateConfig("single_free", 2),
            regular / "ds",
            workers=0,
            resume=resume,
            progress=False,
        )
    with pytest.raises(InputError, match=r"^out .* is a file, not a folder"):
        generate(
            GenerateConfig("single_free", 2), regular, workers=0, resume=resume, progress=False
        )


def test_store_write_failure_is_a_dataset_error(tmp_path):
    from probaff.data.store import write_manifest

    regular = tmp_path / "file"
    regular.write_text("x")
    with pytest.raises(DatasetError, match=r"cannot write .*manifest\.json \(Not a directory\)"):
        write_manifest(regular / "ds", {})


# 6. `--scheduler` where no scheduler listens: one line naming the address and the way out


@pytest.fixture
def _quick_connect():
    import dask

    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        yield


def test_unreachable_scheduler_is_one_clear_error(_quick_connect):
    from probaff._dask import dask_client

    with (
        pytest.raises(
            InputError, match=r"no Dask scheduler could be reached at tcp://127\.0\.0\.1:9"
        ) as info,
        dask_client(None, "tcp://127.0.0.1:9"),
    ):
        pass
    assert "dask scheduler" in str(info.value) and "--workers K" in str(info.value)


def test_generate_with_an_unreachable_scheduler_exits_2(capsys, tmp_path, _quick_connect):
    argv = ["generate", "--scene", "single_free", "--n", "2", "--out", str(tmp_path / "ds")]
    assert probaff_main([*argv, "--scheduler", "tcp://127.0.0.1:9"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(
        "probaff generate: error: no Dask scheduler could be reached at tcp://127.0.0.1:9"
    )


@pytest.mark.parametrize(
    ("address", "message"),
    [
        ("", "scheduler must be a Dask scheduler address"),
        (8786, "scheduler must be a Dask scheduler address"),
        ("tcp://host", "is not a Dask scheduler address"),
        ("carrier-pigeon://loft:1", "unknown scheme 'carrier-pigeon'"),
    ],
)
def test_malformed_scheduler_addresses(address, message):
    from probaff._dask import check_scheduler

    with pytest.raises(InputError, match=message):
        check_scheduler(address)
    assert check_scheduler(None) is None
    assert check_scheduler("tcp://127.0.0.1:8786") == "tcp://127.0.0.1:8786"
