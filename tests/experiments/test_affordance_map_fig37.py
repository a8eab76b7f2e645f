"""Fig. 3.7 of the affordance-map study as the thesis plots it, and the study's MRF.

Covers probaff.experiments.affordance_map.report (`fig_3_7`: the mean map entropy by step with
intervals, the stop steps, the verdict judged only where both loops push; the labelled flat
tails of the areas), probaff.experiments.affordance_map.figures (`plot_fig_3_7`) and
probaff.experiments.affordance_map.config (the thesis's symmetry pairs on by default, a
coupling that is not a finite number refused).
"""

import math
import re

import numpy as np
import pytest
from study_helpers import map_result

from probaff.errors import InputError
from probaff.experiments.affordance_map import SMOKE, AffordanceMapConfig, world
from probaff.experiments.affordance_map.figures import plot_fig_3_7
from probaff.experiments.affordance_map.report import fig_3_7_csv, markdown, summarise
from probaff.experiments.config_cli import parse_study_args
from probaff.maps.options import DEFAULT_COUPLING, THESIS_SYMMETRY_COUPLING, MRFParams

COUNTS = {"tp": [8, 8, 6, 6], "fp": [2, 2, 2, 2], "fn": [2, 2, 2, 2], "tn": [4, 4, 4, 4]}
CONFIG = AffordanceMapConfig(max_steps=4, sensor="scanner")


def _result(index, ig_curve, ex_curve):
    return map_result(index, ig_curve, ex_curve, COUNTS, [[0, 0], [0, 1]], [])


def _early_stop_maps():
    """Information gain falls faster for 2 pushes and stops; exhaustive pushes 4 times and
    ends lower, so the areas with their flat tails favour exhaustive."""
    return [
        _result(i, [20.0, 15.0, 12.0 - 0.1 * i], [20.0, 18.0, 16.0, 6.0, 2.0 + 0.1 * i])
        for i in range(4)
    ]


def test_the_verdict_is_judged_where_both_loops_push_not_on_the_flat_tail():
    summary, _, _ = summarise(CONFIG, _early_stop_maps(), None)
    auc = summary["auc_difference"]
    # Trapezoid areas to step 4: 55 - 0.25 i against 51 + 0.05 i.
    np.testing.assert_allclose(auc["per_map"], [4.0, 3.7, 3.4, 3.1])
    assert auc["mean"] - auc["ci"] > 0  # the areas alone would call information gain slower
    fig = summary["fig_3_7"]
    assert fig["steps"] == [1, 2, 3, 4] and fig["metric"] == "entropy_mrf"
    ig, ex = fig["policies"]["information_gain"], fig["policies"]["exhaustive"]
    assert ig["stops"] == {"per_map": [2, 2, 2, 2], "median": 2.0, "min": 2, "max": 2}
    assert ex["stops"]["per_map"] == [4, 4, 4, 4] and ex["stops"]["median"] == 4.0
    assert ig["pushing"] == [4, 4, 0, 0] and ex["pushing"] == [4, 4, 4, 4]
    # Means over all maps, a stopped loop carried flat: 12 - 0.1 i averages 11.85.
    assert ig["mean"][:3] == pytest.approx([15.0, 11.85, 11.85])
    assert ig["ci"][0] == pytest.approx(0.0) and ig["ci"][2] > 0
    paired = fig["paired"]
    assert paired["pairs"] == [4, 4, 0, 0]
    assert paired["mean"][:2] == pytest.approx([-3.0, -4.15]) and paired["mean"][2:] == [None] * 2
    np.testing.assert_allclose(fig["window"]["per_map"], [-3.5, -3.55, -3.6, -3.65])
    assert fig["window"]["maps"] == 4 and fig["window"]["steps_below"] == [1, 2]
    assert fig["window"]["steps_above"] == []
    assert fig["verdict"] == "faster" and summary["fig_3_7_holds"] is True
    ig_summary = summary["policies"]["information_gain"]
    assert ig_summary["flat_steps_per_map"] == 2.0
    assert summary["policies"]["exhaustive"]["flat_steps_per_map"] == 0.0


