"""benchmarks/pusht_active.py without the environment: joined runs, their figure, bad flags."""

from pathlib import Path

import pytest

COLUMNS = "strategy,train_pushes,rmse_z,rmse_theta,nlpd,coverage90,success_rate,success_low,"
COLUMNS += "success_high,max_reward,max_coverage"


@pytest.fixture(scope="module")
def active(benchmark_script):
    with benchmark_script("pusht_active") as module:
        yield module


def _run(folder: Path, strategy: str, rates: list[float]) -> Path:
    folder.mkdir()
    rows = [
        f"{strategy},{n},5.0,0.1,6.0,0.9,{r},{r - 0.1},{min(r + 0.05, 1.0)},0.95,0.9"
        for n, r in zip((20, 40, 60), rates, strict=True)
    ]
    (folder / "results.csv").write_text("\n".join([COLUMNS, *rows]) + "\n")
    return folder


def test_merge_joins_runs_in_strategy_order_with_the_success_figure(active, tmp_path, capsys):
    a = _run(tmp_path / "random", "random", [0.6, 0.8, 0.9])
    b = _run(tmp_path / "reduction", "reduction", [0.7, 0.9, 0.95])
    out = tmp_path / "joined"
    assert active.main(["--merge", str(a), str(b), "--out", str(out)]) == 0
    lines = (out / "results.csv").read_text().splitlines()
    assert lines[0] == COLUMNS and len(lines) == 7
    assert [ln.split(",")[:2] for ln in lines[1:3]] == [["reduction", "20"], ["random", "20"]]
    assert (out / "success_vs_pushes.png").stat().st_size > 0
    assert "| reduction | 60 |" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("flags", "word"),
    [
        (["--strategies", "entropy"], "--strategies"),
        (["--strategies", ","], "--strategies"),
        (["--merge", "no_such_folder"], "--merge"),
        (["--sizes", "0"], "--sizes"),
    ],
)
def test_bad_flags_print_one_line_and_exit_2(active, tmp_path, refused_flags, flags, word):
    refused_flags(active.main, [*flags, "--out", str(tmp_path / "out")], word)
