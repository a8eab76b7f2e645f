"""The chapter 6 study runs end to end on a shrunken configuration, resumes, and its
summaries compute what the records hold.

Covers probaff.experiments.modular.charts, probaff.experiments.modular.config,
probaff.experiments.modular.demo, probaff.experiments.modular.drawing,
probaff.experiments.modular.figures, probaff.experiments.modular.report,
probaff.experiments.modular.run, probaff.experiments.modular.trials.
"""

import json
import math

import numpy as np
import pytest
from matplotlib.container import BarContainer
from matplotlib.patches import Polygon
from study_helpers import (
    assert_resumes,
    assert_wrote,
    is_png,
    record_saved_figures,
    rerun_smoke,
    run_smoke,
)

import probaff.eval.plots as plots
import probaff.experiments.modular.charts as charts
import probaff.experiments.modular.drawing as drawing
from probaff.errors import InputError, ProbaffError
from probaff.experiments.modular import ModularStudyConfig, TrialSettings, run
from probaff.experiments.modular.report import (
    summarise_chains,
    summarise_skills,
    summarise_stepped,
    summarise_stepped_calibration,
    summarise_stepped_paired,
    summarise_two_objects,
)


@pytest.mark.slow
def test_script_smoke_and_resume(tmp_path):
    out = tmp_path / "modular"
    files = run_smoke("modular", out)
    tables = ("backward.csv", "two_objects.csv", "pick_place.csv", "chains.csv", "summary.md")
    tables += ("stepped.csv", "stepped_paired.csv", "stepped_calibration.csv")
    figures = ("tabletop_predictions.png", "sideview_predictions.png", "chain_errors.png")
    more = ("modular_vs_monolithic.png", "learning_curves.png")
    assert_wrote(files, out, tables + figures + more)
    text = (out / "summary.md").read_text()
    assert "5.8 cm without, 2.57 cm with" in text and "| monolithic | 2 | along |" in text
    assert "Hand: compliant" in text  # the thesis's setting is the default
    datasets = sorted(p.name for p in (out / "data").iterdir())
    assert datasets and all("_compliant_" in name for name in datasets)
    tasks = sorted((out / "tasks").glob("*.json"))
    assert len(tasks) == 4 * 2  # (push, pick, place, chained) x 2 trials at one scale
    records = [json.loads(p.read_text()) for p in tasks]
    push = [r for r in records if r["part"] == "push"]
    assert {tuple(r["test_rows"]) for r in push} == {(0, 1), (2, 3)}  # disjoint test slices
    for r in push:
        # the compliant hand deviates from its command along the path, more than at its end
        assert 0.0 < r["reaction_mm"] < r["reaction_path_mm"] < 50.0
        assert np.asarray(r["two"]["modular"]["mean"]).shape == (2, 2, 3)
        assert np.asarray(r["chains"]["3"]["lo"]).shape == (2, 3, 3)
        lo, hi = np.asarray(r["chains"]["3"]["lo"]), np.asarray(r["chains"]["3"]["hi"])
        assert np.all(lo <= hi)
        # the stepped model rolled out on the same test scenes, 14 steps of 2.5 cm
        stepped = r["stepped"]
        assert stepped["steps"] == 14 and stepped["true"] == r["two"]["true"]
        for name in ("stepped_forward", "stepped_planned", "stepped_backward"):
            assert np.isfinite(np.asarray(stepped[name])).all()
            assert np.asarray(stepped[name]).shape == (2, 2, 3)
        assert stepped["stepped_forward"] != stepped["stepped_backward"]  # reactions moved it
        assert stepped["calibration"]["hand_backward"]["rows"] == 2 * 14
        assert "stepped" in r["fit_seconds"]
    assert "## The stepped push model" in text
    assert_resumes(lambda: rerun_smoke("modular", out), tasks)  # resumes: no reruns


def _push_record(trial, true, modular, mono):
    def block(mean):
        mean = np.asarray(mean, dtype=float)
        return {"mean": mean.tolist(), "lo": (mean - 0.01).tolist(), "hi": (mean + 0.01).tolist()}

    chain = block(np.asarray(modular)[:, [0, 1, 1]])
    return {
        "part": "push",
        "n_train": 10,
        "test_rows": [trial],
        "two": {
            "rows": [trial],
            "true": true,
            "modular": block(modular),
            "monolithic": block(mono),
        },
        "chains": {
            "3": {
                **chain,
                "true": np.asarray(true)[:, [0, 1, 1]].tolist(),
                "touched": [[1.0, 1.0, 0.5]],
                "seconds": [0.2],
            }
        },
    }


