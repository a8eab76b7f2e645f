"""Chapter 3's study: building affordance maps by pushing, information gain against exhaustive.

`run` trains one `AffordanceClassifier` on generated training maps, then, for each test map
(generated from an independent seed stream, so disjoint from the training maps), explores it
from a random free cell and runs the manipulation loop twice from that same exploration: once
with the information-gain policy on the MRF and once with the exhaustive nearest-box baseline
(`probaff.planning.manipulation_loop`). Each test map is one resumable task (`run_tasks`); its
result lands in ``out/tasks/`` as JSON, keyed by the map index and a fingerprint of every
setting that shapes the results, so a rerun recomputes only missing maps and never mixes
settings. The MRF's settings are one `MRFParams` (``config.mrf``).

A loop that stops early keeps its last state: the curves carry its last values to
``max_steps``. Outputs in ``out/`` (all written atomically): ``entropy.csv`` (per policy and
step: mean and spread of the map entropy, the MRF entropy, the accuracy and the distance),
``summary.md``, and the figures ``entropy_vs_step.png`` (Fig. 3.7), ``accuracy_vs_step.png``,
``distance_vs_step.png``, ``mrf_smoothing.png`` (Fig. 3.5) and ``loop_steps.png`` (Fig. 3.6).

The classifier's precision and recall are measured on the test maps' initial predictions:
every believed box that truly is a box and has a prediction, threshold 0.5. The summary also
gives, per map and under the MRF, the area under the entropy curve with a 95 % interval over
maps, the paired difference of the two policies' areas, and the steps each policy needs to
bring the map entropy down to ``entropy_target`` of its start.

The robot sees with the world file's sensor (``sensor=None``): the head's depth camera of
chapter 2 (`probaff.sim.depth`); ``sensor="scanner"`` gives the idealised range scanner, whose
range noise ``sensor_noise`` sets.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
import warnings
from dataclasses import InitVar, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from probaff._checks import check_count
from probaff._dask import check_scheduler, check_workers
from probaff._io import atomic_write_text
from probaff._threads import torch_threads
from probaff.errors import InputError
from probaff.eval.fingerprint import config_fingerprint
from probaff.eval.map_figures import plot_loop_steps, plot_mrf_smoothing, plot_step_curves
from probaff.eval.metrics import mean_halfwidth
from probaff.eval.tasks import ResultStore, run_tasks
from probaff.grid import DIRECTION_NAMES
from probaff.maps.options import MRFParams
from probaff.perception.exploration import explore
from probaff.planning.classifier import AffordanceClassifier, collect_voxels
from probaff.planning.manipulation_loop import POLICIES, LoopSnapshot, ManipulationLoop
from probaff.sim.config import SENSOR_KINDS, WarehouseSpec, load_warehouse
from probaff.sim.warehouse import WarehouseMap, generate_map, rule_affordances

__all__ = [
    "NOISY_SENSOR",
    "RUN_ONLY",
    "AffordanceMapConfig",
    "demo",
    "map_task",
    "run",
    "train_classifier",
    "world",
]

NOISY_SENSOR = 0.2
"""Range noise (m) of the degraded idealised scanner (``sensor="scanner"``): the world file's
0.01 m makes the classifier almost certain; 0.2 m leaves it unsure of a few boxes per map."""

_SNAPSHOTS = 4  # loop states kept per map for Fig. 3.6
_STREAM_TRAIN, _STREAM_TEST, _STREAM_LOOP = 0, 1, 2  # independent seed streams


@dataclass(frozen=True)
class AffordanceMapConfig:
    """Settings of the affordance-map study.

    Attributes:
        n_maps: Test maps.
        seed: Seed of the training maps, the test maps, the starts and all sensor noise.
        train_maps: Maps the classifier is trained on.
        mrf: The MRF's couplings ``J``, ``J_sym``, ``J_along`` and the reward weight
            ``alpha`` of ``G = alpha R - (1 - alpha) C`` (validated by `MRFParams`). The
            keywords ``alpha``, ``coupling``, ``symmetry_coupling`` and ``along_coupling``
            are accepted by the constructor as shorthands that replace those fields of
            `mrf`, and are readable as properties.
        max_steps: Most pushes per map and policy.
        out: Output folder.
        workers: 0 runs in this process; K > 0 or None uses a local Dask cluster.
        scheduler: Address of an existing Dask scheduler; overrides `workers`.
        progress: Show a progress bar.
        sensor_noise: Range noise (m) of the idealised scanner; None keeps the world file's
            value. Only with ``sensor="scanner"``.
        sensor: The robot's sensor, one of `SENSOR_KINDS`: ``"camera"`` (the head's depth
            camera of chapter 2) or ``"scanner"`` (the idealised range scanner); None keeps
            the world file's (the camera).
        entropy_target: The map entropy to reach, as a share of the map's initial one (both
            under the MRF): the summary counts each policy's steps until its map gets there.
        stop_at_no_gain: Stop the information-gain loop when every ``G < 0`` (the thesis's
            rule); False keeps it pushing to `max_steps`, for a step-by-step comparison.
    """

    n_maps: int = 20
    seed: int = 0
    train_maps: int = 20
    mrf: MRFParams = field(default_factory=MRFParams)
    max_steps: int = 20
    out: str = "results/affordance_map"
    workers: int | None = 0
    scheduler: str | None = None
    progress: bool = True
    sensor_noise: float | None = None
    sensor: str | None = None
    entropy_target: float = 0.5
    stop_at_no_gain: bool = True
    alpha: InitVar[float | None] = None
    coupling: InitVar[float | None] = None
    symmetry_coupling: InitVar[float | None] = None
    along_coupling: InitVar[float | None] = None

    def __post_init__(
        self,
        alpha: float | None,
        coupling: float | None,
        symmetry_coupling: float | None,
        along_coupling: float | None,
    ) -> None:
        """Fold the shorthand MRF keywords into `mrf` (validated there, once)."""
        given = {
            k: v
            for k, v in (
                ("alpha", alpha),
                ("coupling", coupling),
                ("symmetry_coupling", symmetry_coupling),
                ("along_coupling", along_coupling),
            )
            if v is not None
        }
        if not isinstance(self.mrf, MRFParams):
            raise InputError(f"mrf must be an MRFParams, got {type(self.mrf).__name__}.")
        if given:
            object.__setattr__(self, "mrf", dataclasses.replace(self.mrf, **given))

    def validate(self) -> AffordanceMapConfig:
        """Check the settings and return them with their counts as builtin ints.

        Returns:
            An equal config whose ``n_maps``, ``train_maps``, ``max_steps``, ``seed`` and
            ``workers`` are `int` (``numpy.int64(3)`` or ``3.0`` become ``3``), so that its
            fingerprint does not depend on how a count was typed.

        Raises:
            InputError: For a setting out of range.
        """
        n_maps = check_count("n_maps", self.n_maps)
        train_maps = check_count("train_maps", self.train_maps)
        max_steps = check_count("max_steps", self.max_steps, minimum=0)
        seed = check_count("seed", self.seed, minimum=0)
        if self.sensor_noise is not None and not (
            math.isfinite(self.sensor_noise) and self.sensor_noise >= 0
        ):
            raise InputError(f"sensor_noise must be a number >= 0, got {self.sensor_noise!r}.")
        world(self.sensor_noise, self.sensor)  # the sensor's name and noise, checked
        if not (isinstance(self.entropy_target, (int, float)) and 0 < self.entropy_target < 1):
            raise InputError(
                f"entropy_target must be a share in (0, 1) of the initial map entropy, got "
                f"{self.entropy_target!r}."
            )
        workers = check_workers(self.workers)
        check_scheduler(self.scheduler)
        return dataclasses.replace(
            self,
            n_maps=n_maps,
            train_maps=train_maps,
            max_steps=max_steps,
            seed=seed,
            workers=workers,
        )

    def fingerprint(self) -> str:
        """Short hash of every setting that changes a map's result (see `RUN_ONLY`)."""
        return config_fingerprint(self, exclude=RUN_ONLY, version=3)  # 3: carried points, camera