def test_the_summary_shows_fig_3_7_and_labels_the_flat_tails():
    summary, _, _ = summarise(CONFIG, _early_stop_maps(), None)
    text = markdown(CONFIG, world(sensor="scanner"), summary, CONFIG.max_steps)
    assert "## Fig. 3.7: map entropy by manipulation step" in text
    assert (
        "Stop step (pushes made) of the information-gain loop: median 2.0, range 2-2 "
        "(per map: 2, 2, 2, 2)." in text
    )
    assert "| 1 | 15.00 ± 0.00 | 4 | 18.00 ± 0.00 | 4 | -3.00 ± 0.00 | 4 |" in text
    assert "| 4 | 11.85 ± 0.21 | 0 | 2.15 ± 0.21 | 4 | n/a | 0 |" in text
    assert re.search(r"minus exhaustive, -3\.5[78] ± 0\.10 nats over 4 maps", text)  # -3.575
    assert "below zero: 1, 2; above zero: none" in text
    assert "Fig. 3.7's finding holds" in text
    # The areas are labelled as carrying the tail flat, not offered as a rate.
    assert "AUC H (MRF) to step 4, tail flat" in text and "not a rate of fall" in text
    assert "carries its last entropy flat for 2.0 of these steps per map" in text
    assert "brings the map entropy down faster" not in text
    assert "J_sym = 0.4 (the up/down and left/right symmetry pairs)" in text
    rows = fig_3_7_csv(summary["fig_3_7"]).splitlines()
    assert rows[0].startswith("step,information_gain_mean,information_gain_ci,")
    assert rows[0].endswith(",paired_mean,paired_ci,pairs") and len(rows) == 5
    assert rows[1].startswith("1,15.000000,0.000000,4,18.000000,0.000000,4,-3.000000,")
    assert rows[3].endswith(",4,,,0")  # step 3: no map where both loops push


@pytest.mark.parametrize(
    ("ig_curves", "verdict", "text"),
    [
        # information gain falls less while both push, then stops
        ([[20.0, 19.0 - 0.1 * i, 18.0] for i in range(4)], "slower", "is refuted here"),
        # one map each way: the interval holds zero
        (
            [[20.0, 10.0, 8.0, 8.0, 8.0] if i % 2 else [20.0, 19.5, 19.0] for i in range(4)],
            "unresolved",
            "is not resolved",
        ),
    ],
)
def test_slower_and_unresolved_verdicts(ig_curves, verdict, text):
    results = [_result(i, c, [20.0, 17.0, 15.0, 14.0, 13.0]) for i, c in enumerate(ig_curves)]
    summary, _, _ = summarise(CONFIG, results, None)
    assert summary["fig_3_7"]["verdict"] == verdict and summary["fig_3_7_holds"] is False
    assert text in markdown(CONFIG, world(sensor="scanner"), summary, CONFIG.max_steps)


def test_a_map_without_a_push_drops_out_of_the_verdict():
    results = [*_early_stop_maps()[:3], _result(3, [20.0], [20.0, 18.0, 16.0, 6.0, 2.0])]
    fig = summarise(CONFIG, results, None)[0]["fig_3_7"]
    assert fig["window"]["per_map"][3] is None and fig["window"]["maps"] == 3
    assert fig["policies"]["information_gain"]["stops"]["per_map"] == [2, 2, 2, 0]
    assert fig["paired"]["pairs"][:2] == [3, 3] and fig["verdict"] == "faster"
    one = summarise(CONFIG, results[:1], None)[0]
    assert one["fig_3_7"]["verdict"] is None and one["fig_3_7_holds"] is None  # no interval


def test_the_figure_marks_the_stops(tmp_path):
    fig = summarise(CONFIG, _early_stop_maps(), None)[0]["fig_3_7"]
    plot_fig_3_7(fig, tmp_path / "fig.png")
    assert (tmp_path / "fig.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_study_mrf_has_the_thesis_symmetry_pairs():
    assert THESIS_SYMMETRY_COUPLING == DEFAULT_COUPLING == 0.4  # §3.4: one Ising J = 0.4
    config = AffordanceMapConfig()
    assert config.mrf == MRFParams(symmetry_coupling=0.4) and config.symmetry_coupling == 0.4
    assert MRFParams().symmetry_coupling is None  # the maps library keeps them optional
    off = parse_study_args(
        AffordanceMapConfig, SMOKE, "study", argv=["--symmetry-coupling", "none"]
    )
    assert off.mrf.symmetry_coupling is None and off.fingerprint() != config.fingerprint()
    on = parse_study_args(AffordanceMapConfig, SMOKE, "study", argv=["--smoke"])
    assert on.mrf.symmetry_coupling == 0.4


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf, "strong", True])
def test_a_symmetry_coupling_that_is_not_a_finite_number_is_refused(value):
    with pytest.raises(InputError, match=r"^symmetry_coupling must be a (finite )?number"):
        AffordanceMapConfig(symmetry_coupling=value)
    with pytest.raises(InputError, match=r"^symmetry_coupling must be a (finite )?number"):
        MRFParams(symmetry_coupling=value)