def test_two_object_and_chain_summaries_score_the_means():
    true = [[[0.0, 0.10, 0.0], [0.0, 0.0, 0.0]]]  # o1 moved 10 cm along, o2 stayed put
    recs = [
        _push_record(
            0, true, [[[0.01, 0.12, 0.0], [0.0, 0.005, 0.0]]], [[[0.0, 0.06, 0], [0, 0.03, 0]]]
        ),
        _push_record(
            1, true, [[[0.03, 0.10, 0.0], [0.0, 0.015, 0.0]]], [[[0.0, 0.08, 0], [0, 0.01, 0]]]
        ),
    ]
    rows = {(r["model"], r["object"], r["axis"]): r for r in summarise_two_objects(recs)}
    assert rows["modular", 1, "along"]["error_cm"] == pytest.approx(1.0)  # (2 + 0) / 2 cm
    assert rows["modular", 1, "off"]["error_cm"] == pytest.approx(2.0)  # (1 + 3) / 2 cm
    assert rows["monolithic", 1, "along"]["error_cm"] == pytest.approx(3.0)  # (4 + 2) / 2 cm
    assert rows["monolithic", 2, "along"]["still_motion_cm"] == pytest.approx(2.0)
    assert rows["modular", 2, "along"]["still_motion_cm"] == pytest.approx(1.0)
    # t interval of the two per-trial errors 2 and 0: 12.706 * sd / sqrt(2)
    assert rows["modular", 1, "along"]["error_ci"] == pytest.approx(
        12.706 * math.sqrt(2) / math.sqrt(2), rel=1e-3
    )
    chains = summarise_chains(recs)
    assert [r["object"] for r in chains] == [1, 2, 3]
    assert chains[0]["error_cm"] == pytest.approx(np.mean([np.hypot(1, 2), 3.0]))
    assert chains[2]["touched"] == 0.5 and chains[0]["moved"] == 1.0 and chains[1]["moved"] == 0.0


def test_stepped_summaries_score_the_rollouts_and_pair_them():
    true = [[[0.0, 0.10, 0.0], [0.0, 0.0, 0.0]]]  # o1 moved 10 cm along, o2 stayed put
    recs = []
    for trial, (fwd, bwd) in enumerate([(0.04, 0.01), (0.02, 0.01)]):
        rec = _push_record(trial, true, [[[0.0, 0.13, 0.0], [0.0, 0.0, 0.0]]], true)
        cal = {"rows": 14, "nlpd": [1.0, 3.0], "coverage": [0.8, 1.0]}
        rec["stepped"] = {
            "true": true,
            "steps": 14,
            "stepped_forward": [[[0.0, 0.10 - fwd, 0.0], [0.03, 0.04, 0.0]]],
            "stepped_planned": [[[0.0, 0.10 - fwd, 0.0], [0.0, 0.0, 0.0]]],
            "stepped_backward": [[[bwd, 0.10, 0.0], [0.0, 0.0, 0.0]]],
            "calibration": {"hand_backward": cal, "link_backward": {**cal, "rows": 0}},
        }
        recs.append(rec)
    rows = {(r["model"], r["object"]): r for r in summarise_stepped(recs)}
    assert rows["stepped_forward", 1]["along_cm"] == pytest.approx(3.0)  # (4 + 2) / 2
    assert rows["stepped_backward", 1]["off_cm"] == pytest.approx(1.0)
    assert rows["stepped_forward", 2]["error_cm"] == pytest.approx(5.0)  # |(3, 4)| cm
    assert rows["whole_push", 1]["along_cm"] == pytest.approx(3.0)  # the two-object chain
    paired = {(r["comparison"], r["object"]): r for r in summarise_stepped_paired(recs)}
    diff = paired["stepped_forward - stepped_backward", 1]
    assert diff["diff_cm"] == pytest.approx(2.0) and diff["trials"] == 2  # (3 + 1) / 2
    assert paired["stepped_planned - stepped_backward", 2]["diff_cm"] == 0.0
    cal = summarise_stepped_calibration(recs)
    assert [r["component"] for r in cal] == ["hand_backward"]  # no held-out link step
    assert cal[0]["nlpd"] == 2.0 and cal[0]["coverage90"] == 0.9 and cal[0]["rows"] == 28
    assert summarise_stepped([_push_record(0, true, true, true)]) == []  # no stepped rollouts