RUN_ONLY = frozenset({"n_maps", "out", "workers", "scheduler", "progress", "entropy_target"})
"""Fields of `AffordanceMapConfig` that do not change any map's result (each map's result is
keyed by its index, so more maps only add results)."""


def _mrf_property(name: str) -> property:
    """A read-only view of ``config.mrf.<name>`` under the old flat field name."""
    return property(
        lambda self: getattr(self.mrf, name), doc=f"Shorthand for ``mrf.{name}`` (see `MRFParams`)."
    )


# The InitVar defaults are class attributes; replace them by views of `mrf` once the
# dataclass machinery has built __init__ (which keeps None as the keywords' default).
for _name in ("alpha", "coupling", "symmetry_coupling", "along_coupling"):
    setattr(AffordanceMapConfig, _name, _mrf_property(_name))
del _name


def world(sensor_noise: float | None = None, sensor: str | None = None) -> WarehouseSpec:
    """The warehouse world, with its sensor and the scanner's range noise replaced if given.

    Args:
        sensor_noise: Range noise (m) of the idealised scanner; None keeps the world file's.
        sensor: One of `SENSOR_KINDS`; None keeps the world file's.

    Raises:
        InputError: For an unknown sensor, or a range noise given for the camera (whose noise
            model lives in ``worlds/camera.yaml``).
    """
    spec = load_warehouse()
    if sensor is not None:
        if sensor not in SENSOR_KINDS:
            raise InputError(f"sensor must be one of {', '.join(SENSOR_KINDS)}, got {sensor!r}.")
        spec = dataclasses.replace(spec, sensor_kind=sensor)
    if sensor_noise is None:
        return spec
    if spec.sensor_kind != "scanner":
        raise InputError(
            "sensor_noise sets the idealised scanner's range noise; pass sensor='scanner' "
            "(--sensor scanner) with it, or leave it out for the camera (worlds/camera.yaml)."
        )
    return dataclasses.replace(spec, sensor_noise=float(sensor_noise))


