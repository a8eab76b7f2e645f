"""benchmarks/pusht_active.py without the environment: joined runs, their figure, bad flags."""

from pathlib import Path

import numpy as np
import pytest

COLUMNS = "strategy,train_pushes,seed,rmse_z,rmse_theta,nlpd,coverage90,success_rate,success_low,"
COLUMNS += "success_high,max_reward,max_coverage"


@pytest.fixture(scope="module")
def active(benchmark_script):
    with benchmark_script("pusht_active") as module:
        yield module


def _run(folder: Path, strategy: str, rates: list[float], seed: int = 0) -> Path:
    folder.mkdir()
    rows = [
        f"{strategy},{n},{seed},5.0,0.1,6.0,0.9,{r},{r - 0.1},{min(r + 0.05, 1.0)},0.95,0.9"
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
    assert not (out / "collections.csv").exists()  # one collection seed: nothing to pool


def test_runs_of_several_collection_seeds_are_pooled_and_paired(active, tmp_path):
    runs = [
        _run(tmp_path / "random0", "random", [0.2, 0.6, 0.9], seed=0),
        _run(tmp_path / "random1", "random", [0.4, 0.8, 0.7], seed=1),
        _run(tmp_path / "reduction0", "reduction", [0.3, 0.8, 0.95], seed=0),
        _run(tmp_path / "reduction1", "reduction", [0.4, 0.9, 0.85], seed=1),
    ]
    out = tmp_path / "joined"
    assert active.main(["--merge", *map(str, runs), "--out", str(out)]) == 0
    lines = (out / "collections.csv").read_text().splitlines()
    header = lines[0].split(",")
    rows = {
        tuple(r[:2]): dict(zip(header, r, strict=True)) for r in (ln.split(",") for ln in lines[1:])
    }
    assert len(rows) == 6
    red = rows["reduction", "60"]
    assert int(red["collections"]) == 2
    assert float(red["success_rate"]) == pytest.approx(0.9)
    # t interval over the two collections: t(0.975, 1) * sd / sqrt(2), clipped to [0, 1]
    hw = 12.7062047 * np.std([0.95, 0.85], ddof=1) / np.sqrt(2)
    assert float(red["success_low"]) == pytest.approx(max(0.9 - hw, 0.0))
    assert (float(red["success_min"]), float(red["success_max"])) == (0.85, 0.95)
    # paired on the seeds: +0.05 and +0.15 against random
    assert float(red["vs_random"]) == pytest.approx(0.1)
    assert float(red["vs_random_ci95"]) == pytest.approx(
        12.7062047 * np.std([0.05, 0.15], ddof=1) / np.sqrt(2)
    )
    assert np.isnan(float(rows["random", "60"]["vs_random"]))  # no difference with itself
    assert "Over collection seeds:" in (out / "summary.md").read_text()


def test_a_table_without_the_seed_column_is_refused(active, tmp_path, capsys):
    old = tmp_path / "old"
    old.mkdir()
    (old / "results.csv").write_text(COLUMNS.replace("seed,", "") + "\n")
    assert active.main(["--merge", str(old), "--out", str(tmp_path / "o")]) == 2
    assert "--merge" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("flags", "word"),
    [
        (["--strategies", "entropy"], "--strategies"),
        (["--strategies", ","], "--strategies"),
        (["--merge", "no_such_folder"], "--merge"),
        (["--sizes", "0"], "--sizes"),
        (["--collections", "0"], "--collections"),
        (["--risk", "-1"], "--risk"),
        (["--risk", "nan"], "--risk"),
        (["--search-candidates", "0"], "--search-candidates"),
        (["--search-beam", "-2"], "--search-beam"),
        (["--search-step-cost", "inf"], "--search-step-cost"),
    ],
)
def test_bad_flags_print_one_line_and_exit_2(active, tmp_path, refused_flags, flags, word):
    refused_flags(active.main, [*flags, "--out", str(tmp_path / "out")], word)