def test_skill_summary_splits_by_the_simulators_verdict():
    true = [[0.2, 0.0, 0.0], [0.0, 0.0, 0.0], [0.2, 0.0, 0.0]]
    pred = [[0.18, 0.0, 0.0], [0.01, 0.0, 0.0], [0.05, 0.0, 0.0]]  # the third judged a failure
    score = {"mean": pred, "sd": [[0.01] * 3] * 3, "nlpd": [1.0, 2.0, 3.0], "coverage": [1, 1, 1]}
    rec = {
        "part": "pick",
        "n_train": 5,
        "test_rows": [0, 1, 2],
        "true": true,
        "success": [True, False, True],
        **{m: score for m in ("forward", "backward", "mixture")},
    }
    rows = {(r["model"], r["case"]): r for r in summarise_skills([rec])}
    ok, failed = rows["forward", "succeeded"], rows["forward", "failed"]
    assert ok["n"] == 2 and failed["n"] == 1
    assert failed["predicted_cm"] == pytest.approx(1.0) and failed["true_cm"] == 0.0
    assert ok["error_cm"] == pytest.approx((2.0 + 15.0) / 2)
    assert rows["forward", "all"]["misjudged"] == 1 and rows["forward", "all"]["nlpd"] == 6.0
    assert ("forward", "slipped") not in rows  # no slip flags, no split
    rows = {(r["model"], r["case"]): r for r in summarise_skills([{**rec, "slipped": [0, 1, 0]}])}
    assert rows["forward", "slipped"]["n"] == 1 and ("forward", "not grasped") not in rows


def test_bad_config(tmp_path):
    with pytest.raises(InputError, match="trials must be a positive integer"):
        run(ModularStudyConfig(trials=0))
    with pytest.raises(InputError, match="scales must be finite numbers >= 1"):
        run(ModularStudyConfig(scales=(0.5,)))
    with pytest.raises(InputError, match="chain_lengths may hold 3, 4 and 5"):
        run(ModularStudyConfig(chain_lengths=(7,)))
    # TrialSettings checks itself when it is built, before any study sees it.
    with pytest.raises(InputError, match="push_groups: unknown feature groups"):
        TrialSettings(push_groups=("colour",))
    with pytest.raises(InputError, match="chain_samples must be an integer >= 2"):
        TrialSettings(chain_samples=1)
    with pytest.raises(InputError, match="settings must be a TrialSettings"):
        run(ModularStudyConfig(settings="fast"))  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"hand must be one of \['stiff', 'compliant'\]"):
        run(ModularStudyConfig(hand="rubber"))
    with pytest.raises(InputError, match="reaction must be one of"):
        TrialSettings(reaction="start")
    with pytest.raises(InputError, match=r"push_scene must be one of \['modular_push', 'resis"):
        run(ModularStudyConfig(push_scene="chain_3"))
    for bad in (0.0, -0.025, math.nan, "2.5 cm", True):
        with pytest.raises(InputError, match="step_length must be a positive"):
            TrialSettings(step_length=bad)
    with pytest.raises(InputError, match="stepped must be True or False"):
        TrialSettings(stepped="yes")  # type: ignore[arg-type]
    # a step that does not divide the scene's 35 cm push: refused before any dataset is made
    with pytest.raises(InputError, match=r"step_length=0.03 m does not divide the 0.35 m push"):
        run(ModularStudyConfig(out=str(tmp_path / "m"), settings=TrialSettings(step_length=0.03)))
    assert not (tmp_path / "m").exists()


# --- figures


@pytest.fixture
def saved(monkeypatch):
    """The figures the module saves, in order (the files are still written)."""
    return record_saved_figures(monkeypatch, plots)


def _json(value):
    """`value` as it comes back from a JSON file: arrays become nested lists."""
    return json.loads(json.dumps(value, default=lambda a: a.tolist()))


