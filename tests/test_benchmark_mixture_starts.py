"""Smoke test of benchmarks/mixture_starts.py: cells, resume, the summary's numbers, bad flags."""

import json
import math
from pathlib import Path

import pytest
from scipy import stats

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def starts(benchmark_script):
    benchmarks = str(Path(__file__).resolve().parents[1] / "benchmarks")
    with pytest.MonkeyPatch.context() as mp:
        mp.syspath_prepend(benchmarks)  # its sibling import, as when run as a script
        with benchmark_script("mixture_starts") as module:
            yield module


def test_smoke_run_writes_cells_tables_and_figure_and_resumes(starts, tmp_path, capsys):
    argv = ["--splits", "0", "--seeds", "0,1", "--n-init", "1,3", "--n", "60", "--test", "40"]
    argv += ["--max-iter", "1", "--out", str(tmp_path)]
    assert starts.main(argv) == 0
    cells = sorted(tmp_path.glob("split*_seed*_ninit*.json"))
    assert [p.name for p in cells] == [
        f"split0_seed{s}_ninit{k}.json" for s in (0, 1) for k in (1, 3)
    ]
    for p in cells:
        cell = json.loads(p.read_text())
        assert math.isfinite(cell["nlpd"]) and cell["rmse"] > 0 and cell["fit_cpu_s"] > 0
    for name in ("starts.md", "starts.csv", "starts.png"):
        assert (tmp_path / name).stat().st_size > 0
    first = capsys.readouterr().out
    assert sum(line.startswith("split 0 seed") for line in first.splitlines()) == 4
    assert "| 0 | 1 |" in first and "| 0 | 3 |" in first
    stamps = [p.stat().st_mtime_ns for p in cells]
    assert starts.main(argv) == 0  # every cell is stored: nothing is refitted
    assert "split 0 seed" not in capsys.readouterr().out
    assert [p.stat().st_mtime_ns for p in cells] == stamps


def test_summary_counts_found_seeds_and_gives_a_student_t_interval(starts):
    cells = [
        {"split": 1, "seed": s, "n_init": 20, "nlpd": v, "fit_cpu_s": 2.0}
        for s, v in enumerate([-0.6, -0.5, 0.1])
    ]
    (row,) = starts.summarise(cells, goal=-0.48)
    assert row["found"] == 2 and row["seeds"] == 3 and row["nlpd_worst"] == 0.1
    values = [-0.6, -0.5, 0.1]
    mean = sum(values) / 3
    sd = math.sqrt(sum((v - mean) ** 2 for v in values) / 2)
    assert row["nlpd_mean"] == pytest.approx(mean)
    assert row["nlpd_half_width"] == pytest.approx(stats.t.ppf(0.975, 2) * sd / math.sqrt(3))


@pytest.mark.parametrize(
    ("flags", "word"),
    [
        (["--n-init", "0"], "--n-init"),
        (["--seeds", "a"], "--seeds"),
        (["--n", "0"], "--n"),
        (["--n", "20000"], "20,190"),
        (["--goal", "nan"], "--goal"),
    ],
)
def test_bad_flags_print_one_line_and_exit_2(starts, tmp_path, refused_flags, flags, word):
    refused_flags(starts.main, [*flags, "--out", str(tmp_path)], word)