def train_classifier(
    spec: WarehouseSpec, n_maps: int, seed: int
) -> tuple[AffordanceClassifier, dict[str, Any]]:
    """Train the classifier on generated, explored training maps.

    Args:
        spec: The warehouse world.
        n_maps: Training maps (a positive integer).
        seed: Study seed (an integer >= 0); the training maps come from its own stream.

    Returns:
        The classifier and a description of its training data.

    Raises:
        InputError: If `n_maps` or `seed` is not such an integer.
    """
    n_maps = check_count("n_maps", n_maps)
    seed = check_count("seed", seed, minimum=0)
    data = collect_voxels(spec, n_maps, np.random.default_rng((seed, _STREAM_TRAIN)))
    model = AffordanceClassifier().fit(data.features, data.labels)
    info = {
        "maps": n_maps,
        "voxels": len(data.features),
        "boxes": data.n_boxes,
        "unseen_boxes": data.unseen_boxes,
        "positives": data.labels.sum(0).tolist(),
    }
    return model, info


def _grid_json(values: np.ndarray) -> list[Any]:
    """Nested lists of an array, NaN as None, floats rounded to 6 decimals."""
    arr = np.asarray(values, dtype=float)
    out = np.round(arr, 6).astype(object)
    out[np.isnan(arr)] = None
    return out.tolist()


def _confusion(unary: np.ndarray, believed: np.ndarray, m: WarehouseMap) -> dict[str, list[int]]:
    """Per-direction counts of the initial predictions on believed boxes that truly are boxes."""
    cells = believed & m.occupancy & np.isfinite(unary).all(-1)
    pred = unary[cells] >= 0.5
    truth = rule_affordances(m)[cells]
    return {
        "tp": (pred & truth).sum(0).tolist(),
        "fp": (pred & ~truth).sum(0).tolist(),
        "fn": (~pred & truth).sum(0).tolist(),
        "tn": (~pred & ~truth).sum(0).tolist(),
    }


def _snapshot_json(shot: LoopSnapshot) -> dict[str, Any]:
    return {
        "occupancy": np.asarray(shot.occupancy, dtype=bool).tolist(),
        "pushability": _grid_json(shot.pushability),
        "robot": list(shot.robot),
        "push": None if shot.push is None else list(shot.push),
        "entropy": shot.entropy,
    }