def _scene(k, seed, monolithic=True, path=True):
    """A synthetic push of a row of `k` boxes along +x, each box ending 5 cm further on."""
    rng = np.random.default_rng(seed)
    sizes = np.column_stack([np.linspace(0.12, 0.2, k), np.full(k, 0.1), np.full(k, 0.15)])
    start = np.column_stack([0.2 * np.arange(k), rng.normal(0, 0.02, k), rng.uniform(-1, 1, k)])
    true = start + np.array([0.05, 0.01, 0.2])
    samples = true + rng.normal(0, [0.01, 0.01, 0.05], (20, k, 3))
    steps = np.linspace(0, 1, 6)[:, None, None]
    return {
        "sizes": sizes,
        "start": start,
        "true_final": true,
        "true_path": start + steps * (true - start) if path else None,
        "samples": samples,
        "hand_start": np.array([-0.25, start[0, 1]]),
        "hand_end": np.array([-0.05, start[0, 1]]),
        "monolithic_final": true + np.array([0.04, -0.02, 0.1]) if monolithic else None,
        "label": f"{k} boxes, seed {seed}",
    }


def _case(skill, success, k=2):
    sizes = np.array([[0.1, 0.1], [0.2, 0.12]])[:k]
    start = np.column_stack([[0.0, 0.25][:k], sizes[:, 1] / 2, np.zeros(k)])
    true = start.copy()
    if success:
        true[0, 1] += 0.2 if skill == "pick" else -0.02
    tcp = np.array([[0.0, 0.3], [0.0, 0.05], [0.0, 0.25]])
    return {
        "skill": skill,
        "success": success,
        "label": f"{skill} case",
        "sizes": sizes,
        "start": start,
        "true_final": true,
        "target": 0,
        "pred_final": true[0] + [0.01, -0.01, 0.0],
        "pred_sd": np.array([0.01, 0.02, 0.05]),
        "tcp_commanded": tcp,
        "tcp_actual": tcp + np.array([0.005, 0.01]),
    }


def _chain_rows():
    rows = []
    for n in (1, 2, 3):
        for obj in range(1, n + 1):
            rows.append(
                {
                    "n_objects": n,
                    "object": obj,
                    "error_cm": 1.0 + obj,
                    "error_ci": 0.3,
                    "coverage90": 0.95 - 0.05 * obj,
                    "coverage_ci": 0.05,
                }
            )
    return rows


def _bar_rows():
    values = {"modular": (1.9, 0.8, 1.0, 0.9), "monolithic": (4.8, 0.5, 2.5, 0.6)}
    rows = []
    for model, errs in values.items():
        for (obj, axis), err in zip(
            [(1, "along"), (1, "off"), (2, "along"), (2, "off")], errs, strict=True
        ):
            rows.append({"model": model, "object": obj, "axis": axis, "error_cm": err})
            rows[-1]["error_ci"] = 0.2
    return rows


THESIS = {
    ("modular", 1, "along"): 1.89,
    ("monolithic", 1, "along"): 4.83,
    ("modular", 2, "along"): 1.02,
    ("monolithic", 2, "along"): 2.49,
}


def _curve_rows(sizes=(5, 10, 20)):
    rows = []
    for panel in ("push o1 along (cm)", "pick up (cm)"):
        for series, scale in (("modular", 1.0), ("monolithic", 2.0)):
            for n in sizes:
                value = scale * 10 / math.sqrt(n)
                rows.append(
                    {"panel": panel, "series": series, "train_size": n, "value": value, "ci": 0.5}
                )
    return rows


def _bars(ax):
    return [c for c in ax.containers if isinstance(c, BarContainer)]


def _polygons(ax, style):
    return [p for p in ax.patches if isinstance(p, Polygon) and p.get_linestyle() == style]


