"""benchmarks/mixture_cost.py: paired differences, one real cell per variant kind, bad flags."""

import math

import numpy as np
import pytest


@pytest.fixture(scope="module")
def cost(benchmark_script):
    with benchmark_script("mixture_cost") as module:
        yield module


def _cell(dataset, variant, fold, cpu, nlpd, srmse):
    return {
        "dataset": dataset,
        "variant": variant,
        "fold": fold,
        "cpu": cpu,
        "nlpd": nlpd,
        "srmse": srmse,
    }


def test_summary_pairs_folds_against_the_default(cost):
    cells = [
        _cell("a", "default", 0, 2.0, 1.0, 0.5),
        _cell("a", "default", 1, 4.0, 2.0, 0.7),
        _cell("a", "cheap", 1, 1.0, 2.5, 0.7),  # out of order: paired by fold, not position
        _cell("a", "cheap", 0, 2.0, 1.1, 0.6),
    ]
    rows = {r["variant"]: r for r in cost.summarise(cells)}
    assert rows["default"]["cpu_ratio"] == 1.0 and rows["default"]["d_nlpd"] == 0.0
    cheap = rows["cheap"]
    assert cheap["cpu"] == pytest.approx(1.5) and cheap["cpu_ratio"] == pytest.approx(0.5)
    assert cheap["d_nlpd"] == pytest.approx(0.3)  # mean of +0.1 and +0.5
    # Student t interval of two paired differences: t(0.975, 1) * sd / sqrt(2)
    assert cheap["d_nlpd_half"] == pytest.approx(12.706 * np.std([0.1, 0.5], ddof=1) / 2**0.5, 1e-3)
    assert cheap["d_srmse"] == pytest.approx(0.05)


@pytest.mark.slow
def test_run_writes_the_table_with_every_variant(cost, tmp_path, capsys):
    out = tmp_path / "cost"
    argv = ["--datasets", "motorcycle", "--folds", "2", "--variants", "gate_fixed,gp_iter_25"]
    assert cost.main([*argv, "--out", str(out)]) == 0
    text = (out / "mixture_cost.md").read_text()
    for variant in ("default", "gate_fixed", "gp_iter_25"):  # the default is always run
        assert f"| motorcycle | {variant} |" in text
    lines = (out / "mixture_cost.csv").read_text().splitlines()
    assert lines[0].startswith("dataset,variant,cpu,cpu_ratio,nlpd") and len(lines) == 4
    rows = [dict(zip(lines[0].split(","), line.split(","), strict=True)) for line in lines[1:]]
    assert all(math.isfinite(float(r["nlpd"])) and float(r["cpu"]) > 0 for r in rows)
    assert "motorcycle fold 1 gp_iter_25" in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv, match",
    [
        (["--datasets", "ch5"], "--datasets names \\['ch5'\\]"),
        (["--variants", "fast"], "--variants names \\['fast'\\]"),
        (["--datasets", ""], "--datasets names nothing"),
        (["--folds", "1"], "--folds must be an integer >= 2"),
    ],
)
def test_bad_flags_are_named(cost, argv, match):
    with pytest.raises(cost.InputError, match=match):
        cost.main(argv)