def map_task(
    spec: WarehouseSpec, classifier: AffordanceClassifier, index: int, settings: dict[str, Any]
) -> dict[str, Any]:
    """Explore one test map and run both policies on it.

    Args:
        spec: The warehouse world.
        classifier: The trained classifier.
        index: Test map index (an integer >= 0).
        settings: ``seed``, ``max_steps``, ``stop_at_no_gain`` and the `MRFParams` fields
            (``alpha``, ``coupling``, ``symmetry_coupling``, ``along_coupling``) flat, so that
            the task's arguments stay JSON-like; a missing or None field keeps its default.

    Returns:
        A JSON-ready result: the map, its exploration, the classifier's confusion counts, each
        policy's steps and stop reason, and the data of the figures.

    Raises:
        InputError: If `index`, ``settings["seed"]`` or ``settings["max_steps"]`` is not an
            integer >= 0.
    """
    index = check_count("index", index, minimum=0)
    seed = check_count("seed", settings["seed"], minimum=0)
    max_steps = check_count("max_steps", settings["max_steps"], minimum=0)
    mrf_params = MRFParams(
        **{
            f.name: settings[f.name]
            for f in dataclasses.fields(MRFParams)
            if settings.get(f.name) is not None
        }
    )
    with torch_threads(1):  # one core per task, and reproducible reductions
        t0 = time.perf_counter()
        rng = np.random.default_rng((seed, _STREAM_TEST, index))
        m = generate_map(spec, rng)
        free = np.argwhere(~m.occupancy)
        start = free[rng.integers(len(free))]
        run_ex = explore(spec, m, start, rng)
        out: dict[str, Any] = {
            "index": index,
            "boxes": m.boxes.tolist(),
            "shape": list(m.shape),
            "start": start.tolist(),
            "scans": len(run_ex.cells),
            "exploration_length": run_ex.path_length,
            "policies": {},
        }
        for k, policy in enumerate(POLICIES):
            loop = ManipulationLoop(
                spec,
                m,
                run_ex,
                classifier,
                policy=policy,
                mrf=mrf_params,
                rng=np.random.default_rng((seed, _STREAM_LOOP, index, k)),
                stop_at_no_gain=settings["stop_at_no_gain"],
            )
            if policy == "information_gain":
                mrf = loop.graphs()[1]
                out["classifier"] = _confusion(loop.unary, loop.believed, m)
                out["figure"] = {
                    "occupancy": loop.believed.tolist(),
                    "unary": _grid_json(
                        np.where(loop.believed[..., None], loop.unary_probabilities(), np.nan)
                    ),
                    "mrf": _grid_json(mrf.to_map(loop.marginals(mrf)[:, 1]).numpy()),
                }
            result = loop.run(
                max_steps, snapshots=_SNAPSHOTS if policy == "information_gain" else 0
            )
            out["policies"][policy] = {
                "steps": [s.to_dict() for s in result.steps],
                "stop": result.stop,
            }
            if policy == "information_gain":
                out["figure"]["snapshots"] = [_snapshot_json(s) for s in result.snapshots]
        out["seconds"] = time.perf_counter() - t0
        return out


def _curves(results: list[dict[str, Any]], policy: str, key: str, steps: int) -> np.ndarray:
    """(n_maps, steps + 1) values of `key`, each map's last value carried to the end."""
    out = np.full((len(results), steps + 1), np.nan)
    for i, res in enumerate(results):
        values = [
            np.nan if s[key] is None else float(s[key]) for s in res["policies"][policy]["steps"]
        ]
        out[i, : len(values)] = values
        out[i, len(values) :] = values[-1]
    return out