def test_tabletop_panels_boxes_and_legend(tmp_path, saved):
    scenes = [_scene(2, 0), _scene(3, 1, monolithic=False), _scene(2, 2), _scene(2, 3)]
    scenes.append(_scene(1, 4, monolithic=False, path=False))
    out = drawing.plot_tabletop_predictions(scenes, tmp_path / "top.png", title="pushes")
    assert out == str(tmp_path / "top.png") and is_png(out)
    (fig,) = saved
    axes = [ax for ax in fig.axes if ax.axison]
    assert len(axes) == 5
    # four panels to a row, the second row holding the fifth
    assert [ax.get_subplotspec().rowspan.start for ax in axes] == [0, 0, 0, 0, 1]
    for ax, scene in zip(axes, scenes, strict=True):
        k = len(scene["sizes"])
        assert ax.get_aspect() == 1.0 and scene["label"] in ax.get_title()
        assert ax.get_xlabel() == "x (m)" and ax.get_ylabel() == "y (m)"
        # the blue dashed box sits at the samples' mean, yaw the circular mean
        dashed = _polygons(ax, "--")
        assert len(dashed) == k
        yaw = scene["samples"][..., 2]
        mean = scene["samples"].mean(0)
        mean[:, 2] = np.arctan2(np.sin(yaw).mean(0), np.cos(yaw).mean(0))
        for j, patch in enumerate(dashed):
            size = tuple(scene["sizes"][j, :2])
            corners = drawing.box_corners(mean[j], size)
            assert np.allclose(patch.get_xy()[:4], corners, atol=1e-6)
        # one dotted monolithic box per object when it is given, none otherwise
        assert len(_polygons(ax, ":")) == (k if scene["monolithic_final"] is not None else 0)
        assert ("monolithic" in ax.get_title()) == (scene["monolithic_final"] is not None)
        arrows = [t for t in ax.texts if t.get_text() == ""]
        assert len(arrows) == 1
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert {"start", "observed final", "modular mean", "monolithic", "hand push"} <= set(labels)
    assert fig.get_suptitle() == "pushes"


def test_tabletop_mean_yaw_is_circular():
    samples = np.zeros((2, 1, 3))
    samples[:, 0, 2] = [math.pi - 0.1, -math.pi + 0.1]
    assert abs(abs(drawing._mean_pose(samples)[0, 2]) - math.pi) < 1e-9


def test_tabletop_reads_json_lists(tmp_path, saved):
    scenes = _json([_scene(2, 5), _scene(4, 6, monolithic=False)])
    scenes[1]["true_path"] = []
    del scenes[1]["monolithic_final"]
    assert is_png(drawing.plot_tabletop_predictions(scenes, tmp_path / "json.png"))
    (fig,) = saved
    assert "2 scenes" in fig.get_suptitle()
    # four objects: the title gives the mean and largest error, not every object
    assert "over 4 objects" in fig.axes[1].get_title()
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert "monolithic" in labels


def test_tabletop_bad_input(tmp_path):
    out = tmp_path / "x.png"
    with pytest.raises(InputError, match="scenes is empty"):
        drawing.plot_tabletop_predictions([], out)
    with pytest.raises(InputError, match="sequence"):
        drawing.plot_tabletop_predictions(_scene(2, 0), out)
    no_samples = {k: v for k, v in _scene(2, 0).items() if k != "samples"}
    with pytest.raises(InputError, match=r"scenes\[1\] lacks key\(s\) \['samples'\]"):
        drawing.plot_tabletop_predictions([_scene(2, 0), no_samples], out)
    wrong_k = dict(_scene(2, 0), samples=np.zeros((5, 3, 3)))
    with pytest.raises(InputError, match=r"scenes\[0\]\['samples'\] has shape \(5, 3, 3\)"):
        drawing.plot_tabletop_predictions([wrong_k], out)
    nan = _scene(2, 0)
    nan["start"][1, 0] = np.nan
    with pytest.raises(InputError, match=r"scenes\[0\]\['start'\] contains 1 NaN"):
        drawing.plot_tabletop_predictions([nan], out)
    with pytest.raises(InputError, match=r"\['sizes'\] must be > 0"):
        drawing.plot_tabletop_predictions([dict(_scene(1, 0), sizes=[[0.1, -0.1, 0.1]])], out)
    with pytest.raises(InputError, match=r"\['hand_end'\] must be an array of numbers"):
        drawing.plot_tabletop_predictions([dict(_scene(1, 0), hand_end=["a", "b"])], out)
    with pytest.raises(InputError, match=r"\['monolithic_final'\] has shape"):
        drawing.plot_tabletop_predictions([dict(_scene(2, 0), monolithic_final=[0, 0, 0])], out)
    with pytest.raises(InputError, match="path must be a file path"):
        drawing.plot_tabletop_predictions([_scene(2, 0)], None)
    assert not out.exists()


