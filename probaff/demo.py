"""`probaff demo`: the main job on a small embedded default, printed as a short report.

It generates a small two-object push dataset (chapter 5's scene, poses observed with a depth
camera's noise), prints a table of it and draws a few pushes with the arm's reachable region,
fits a mixture of GP experts by EM next to a single GP, printing their held-out RMSE, NLPD and
90 % interval coverage and drawing both models' predictive density of o2's motion for a push
where the mixture sees two outcomes (o2 hit or not), and then explores a small warehouse map
(boxes and interior wall blocks that the camera cannot tell apart), pushes a few blocks chosen
by information gain on the affordance MRF, and prints the map's entropy before and after,
drawing the walls crossed out on the loop's figure, then plans and executes one push-to-edge
episode (chapter 4: A* over the mixture's predictions, closed loop in the simulator), drawn to
a PNG, and fits chapter 6's per-skill transition models and predicts a pick, a place and a
three-object chained push, drawn against what the simulator did. Last (chapter 2) it scans
23 office scenes from the robot's head (three views each, as the chapter 2 study does),
segments them by region growing, trains the label classifiers on all but one and draws the
held-out scene's segments and predicted labels to a PNG, printing its held-out precision and
recall.

The report: each stage's lines come out together when the stage ends, above one transient
progress bar over the stages (on stderr); the `RuntimeWarning`s that a fit records in its
history (e.g. EM reseeding a collapsed expert) are summarised in one ``note:`` line per fit
(per stage for the chapters' parts) instead of being printed as they happen; the report ends
with its headline numbers and the paths of its figures.
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import re
import sys
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch.distributions import Normal
from tqdm.auto import tqdm

from probaff._checks import check_count
from probaff._threads import limit_threads
from probaff.data import GenerateConfig, generate
from probaff.data.noise import PoseNoise
from probaff.data.schema import PushDataset
from probaff.data.summary import summarize
from probaff.eval.metrics import interval_coverage, nlpd, rmse
from probaff.experiments.affordance_map.demo import demo as affordance_demo
from probaff.experiments.modular.demo import demo as modular_demo
from probaff.experiments.planning.demo import demo as planning_demo
from probaff.experiments.point_cloud_labels.demo import DEMO_SCENES
from probaff.experiments.point_cloud_labels.demo import demo as point_cloud_demo
from probaff.experiments.point_cloud_labels.intervals import interval_text
from probaff.experiments.push_models.figures import plot_predictive_density, plot_pushes
from probaff.features import chapter5_features
from probaff.models import GPOptions, MixtureOfGPExperts, fit_em
from probaff.sim import load_arm, load_tabletop

__all__ = ["DemoConfig", "run"]

_STAGES = 6
"""Stages of the report: dataset, models, affordance map, planning, chapter 6, chapter 2."""

_EM_ITERATION = re.compile(r"EM iteration (\d+): (.*)", re.DOTALL)


@dataclass(frozen=True)
class DemoConfig:
    """Settings of the demo.

    Attributes:
        out: Output folder (created; an earlier demo there is resumed).
        n: Pushes to generate.
        seed: Dataset seed.
        workers: 0 runs in this process; K > 0 uses a local Dask cluster.
        office_scenes: Office scenes of the chapter 2 part, the held-out one included (an
            integer >= 2; by default `DEMO_SCENES`, 23: 22 train the label classifiers, as
            many as one fold of the chapter 2 study trains on).
        progress: Show one progress bar over the demo's stages (on stderr, gone at the end).
    """

    out: str = "results/demo"
    n: int = 96
    seed: int = 0
    workers: int = 0
    office_scenes: int = DEMO_SCENES
    progress: bool = True


def run(config: DemoConfig) -> dict[str, Any]:
    """Run the demo, print its report and return what it found and wrote.

    Args:
        config: Demo settings.

    Returns:
        ``{"summary": ..., "dataset": path, "figure": path, "models", "affordance_map",
        "planning", "modular", "point_cloud_labels": each part's summary, "figures": the
        paths of every figure, in the report's order}``.

    Raises:
        InputError: If `n`, `seed`, `workers` or `office_scenes` is not a valid count (before
            any work).
    """
    check_count("n", config.n)
    check_count("seed", config.seed, minimum=0)
    check_count("workers", config.workers, minimum=0)
    check_count("office_scenes", config.office_scenes, minimum=2)
    out = Path(config.out)
    seed = config.seed
    report = _Report(_STAGES, config.progress)
    report.line(f"probaff demo: {config.n} two-object pushes, seed {seed}, output in {out}")
    try:
        with report.stage("two-object pushes (chapter 5's scene)"):
            ds, summary, pushes_png = _dataset(config, out)
        with report.stage("push models, scored on held-out pushes") as notes:
            models, density_png = _compare_models(ds, seed, out, notes)
        with report.stage("affordance map, refined by pushing"):
            affordance = affordance_demo(out / "affordance_map", seed=seed, steps=4)
        with report.stage("push to the edge (chapter 4)"):
            planning = planning_demo(out / "planning", seed=seed, progress=False)
        with report.stage("modular transition models (chapter 6)"):
            modular = modular_demo(out / "modular", seed=seed, progress=False)
        with report.stage("point-cloud labels (chapter 2)"):
            labels = point_cloud_demo(
                out / "point_cloud_labels", seed=seed, scenes=config.office_scenes, progress=False
            )
    finally:
        report.close()
    result: dict[str, Any] = {
        "summary": summary,
        "dataset": os.fspath(out / "two_objects"),
        "figure": os.fspath(pushes_png),
        "models": models,
        "affordance_map": affordance,
        "planning": planning,
        "modular": {k: modular[k] for k in ("chains", "skills", "files")},
        "point_cloud_labels": labels,
    }
    result["figures"] = [
        os.fspath(pushes_png),
        os.fspath(density_png),
        os.fspath(affordance["figure"]),
        os.fspath(planning["figure"]),
        *(os.fspath(f) for f in modular["files"] if str(f).endswith(".png")),
        os.fspath(labels["file"]),
    ]
    for text in _summary_lines(result):
        report.line(text)
    return result


class _Report:
    """The printed report: lines on stdout above one transient progress bar on stderr.

    A stage's own prints are held until it ends and then printed, indented, under its title,
    followed by its ``note:`` lines, so that the bar never splits a line of the report.
    """

    def __init__(self, stages: int, progress: bool) -> None:
        self._bar = tqdm(
            total=stages,
            desc="probaff demo",
            unit="stage",
            leave=False,
            disable=not progress,
            file=sys.stderr,
        )

    def line(self, text: str = "") -> None:
        """Print one line of the report above the bar."""
        tqdm.write(text, file=sys.stdout)

    @contextlib.contextmanager
    def stage(self, title: str) -> Iterator[list[str]]:
        """Run one stage; yield its list of ``note:`` lines (a fit's warnings go there).

        The `RuntimeWarning`s left over from the stage's fits (those not noted per fit) are
        summarised in one more note. The stage's lines are printed even when it fails.
        """
        self._bar.set_description(f"probaff demo: {title}")
        notes: list[str] = []
        held = io.StringIO()
        try:
            with contextlib.redirect_stdout(held), _fit_warnings("this stage's fits", notes):
                yield notes
        finally:
            self.line()
            self.line(title)
            for text in [*held.getvalue().splitlines(), *notes]:
                self.line(f"  {text}")
            self._bar.update()

    def close(self) -> None:
        """Remove the bar."""
        self._bar.close()


@contextlib.contextmanager
def _fit_warnings(source: str, notes: list[str]) -> Iterator[None]:
    """Hold back the `RuntimeWarning`s of a block (a fit's history) and note them in one line.

    Every `RuntimeWarning` raised in the block is recorded (repeats included) instead of
    printed, and, if there was any, `_warning_note` of them is appended to `notes`. Warnings of
    other categories are shown as usual when the block ends.

    Args:
        source: What the block is, for the note (e.g. ``"the mixture M=3 fit"``).
        notes: Where the note goes.
    """
    caught: list[warnings.WarningMessage] = []
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", RuntimeWarning)
            yield
    finally:  # also when the block fails: nothing is lost
        for w in caught:
            if not issubclass(w.category, RuntimeWarning):
                warnings.showwarning(w.message, w.category, w.filename, w.lineno, w.file, w.line)
        messages = [str(w.message) for w in caught if issubclass(w.category, RuntimeWarning)]
        if messages:
            notes.append(_warning_note(source, messages))


def _warning_note(source: str, messages: list[str]) -> str:
    """One line that summarises a fit's warnings.

    Messages that differ only in their ``"EM iteration N: "`` prefix are merged into one part
    with their count and the range of their iterations; repeats of any other message are
    counted.

    Args:
        source: What raised them (e.g. ``"the mixture M=3 fit"``).
        messages: The warnings' texts, at least one.

    Returns:
        E.g. ``"note: 2 warnings from the mixture M=3 fit: collapsed expert(s) took samples
        from another expert (2 times, EM iterations 1 to 3)"`` (a fit that restarts EM counts
        its iterations from 1 again).
    """
    merged: dict[str, list[int]] = {}
    for message in messages:
        match = _EM_ITERATION.fullmatch(message.strip())
        text, iteration = (match[2], int(match[1])) if match else (message.strip(), 0)
        merged.setdefault(text.rstrip("."), []).append(iteration)
    parts = []
    for text, iterations in merged.items():
        numbered = sorted(i for i in iterations if i)
        where = []
        if len(iterations) > 1:
            where.append(f"{len(iterations)} times")
        if numbered and numbered[0] == numbered[-1]:
            where.append(f"EM iteration {numbered[0]}")
        elif numbered:
            where.append(f"EM iterations {numbered[0]} to {numbered[-1]}")
        parts.append(f"{text} ({', '.join(where)})" if where else text)
    n = len(messages)
    return f"note: {n} warning{'s' if n > 1 else ''} from {source}: " + "; ".join(parts)


def _dataset(config: DemoConfig, out: Path) -> tuple[PushDataset, dict[str, Any], Path]:
    """Generate (or resume) the demo's pushes, print their table and draw six of them.

    Returns:
        The dataset, its summary (`probaff.data.summary.summarize`) and the figure's path.
    """
    ds_path = out / "two_objects"
    gen = GenerateConfig(
        scene="two_objects", n=config.n, seed=config.seed, shard_size=16, pose_noise=PoseNoise()
    )
    ds = generate(gen, ds_path, workers=config.workers, resume=ds_path.exists(), progress=False)
    summary = summarize(ds)
    for text in _dataset_table(summary):
        print(text)
    print(f"dataset: {os.fspath(ds_path)} (`probaff describe` prints its full summary)")
    world = load_tabletop()
    tx, ty = world.table_size
    reach = load_arm(world.arm).reachable_mask(
        (-tx / 2, tx / 2), (-ty / 2, ty / 2), resolution=0.04, n_yaws=2
    )
    figure = out / "demo_pushes.png"
    plot_pushes(ds, list(range(min(6, len(ds)))), figure, reachable=reach)
    print(f"figure:  {os.fspath(figure)}")
    return ds, summary, figure


def _dataset_table(summary: dict[str, Any]) -> list[str]:
    """A push dataset's summary as a few lines: one line of counts, a table per object slot.

    Args:
        summary: `probaff.data.summary.summarize_pushes` of the dataset.

    Returns:
        The lines: what was generated, a header and one row per slot (o1 is the pushed
        object) with the fractions moved more than 1 cm, fallen off and touched by the hand
        and the mean exact |effect| along and across the push (cm) and its turn (deg), then
        the objects drawn.
    """
    noise = summary.get("pose_noise")
    seen = (
        "exact poses"
        if not noise
        else f"poses seen with {1000 * noise['position_std_m']:.0f} mm / "
        f"{math.degrees(noise['yaw_std_rad']):.0f} deg noise"
    )
    lines = [
        f"{summary['n_pushes']} pushes of scene {summary['scene']} (seed {summary['seed']}), "
        f"{summary['n_objects_per_scene']} objects each, {seen}",
        f"{'object':6s}  {'moved >1 cm':>11s}  {'fell off':>8s}  {'hand contact':>12s}  "
        f"{'along push':>10s}  {'across':>8s}  {'turn':>8s}",
    ]
    for slot, s in summary["objects"].items():
        e = s["mean_abs_effect"]
        lines.append(
            f"{slot:6s}  {_percent(s['fraction_moved_gt_1cm'], 11)}  "
            f"{_percent(s['fraction_fell_off'], 8)}  {_percent(s['fraction_hand_contact'], 12)}  "
            f"{100 * e['dz_p_m']:7.2f} cm  {100 * e['dy_p_m']:5.2f} cm  "
            f"{math.degrees(e['dtheta_p_rad']):4.1f} deg"
        )
    lines.append("(along, across, turn: mean |effect| of the exact poses, in the push's frame)")
    counts = ", ".join(f"{name} {k}" for name, k in summary["object_counts"].items())
    lines.append(f"objects: {counts}")
    return lines


def _percent(fraction: float | None, width: int) -> str:
    """`fraction` in percent, right-aligned in `width` characters (``n/a`` for ``None``)."""
    return f"{'n/a':>{width}s}" if fraction is None else f"{100 * fraction:{width - 2}.0f} %"


def _summary_lines(result: dict[str, Any]) -> list[str]:
    """The report's last lines: its headline numbers, then the paths of its figures."""
    models = result["models"]
    rmse_o2 = ", ".join(f"{k} {v['rmse_o2_dz_cm']:.2f} cm" for k, v in models.items())
    nlpd_all = ", ".join(  # a stacked point has its mixture's density
        f"{k} {v['nlpd']:.2f}" for k, v in models.items() if not k.endswith(", stacked")
    )
    amap = result["affordance_map"]
    edge = result["planning"]
    chain = [r for r in result["modular"]["chains"] if r["n_objects"] == 3]
    labels = result["point_cloud_labels"]
    rows = [
        ("pushes", f"{result['summary']['n_pushes']} of {result['summary']['scene']}"),
        ("o2 RMSE along push", rmse_o2),
        ("NLPD (6 dims)", nlpd_all),
        (
            "map entropy",
            f"{amap['entropy'][0]:.2f} -> {amap['entropy'][-1]:.2f} nats after "
            f"{len(amap['pushes'])} pushes (MAP accuracy {amap['accuracy'][0]:.3f} -> "
            f"{amap['accuracy'][-1]:.3f}; {len(amap['boxes'])} boxes, {len(amap['walls'])} "
            "wall blocks that look like boxes)",
        ),
        (
            "push to the edge",
            f"{edge['outcome']} after {edge['pushes']} pushes, {edge['replans']} replans",
        ),
        (
            "three-object chain",
            " / ".join(f"{r['error_cm']:.1f}" for r in chain) + " cm error (o1 / o2 / o3)",
        ),
        (
            "office labels",
            f"precision / recall {interval_text(labels['intervals']['thesis'])} % (logistic "
            f"regressions), {interval_text(labels['intervals']['new'])} % (trees)",
        ),
    ]
    return [
        "",
        "summary",
        *(f"  {name:19s} {value}" for name, value in rows),
        "figures",
        *(f"  {path}" for path in result["figures"]),
    ]


def _compare_models(
    ds: PushDataset, seed: int, out: Path, notes: list[str]
) -> tuple[dict[str, dict[str, float]], Path]:
    """Held-out scores of a 3-expert EM mixture and of a single GP, and o2's density figure.

    The mixture is scored twice by RMSE: by its predictive mean and by its mean stacked with
    the single GP (``point="stacked"``, `probaff.models.mixture.point`); the densities are the
    same. Both models see the same pushes, features (gate: f_x; experts: f_o & f_c) and noise
    floor (that of the dataset's pose noise). The figure shows, for the held-out push where
    the mixture's prediction of o2's displacement along the push is most clearly bimodal
    (o2 hit or not hit), both models' predictive densities and what was observed. Each fit's
    `RuntimeWarning`s become one line of `notes`.

    Returns:
        The scores per model and the figure's path.
    """
    features = chapter5_features(ds)
    X = features.values
    Y = ds["effect"][:, :2].reshape(len(ds), 6)
    rng = np.random.default_rng(seed)
    test = rng.permutation(len(ds))[: len(ds) // 3]
    train = np.setdiff1d(np.arange(len(ds)), test)
    y = torch.as_tensor(Y[test])
    floor = PoseNoise().effect_std(2) if ds.has_pose_noise else "auto"
    scores: dict[str, dict[str, float]] = {}
    preds = {}
    with limit_threads(1):
        for name, m in (("single GP", 1), ("mixture M=3", 3)):
            model = MixtureOfGPExperts(
                m,
                groups=features.groups,
                gate_features=("f_x",),
                expert_features=("f_o", "f_c"),
                gp=GPOptions(lengthscale_prior=True, noise_floor=floor),
                point="stacked",
            )
            with _fit_warnings(f"the {name} fit", notes):
                fit_em(model, X[train], Y[train], seed=seed)
            pred = preds[name] = model.predict(X[test])
            # the mixture's mean, and (M > 1) its mean stacked with the single GP
            points = {name: pred.mean}
            if m > 1:
                points[f"{name}, stacked"] = model.predict_point(X[test], mean=pred.mean)
            for label, point in points.items():
                err = rmse(point, y)
                scores[label] = {
                    "rmse_o1_dz_cm": float(100 * err[1]),
                    "rmse_o2_dz_cm": float(100 * err[4]),
                    "nlpd": float(nlpd(pred, y).sum()),
                    "coverage90": float(interval_coverage(pred, y, 0.9).mean()),
                }
    print(
        f"held-out pushes: {len(test)} (trained on {len(train)}); "
        f"pose noise: {'on' if ds.has_pose_noise else 'off'}"
    )
    print(
        f"{'model':23s} {'o1 dz RMSE':>11s} {'o2 dz RMSE':>11s} {'NLPD (6 dims)':>14s} "
        f"{'90% coverage':>13s}"
    )
    for name, s in scores.items():
        print(
            f"{name:23s} {s['rmse_o1_dz_cm']:8.2f} cm {s['rmse_o2_dz_cm']:8.2f} cm "
            f"{s['nlpd']:14.2f} {s['coverage90']:13.2f}"
        )
    figure = _plot_o2_density(preds, Y[test], out / "demo_o2_density.png")
    print(f"o2 density figure: {os.fspath(figure)}")
    return scores, figure


def _plot_o2_density(preds: dict[str, Any], Y: np.ndarray, path: Path) -> Path:
    """Plot o2's dz density at the held-out push where the mixture is most bimodal."""
    mixture = preds["mixture M=3"]
    probs = mixture.mixture_distribution.probs  # (N, M)
    loc = mixture.component_distribution.base_dist.loc[..., 4]  # (N, M), o2 dz
    scale = mixture.component_distribution.base_dist.scale[..., 4]
    spread = (loc.max(1).values - loc.min(1).values) / scale.min(1).values
    weight = 1.0 - probs.max(1).values  # mass away from the most probable expert
    i = int(torch.argmax(spread * weight))
    lo = float(torch.min(loc[i] - 4 * scale[i]).clamp_max(Y[i, 4] - 0.01))
    hi = float(torch.max(loc[i] + 4 * scale[i]).clamp_min(Y[i, 4] + 0.01))
    grid = torch.linspace(lo, hi, 400, dtype=torch.float64)
    densities = {}
    for name, pred in preds.items():
        p = pred.mixture_distribution.probs[i]
        comp = pred.component_distribution.base_dist
        d = Normal(comp.loc[i, :, 4], comp.scale[i, :, 4])
        densities[name] = (p[None, :] * d.log_prob(grid[:, None]).exp()).sum(1).numpy()
    plot_predictive_density(
        100 * grid.numpy(),
        {k: v / 100 for k, v in densities.items()},
        100 * float(Y[i, 4]),
        path,
        xlabel="o2 dz_p (cm)",
        title="o2 along the push, one held-out push: hit or not hit",
    )
    return path