def _nan_stats(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-step mean and standard deviation over maps, skipping NaN (all-NaN gives NaN)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmean(v, 0), np.nanstd(v, 0)


def _precision_recall(results: list[dict[str, Any]]) -> tuple[np.ndarray, np.ndarray]:
    tp = np.sum([r["classifier"]["tp"] for r in results], 0).astype(float)
    fp = np.sum([r["classifier"]["fp"] for r in results], 0).astype(float)
    fn = np.sum([r["classifier"]["fn"] for r in results], 0).astype(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(tp + fp > 0, tp / (tp + fp), 0.0), np.where(
            tp + fn > 0, tp / (tp + fn), 0.0
        )


def _figure_map(results: list[dict[str, Any]]) -> dict[str, Any]:
    """The map drawn in Figs. 3.5 and 3.6: the first with the most information-gain pushes."""
    pushes = [len(r["policies"]["information_gain"]["steps"]) for r in results]
    return results[int(np.argmax(pushes))]


def _write_figures(
    results: list[dict[str, Any]], curves: dict[str, dict[str, np.ndarray]], out: Path
) -> dict[str, str]:
    files = {}
    for key, ylabel, name in (
        ("entropy", "average map entropy (nats)", "entropy_vs_step.png"),
        ("accuracy", "map accuracy (MAP estimate)", "accuracy_vs_step.png"),
        ("distance", "distance travelled (cells)", "distance_vs_step.png"),
    ):
        title = f"{ylabel} over {len(results)} maps (mean, band: 1 std)"
        plot_step_curves({p: curves[p][key] for p in POLICIES}, ylabel, title, out / name)
        files[key] = os.fspath(out / name)
    chosen = _figure_map(results)
    fig = chosen["figure"]
    occ = np.array(fig["occupancy"], dtype=bool)
    unary = np.array(fig["unary"], dtype=float)
    mrf = np.array(fig["mrf"], dtype=float)
    direction = int(np.nanargmax(np.nansum(np.abs(mrf - unary), (0, 1))))  # most smoothed
    plot_mrf_smoothing(occ, unary, mrf, direction, out / "mrf_smoothing.png")
    files["mrf_smoothing"] = os.fspath(out / "mrf_smoothing.png")
    shots = [
        LoopSnapshot(
            occupancy=np.array(s["occupancy"], dtype=bool),
            pushability=np.array(s["pushability"], dtype=float),
            robot=(int(s["robot"][0]), int(s["robot"][1])),
            push=None if s["push"] is None else tuple(s["push"]),
            entropy=float(s["entropy"]),
        )
        for s in fig["snapshots"]
    ]
    plot_loop_steps(
        shots, out / "loop_steps.png", title=f"information-gain loop on test map {chosen['index']}"
    )
    files["loop_steps"] = os.fspath(out / "loop_steps.png")
    return files


def _auc(curve: np.ndarray) -> float:
    """Area under a per-step curve (trapezoid rule, one unit per step)."""
    c = np.asarray(curve, dtype=float)
    return float(np.sum(0.5 * (c[1:] + c[:-1]))) if c.size > 1 else float(c.sum())


def _steps_to(curve: np.ndarray, target: float) -> float:
    """First step at which a map's curve falls to `target` times its start; NaN if never."""
    reached = np.flatnonzero(curve <= target * curve[0])
    return float(reached[0]) if reached.size and curve[0] > 0 else math.nan


def _mean_ci(values: list[float]) -> tuple[float | None, float | None]:
    """Mean and 95 % Student-t half-width of the finite values (None when there are none)."""
    v = [x for x in values if math.isfinite(x)]
    if not v:
        return None, None
    return float(np.mean(v)), (mean_halfwidth(v) if len(v) > 1 else None)


def _summarise(
    config: AffordanceMapConfig, results: list[dict[str, Any]], training: dict[str, Any] | None
) -> tuple[dict[str, Any], str, dict[str, dict[str, np.ndarray]]]:
    """The summary numbers, the CSV text and the per-map curves of every policy."""
    steps = config.max_steps
    curves = {
        p: {
            k: _curves(results, p, k, steps)
            for k in ("entropy", "entropy_mrf", "accuracy", "distance")
        }
        for p in POLICIES
    }
    precision, recall = _precision_recall(results)
    csv = [
        "policy,step,entropy_mean,entropy_std,entropy_mrf_mean,entropy_mrf_std,"
        "accuracy_mean,accuracy_std,distance_mean,distance_std,active_maps"
    ]
    means: dict[str, dict[str, np.ndarray]] = {}
    for p in POLICIES:
        stats = {k: _nan_stats(v) for k, v in curves[p].items()}
        means[p] = {k: s[0] for k, s in stats.items()}
        active = np.array(
            [[len(r["policies"][p]["steps"]) > t for t in range(steps + 1)] for r in results]
        ).sum(0)
        for t in range(steps + 1):
            row = [p, str(t)]
            for k in ("entropy", "entropy_mrf", "accuracy", "distance"):
                row += [f"{stats[k][0][t]:.6f}", f"{stats[k][1][t]:.6f}"]
            csv.append(",".join([*row, str(int(active[t]))]))
    summary: dict[str, Any] = {
        "maps": len(results),
        "classifier": {
            "precision": precision.tolist(),
            "recall": recall.tolist(),
            "training": training,
        },
        "policies": {},
    }
    for p in POLICIES:
        pushes = [s for r in results for s in r["policies"][p]["steps"][1:]]
        real = [s for s in pushes if s["real_box"]]
        summary["policies"][p] = {
            "entropy": means[p]["entropy"].tolist(),
            "entropy_mrf": means[p]["entropy_mrf"].tolist(),
            "accuracy": means[p]["accuracy"].tolist(),
            "distance": means[p]["distance"].tolist(),
            "entropy_auc": _auc(means[p]["entropy"]),
            "entropy_mrf_auc": _auc(means[p]["entropy_mrf"]),
            "pushes_per_map": len(pushes) / len(results),
            "moved_share": (sum(bool(s["moved"]) for s in real) / len(real)) if real else None,
            "detection_agreement": (sum(s["moved"] == s["observed"] for s in real) / len(real))
            if real
            else None,
            "phantom_pushes": len(pushes) - len(real),
            "stops": {
                reason: sum(r["policies"][p]["stop"] == reason for r in results)
                for reason in ("no_gain", "no_candidate", "max_steps")
            },
        }
    per_map_auc = {p: [_auc(c) for c in curves[p]["entropy_mrf"]] for p in POLICIES}
    for p in POLICIES:
        reach = [_steps_to(c, config.entropy_target) for c in curves[p]["entropy_mrf"]]
        _, auc_ci = _mean_ci(per_map_auc[p])  # the mean is the AUC of the mean curve
        steps_mean, steps_ci = _mean_ci(reach)
        summary["policies"][p].update(
            {
                "entropy_mrf_auc_ci": auc_ci,
                "steps_to_target": steps_mean,
                "steps_to_target_ci": steps_ci,
                "reached_target": int(sum(math.isfinite(x) for x in reach)),
            }
        )
    diff = [a - b for a, b in zip(*(per_map_auc[p] for p in POLICIES), strict=True)]
    summary["auc_difference"] = dict(zip(("mean", "ci"), _mean_ci(diff), strict=True))
    summary["task_seconds"] = float(sum(r["seconds"] for r in results))
    return summary, "\n".join(csv) + "\n", curves


def _fmt(v: Any, digits: int = 3) -> str:
    return "n/a" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.{digits}f}"


def _markdown(
    config: AffordanceMapConfig, spec: WarehouseSpec, s: dict[str, Any], steps: int
) -> str:
    ig, ex = s["policies"]["information_gain"], s["policies"]["exhaustive"]
    noise = (
        f"the head camera ({spec.camera_pans} views of {spec.camera.width} x "
        f"{spec.camera.height} pixels per scan, worlds/camera.yaml's noise model)"
        if spec.camera is not None and spec.sensor_kind == "camera"
        else f"the idealised scanner, range noise {spec.sensor_noise} m"
    )
    mrf = config.mrf
    lines = [
        "# Affordance map by interactive manipulation (chapter 3)",
        "",
        f"{s['maps']} test maps, classifier trained on {config.train_maps} other maps, seed "
        f"{config.seed}; alpha = {mrf.alpha}, J = {mrf.coupling}, J_along = "
        f"{mrf.along_coupling if mrf.along_coupling is not None else mrf.coupling}, "
        "J_sym = "
        f"{mrf.symmetry_coupling}, at most {config.max_steps} pushes; sensor: {noise}; "
        + (
            "the information-gain loop stops when every G < 0."
            if config.stop_at_no_gain
            else "the information-gain loop keeps pushing its best candidate even when G < 0."
        ),
        "Entropies are whole-map sums of marginal entropies (nats). The information-gain policy "
        "is scored on the MRF; the exhaustive baseline on independent unaries (coupling 0); "
        "'H (MRF)' scores both on the MRF. A loop that stopped keeps its last state.",
        "",
        "## Classifier (initial predictions on the test maps' boxes, threshold 0.5)",
        "",
        "| direction | precision | recall |",
        "|---|---|---|",
    ]
    for k, name in enumerate(DIRECTION_NAMES):
        lines.append(
            f"| {name} | {100 * s['classifier']['precision'][k]:.1f} | "
            f"{100 * s['classifier']['recall'][k]:.1f} |"
        )
    lines += [
        "",
        "## Summary",
        "",
        "| policy | H step 0 | H final | AUC H | AUC H (MRF) | accuracy 0 | accuracy final | "
        "distance | pushes/map | moved | detection agrees | stops (no gain / none / max) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for p, d in (("information gain", ig), ("exhaustive", ex)):
        st = d["stops"]
        lines.append(
            f"| {p} | {_fmt(d['entropy'][0])} | {_fmt(d['entropy'][-1])} | "
            f"{_fmt(d['entropy_auc'], 2)} | {_fmt(d['entropy_mrf_auc'], 2)} | "
            f"{_fmt(d['accuracy'][0])} | {_fmt(d['accuracy'][-1])} | {_fmt(d['distance'][-1], 1)}"
            f" | {_fmt(d['pushes_per_map'], 1)} | {_fmt(d['moved_share'], 2)} | "
            f"{_fmt(d['detection_agreement'], 3)} | {st['no_gain']} / {st['no_candidate']} / "
            f"{st['max_steps']} |"
        )
    diff = s["auc_difference"]
    lines += [
        "",
        f"Per map, under the MRF (± 95 % Student-t half-width over maps): area under the "
        f"entropy curve and steps until the map entropy falls to {config.entropy_target:g} "
        "of its start (over the maps that got there).",
        "",
        "| policy | AUC H (MRF) | steps to target | maps reaching it |",
        "|---|---|---|---|",
    ]
    for p, d in (("information gain", ig), ("exhaustive", ex)):
        lines.append(
            f"| {p} | {_fmt(d['entropy_mrf_auc'], 2)} ± {_fmt(d['entropy_mrf_auc_ci'], 2)} | "
            f"{_fmt(d['steps_to_target'], 1)} ± {_fmt(d['steps_to_target_ci'], 1)} | "
            f"{d['reached_target']} / {s['maps']} |"
        )
    lines += [
        "",
        f"AUC H (MRF), information gain minus exhaustive, paired by map: "
        f"{_fmt(diff['mean'], 2)} ± {_fmt(diff['ci'], 2)}.",
        "",
        "## Per step (means over maps)",
        "",
        "| step | H info gain | H exhaustive | H (MRF) info gain | H (MRF) exhaustive | "
        "acc info gain | acc exhaustive | dist info gain | dist exhaustive |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for t in range(steps + 1):
        lines.append(
            f"| {t} | {_fmt(ig['entropy'][t])} | {_fmt(ex['entropy'][t])} | "
            f"{_fmt(ig['entropy_mrf'][t])} | {_fmt(ex['entropy_mrf'][t])} | "
            f"{_fmt(ig['accuracy'][t])} | {_fmt(ex['accuracy'][t])} | "
            f"{_fmt(ig['distance'][t], 1)} | {_fmt(ex['distance'][t], 1)} |"
        )
    lines += ["", f"Task time (sum over maps): {s['task_seconds']:.1f} s."]
    if "runtime_s" in s:
        lines.append(f"Wall time of this run: {s['runtime_s']:.1f} s.")
    return "\n".join(lines) + "\n"


def run(config: AffordanceMapConfig) -> dict[str, Any]:
    """Run the study (resumably) and write its tables and figures.

    Args:
        config: Study settings.

    Returns:
        ``{"summary": ..., "files": {name: path}, "computed": maps computed by this call}``.

    Raises:
        InputError: For settings out of range.
    """
    config = config.validate()
    t0 = time.perf_counter()
    out = Path(config.out)
    store = ResultStore(out / "tasks")
    fp = config.fingerprint()
    keys = [f"map-{i:03d}-{fp}" for i in range(config.n_maps)]
    missing = sum(not store.done(k) for k in keys)
    spec = world(config.sensor_noise, config.sensor)
    train_key = f"classifier-{fp}"
    classifier = None
    if missing:
        classifier, trained = train_classifier(spec, config.train_maps, config.seed)
        store.save(train_key, trained)
    training = store.load(train_key) if store.done(train_key) else None
    mrf = config.mrf
    settings = {
        "seed": config.seed,
        "alpha": mrf.alpha,
        "coupling": mrf.coupling,
        "symmetry_coupling": mrf.symmetry_coupling,
        "along_coupling": mrf.along_coupling,
        "max_steps": config.max_steps,
        "stop_at_no_gain": config.stop_at_no_gain,
    }
    results = run_tasks(
        map_task,
        [(k, (spec, classifier, i, settings)) for i, k in enumerate(keys)],
        store,
        workers=config.workers,
        scheduler=config.scheduler,
        progress=config.progress,
        desc="affordance maps",
    )
    summary, csv, curves = _summarise(config, results, training)
    files = {
        "entropy_csv": os.fspath(out / "entropy.csv"),
        "summary": os.fspath(out / "summary.md"),
    }
    atomic_write_text(out / "entropy.csv", csv)
    files.update(_write_figures(results, curves, out))
    summary["runtime_s"] = time.perf_counter() - t0
    atomic_write_text(out / "summary.md", _markdown(config, spec, summary, config.max_steps))
    return {"summary": summary, "files": files, "computed": missing}


def demo(
    out_dir: str | os.PathLike[str],
    seed: int = 0,
    steps: int = 4,
    train_maps: int = 2,
    sensor: str | None = None,
) -> dict[str, Any]:
    """Explore one small map, push boxes by information gain, and report the entropy per step.

    The map is 8 x 8 cells with 8 to 14 boxes, seen by the world file's sensor (the head
    camera). The classifier is trained on only `train_maps` other maps of that size, so that
    some of its predictions are unsure: that is what the loop's pushes are for. The loop
    pushes its best candidate `steps` times even when no push is worth its travel (the study's
    ``stop_at_no_gain=False``), so that each step's effect on the map entropy shows; a push
    that moves a box gives the box fresh, unsure variables in its new cell.

    Args:
        out_dir: Folder of the figure ``loop_steps.png`` (created).
        seed: Seed of the maps and the sensor noise (an integer >= 0).
        steps: Pushes (an integer >= 0).
        train_maps: Maps the classifier is trained on (a positive integer).
        sensor: One of `SENSOR_KINDS`; None keeps the world file's.

    Returns:
        ``{"entropy", "accuracy", "pushes", "moved", "stop", "figure"}``: the map entropy
        (nats) and the MAP accuracy at each step (``steps + 1`` values), the pushes
        ``[row, col, direction]``, whether each moved its box, and the stop reason.

    Raises:
        InputError: If `seed` or `steps` is not an integer >= 0, `train_maps` not a positive
            integer, or `sensor` unknown.
    """
    seed = check_count("seed", seed, minimum=0)
    steps = check_count("steps", steps, minimum=0)
    train_maps = check_count("train_maps", train_maps)
    spec = dataclasses.replace(world(sensor=sensor), rows=8, cols=8, boxes=(8, 14))
    classifier, _ = train_classifier(spec, train_maps, seed)
    rng = np.random.default_rng((seed, _STREAM_TEST, 0))
    m = generate_map(spec, rng)
    free = np.argwhere(~m.occupancy)
    exploration = explore(spec, m, free[rng.integers(len(free))], rng)
    loop = ManipulationLoop(
        spec,
        m,
        exploration,
        classifier,
        rng=np.random.default_rng((seed, _STREAM_LOOP, 0)),
        stop_at_no_gain=False,
    )
    result = loop.run(steps, snapshots=steps + 1)
    figure = Path(out_dir) / "loop_steps.png"
    plot_loop_steps(result.snapshots, figure, title="information-gain loop on a small map")
    entropy = [s.entropy for s in result.steps]
    accuracy = [s.accuracy for s in result.steps]
    done = [s for s in result.steps[1:] if s.push is not None]
    pushes = [list(s.push) for s in done if s.push is not None]
    moved = [bool(s.moved) for s in done]
    trail = " -> ".join(f"{h:.2f}" for h in entropy)
    print(
        f"map entropy by step (nats, classifier trained on {train_maps} maps): {trail}; "
        f"{len(pushes)} push(es), {sum(moved)} moved a box (stop: {result.stop})"
    )
    print(f"MAP accuracy: {accuracy[0]:.3f} -> {accuracy[-1]:.3f}; figure: {os.fspath(figure)}")
    return {
        "entropy": entropy,
        "accuracy": accuracy,
        "pushes": pushes,
        "moved": moved,
        "stop": result.stop,
        "figure": os.fspath(figure),
    }