def test_sideview_panels(tmp_path, saved):
    cases = [_case("pick", True), _case("pick", False), _case("place", True, k=1)]
    cases += [_case("place", False)] * 3
    out = drawing.plot_sideview_predictions(_json(cases), tmp_path / "side.png")
    assert is_png(out)
    (fig,) = saved
    axes = [ax for ax in fig.axes if ax.axison]
    assert len(axes) == 6
    assert [ax.get_subplotspec().rowspan.start for ax in axes] == [0] * 5 + [1]
    titles = [ax.get_title() for ax in axes]
    assert "pick: lifted" in titles[0] and "pick: not lifted" in titles[1]
    assert "place: placed" in titles[2] and "place: not placed" in titles[3]
    assert "2 picks, 4 places" in fig.get_suptitle()
    ax = axes[0]
    assert ax.get_ylabel() == "z (m)" and ax.get_ylim()[0] < 0 < ax.get_ylim()[1]
    (pred,) = _polygons(ax, "--")
    corners = drawing.box_corners(np.asarray(cases[0]["pred_final"]), (0.1, 0.1))
    assert np.allclose(pred.get_xy()[:4], corners)
    # the 90 % bars span 1.645 sd either side of the predicted centre
    (bars,) = ax.containers
    (xbar, zbar) = bars.lines[2]
    x_ends = xbar.get_segments()[0][:, 0]
    z_ends = zbar.get_segments()[0][:, 1]
    centre = cases[0]["pred_final"]
    assert np.allclose(x_ends, centre[0] + np.array([-1, 1]) * 1.645 * 0.01)
    assert np.allclose(z_ends, centre[1] + np.array([-1, 1]) * 1.645 * 0.02)
    styles = sorted(
        line.get_linestyle() for line in ax.get_lines() if line.get_color() == "crimson"
    )
    assert styles == ["-", "--"]


def test_sideview_bad_input(tmp_path):
    out = tmp_path / "x.png"
    with pytest.raises(InputError, match="cases is empty"):
        drawing.plot_sideview_predictions([], out)
    with pytest.raises(InputError, match=r"cases\[0\]\['skill'\] must be one of"):
        drawing.plot_sideview_predictions([dict(_case("pick", True), skill="push")], out)
    with pytest.raises(InputError, match=r"cases\[0\]\['target'\] is 2 but the case has 2"):
        drawing.plot_sideview_predictions([dict(_case("pick", True), target=2)], out)
    with pytest.raises(InputError, match=r"cases\[0\]\['target'\] must be an integer"):
        drawing.plot_sideview_predictions([dict(_case("pick", True), target=0.5)], out)
    with pytest.raises(InputError, match=r"\['success'\] must be true or false"):
        drawing.plot_sideview_predictions([dict(_case("pick", True), success="yes")], out)
    with pytest.raises(InputError, match=r"\['pred_sd'\] must be >= 0"):
        drawing.plot_sideview_predictions([dict(_case("pick", True), pred_sd=[0.1, -0.1, 0])], out)
    with pytest.raises(InputError, match=r"\['tcp_actual'\] contains 1 NaN"):
        bad = dict(_case("pick", True), tcp_actual=[[0, 0.1], [0, math.inf]])
        drawing.plot_sideview_predictions([bad], out)
    with pytest.raises(InputError, match=r"\['tcp_commanded'\] is empty"):
        drawing.plot_sideview_predictions(
            [dict(_case("pick", True), tcp_commanded=np.zeros((0, 2)))], out
        )
    with pytest.raises(InputError, match=r"cases\[0\]\['true_final'\] has shape \(1, 3\)"):
        drawing.plot_sideview_predictions([dict(_case("pick", True), true_final=[[0, 0, 0]])], out)
    assert not out.exists()


def test_chain_errors(tmp_path, saved):
    rows = _chain_rows()
    out = charts.plot_chain_errors(_json(rows), tmp_path / "chain.png", title="chains")
    assert is_png(out)
    (fig,) = saved
    err_ax, cov_ax = fig.axes
    assert err_ax.get_ylabel() == "mean position error (cm)"
    assert "coverage" in cov_ax.get_ylabel()
    # one line per chain length, in both panels; its points are that length's objects
    for ax, key in ((err_ax, "error_cm"), (cov_ax, "coverage90")):
        lines = [c.lines[0] for c in ax.containers]
        assert len(lines) == 3  # one per chain length
        for n, line in zip((1, 2, 3), lines, strict=True):
            want = [r[key] for r in rows if r["n_objects"] == n]
            assert np.allclose(line.get_ydata(), want)
            assert np.allclose(np.round(line.get_xdata()), np.arange(1, n + 1))
    nominal = [line for line in cov_ax.get_lines() if line.get_linestyle() == "--"]
    assert len(nominal) == 1 and np.allclose(nominal[0].get_ydata(), 0.9)
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert labels == ["1 object", "2 objects", "3 objects", "nominal 90 %"]


def _refuses_empty_and_incomplete_rows(plot, rows, index, key, out):
    """`plot` refuses no rows, and `rows` once its row `index` lacks `key`."""
    with pytest.raises(InputError, match="rows is empty"):
        plot([], out)
    del rows[index][key]
    with pytest.raises(InputError, match=rf"rows\[{index}\] lacks key\(s\) \['{key}'\]"):
        plot(rows, out)


def test_chain_errors_bad_input(tmp_path):
    out = tmp_path / "x.png"
    _refuses_empty_and_incomplete_rows(
        charts.plot_chain_errors, _chain_rows(), 2, "coverage_ci", out
    )
    beyond = [dict(_chain_rows()[0], object=2)]
    with pytest.raises(InputError, match=r"rows\[0\]\['object'\] is 2 but the chain has 1"):
        charts.plot_chain_errors(beyond, out)
    with pytest.raises(InputError, match="not percent"):
        charts.plot_chain_errors([dict(_chain_rows()[0], coverage90=90.0)], out)
    with pytest.raises(InputError, match=r"rows\[0\]\['n_objects'\] must be a positive integer"):
        charts.plot_chain_errors([dict(_chain_rows()[0], n_objects=1.5)], out)
    with pytest.raises(InputError, match=r"rows\[0\]\['error_ci'\] must be a finite number"):
        charts.plot_chain_errors([dict(_chain_rows()[0], error_ci=math.nan)], out)
    twice = _chain_rows()[:1] * 2
    with pytest.raises(InputError, match=r"rows\[1\] repeats \(n_objects, object\)"):
        charts.plot_chain_errors(twice, out)
    assert not out.exists()


def test_modular_vs_monolithic(tmp_path, saved):
    rows = _bar_rows()
    out = charts.plot_modular_vs_monolithic(rows, tmp_path / "bars.png", thesis=THESIS)
    assert is_png(out)
    (fig,) = saved
    (ax,) = fig.axes
    assert ax.get_ylabel() == "mean absolute error (cm)"
    ticks = [t.get_text() for t in ax.get_xticklabels()]
    assert ticks == [
        "o1\nalong the push",
        "o1\noff the push",
        "o2\nalong the push",
        "o2\noff the push",
    ]
    bars = {c.get_label(): [p.get_height() for p in c.patches] for c in _bars(ax)}
    assert np.allclose(bars["modular"], [1.9, 0.8, 1.0, 0.9])
    assert np.allclose(bars["monolithic"], [4.8, 0.5, 2.5, 0.6])
    # each thesis tick lies across its own bar, at the thesis value
    patches = {c.get_label(): c.patches for c in _bars(ax)}
    (ticks_coll,) = [c for c in ax.collections if c.get_label() == "thesis"]
    segments = ticks_coll.get_segments()
    assert len(segments) == 4
    for seg, ((model, obj, axis), value) in zip(segments, THESIS.items(), strict=True):
        group = [(1, "along"), (1, "off"), (2, "along"), (2, "off")].index((obj, axis))
        bar = patches[model][group]
        assert np.allclose(seg[:, 1], value)
        assert bar.get_x() <= seg[:, 0].min() and seg[:, 0].max() <= bar.get_x() + bar.get_width()
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert labels == ["modular", "monolithic", "thesis"]


def test_modular_vs_monolithic_without_thesis(tmp_path, saved):
    rows = [r for r in _bar_rows() if r["object"] == 1] + [dict(_bar_rows()[0], model="other")]
    assert is_png(charts.plot_modular_vs_monolithic(_json(rows), tmp_path / "b.png"))
    (fig,) = saved
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert labels == ["modular", "monolithic", "other"]
    colours = {c.get_label(): c.patches[0].get_facecolor() for c in _bars(fig.axes[0])}
    assert len(set(colours.values())) == 3


def test_modular_vs_monolithic_bad_input(tmp_path):
    out = tmp_path / "x.png"
    with pytest.raises(InputError, match="rows is empty"):
        charts.plot_modular_vs_monolithic([], out)
    with pytest.raises(InputError, match=r"rows\[0\]\['axis'\] must be one of \['along', 'off'\]"):
        charts.plot_modular_vs_monolithic([dict(_bar_rows()[0], axis="x")], out)
    with pytest.raises(InputError, match=r"rows\[0\]\['error_cm'\] contains 1 NaN"):
        charts.plot_modular_vs_monolithic([dict(_bar_rows()[0], error_cm=math.nan)], out)
    with pytest.raises(InputError, match=r"rows\[0\]\['object'\] must be a positive integer"):
        charts.plot_modular_vs_monolithic([dict(_bar_rows()[0], object=0)], out)
    with pytest.raises(InputError, match=r"thesis\[\('Modular', 1, 'along'\)\] matches no bar"):
        charts.plot_modular_vs_monolithic(_bar_rows(), out, thesis={("Modular", 1, "along"): 1.9})
    with pytest.raises(InputError, match="thesis must map"):
        charts.plot_modular_vs_monolithic(_bar_rows(), out, thesis=[1.89])
    with pytest.raises(InputError, match=r"rows\[8\] repeats \(model, object, axis\)"):
        charts.plot_modular_vs_monolithic(_bar_rows() + _bar_rows()[:1], out)
    assert not out.exists()


def test_learning_curves(tmp_path, saved):
    rows = _curve_rows(sizes=(20, 5, 10, 40))  # unsorted sizes spanning a factor 8
    rows += [
        dict(r, panel="place (cm)", train_size=s) for r, s in zip(rows[:2], (4, 8), strict=True)
    ]
    out = charts.plot_learning_curves(_json(rows), tmp_path / "curves.png")
    assert is_png(out)
    (fig,) = saved
    axes = [ax for ax in fig.axes if ax.axison]
    assert [ax.get_title() for ax in axes] == ["push o1 along (cm)", "pick up (cm)", "place (cm)"]
    assert axes[0].get_ylabel() == "error (cm)"
    assert axes[0].get_xscale() == "log" and axes[2].get_xscale() == "linear"
    assert [t.get_text() for t in axes[0].get_xticklabels()] == ["5", "10", "20", "40"]
    # each line is one series, in order of size, with its band
    lines = axes[0].get_lines()
    assert [line.get_label() for line in lines] == ["modular", "monolithic"]
    assert len(axes[0].collections) == 2
    assert np.allclose(lines[0].get_xdata(), [5, 10, 20, 40])
    assert np.allclose(lines[1].get_ydata(), 20 / np.sqrt([5, 10, 20, 40]))
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert labels == ["modular", "monolithic", "95 % interval"]


def test_learning_curves_linear_sizes_and_single_points(tmp_path, saved):
    rows = [r for r in _curve_rows(sizes=(10, 20, 40)) if r["panel"] == "pick up (cm)"]
    rows.append(dict(rows[0], series="one size", train_size=30, ci=1.0))
    assert is_png(charts.plot_learning_curves(rows, tmp_path / "c.png", title="pick"))
    (fig,) = saved
    (ax,) = fig.axes
    assert ax.get_xscale() == "linear" and fig.get_suptitle() == "pick"
    # a series of one size shows its interval as an error bar, the others as bands
    (bar,) = ax.containers
    (segment,) = bar.lines[2][0].get_segments()
    assert np.allclose(segment, [[30, rows[0]["value"] - 1], [30, rows[0]["value"] + 1]])


def test_learning_curves_bad_input(tmp_path):
    out = tmp_path / "x.png"
    _refuses_empty_and_incomplete_rows(charts.plot_learning_curves, _curve_rows(), 3, "ci", out)
    with pytest.raises(InputError, match=r"rows\[0\]\['train_size'\] must be a positive integer"):
        charts.plot_learning_curves([dict(_curve_rows()[0], train_size="ten")], out)
    with pytest.raises(InputError, match=r"rows\[0\]\['value'\] contains 1 NaN"):
        charts.plot_learning_curves([dict(_curve_rows()[0], value=math.inf)], out)
    with pytest.raises(InputError, match=r"rows\[0\]\['series'\] must be a non-empty string"):
        charts.plot_learning_curves([dict(_curve_rows()[0], series=None)], out)
    with pytest.raises(InputError, match=r"rows\[1\] repeats \(panel, series, size\)"):
        charts.plot_learning_curves(_curve_rows()[:1] * 2, out)
    with pytest.raises(ProbaffError, match="must be a sequence"):
        charts.plot_learning_curves({"panel": "a"}, out)
    assert not out.exists()
