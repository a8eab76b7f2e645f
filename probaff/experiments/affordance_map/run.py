"""Chapter 3's study: building affordance maps by pushing, information gain against exhaustive.

`run` trains one `AffordanceClassifier` on generated training maps, then, for each test map
(generated from an independent seed stream, so disjoint from the training maps), explores it
from a random free cell and runs the manipulation loop twice from that same exploration: once
with the information-gain policy on the MRF and once with the exhaustive nearest-box baseline
(`probaff.planning.ManipulationLoop`). Each test map is one resumable task (`run_tasks`); its
result lands in ``out/tasks/`` as JSON, keyed by the map index and a fingerprint of every
setting that shapes the results, so a rerun recomputes only missing maps and never mixes
settings. The MRF's settings are one `MRFParams` (``config.mrf``).

The MRF is the thesis's (``config.mrf`` defaults to
`probaff.experiments.affordance_map.config.STUDY_MRF`): Ising ties between the
same direction of neighbouring boxes plus the up/down and left/right symmetry pairs.

A loop that stops early keeps its last state: the curves carry its last values to
``max_steps``. Outputs in ``out/`` (all written atomically): ``entropy.csv`` (per policy and
step: mean and spread of the map entropy, the MRF entropy, the accuracy and the distance),
``fig_3_7.csv`` (Fig. 3.7's table, see `probaff.experiments.affordance_map.report.fig_3_7`),
``summary.md``, and the figures ``fig_3_7.png`` (Fig. 3.7: mean map entropy at steps 1-19 with
95 % intervals, each loop's stop step, the paired difference where both loops push),
``entropy_vs_step.png``, ``entropy_mrf_vs_step.png``, ``accuracy_vs_step.png``,
``distance_vs_step.png`` (means with one standard deviation), ``auc_difference.png``,
``mrf_smoothing.png`` (Fig. 3.5) and ``loop_steps.png`` (Fig. 3.6).

The classifier's precision and recall are measured on the test maps' initial predictions:
every believed box that truly is a box and has a prediction, threshold 0.5. Fig. 3.7's
verdict ("the information-gain loop's entropy falls faster") is judged only on the steps where
both loops still push. The summary also gives, per map and under the MRF, the area under the
entropy curve to ``max_steps`` with a 95 % interval over maps (labelled with the flat tail
it carries after a stop: not a rate), the paired difference of the two policies' areas, and
the steps each policy needs to bring the map entropy down to ``entropy_target`` of its
start.

The robot sees with the world file's sensor (``sensor=None``): the head's depth camera of
chapter 2 (`probaff.sim.depth`); ``sensor="scanner"`` gives the idealised range scanner, whose
range noise ``sensor_noise`` sets.
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any

import numpy as np

from probaff._checks import check_count
from probaff._threads import limit_threads
from probaff.eval.tasks import ResultStore
from probaff.experiments.affordance_map.config import AffordanceMapConfig, world
from probaff.experiments.affordance_map.figures import study_figures
from probaff.experiments.affordance_map.report import fig_3_7_csv, markdown, summarise
from probaff.experiments.base import StudyRun
from probaff.maps.options import MRFParams
from probaff.perception.exploration import explore
from probaff.planning import POLICIES, AffordanceClassifier, ManipulationLoop, collect_voxels
from probaff.planning.manipulation.loop import LoopSnapshot
from probaff.sim import WarehouseMap, WarehouseSpec, generate_map
from probaff.sim.warehouse import rule_affordances

__all__ = ["STREAM_LOOP", "STREAM_TEST", "map_task", "run", "train_classifier"]

_SNAPSHOTS = 4  # loop states kept per map for Fig. 3.6
_STREAM_TRAIN = 0
STREAM_TEST, STREAM_LOOP = 1, 2
"""Independent seed streams of the test maps and of the loops (the training maps' is 0)."""


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
    with limit_threads(1):  # one core per task, and reproducible reductions
        t0 = time.perf_counter()
        rng = np.random.default_rng((seed, STREAM_TEST, index))
        m = generate_map(spec, rng)
        free = np.argwhere(~m.occupancy)
        start = free[rng.integers(len(free))]
        run_ex = explore(spec, m, start, rng)
        out: dict[str, Any] = {
            "index": index,
            "boxes": m.boxes.tolist(),
            "walls": np.argwhere(m.walls).tolist(),
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
                rng=np.random.default_rng((seed, STREAM_LOOP, index, k)),
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


def run(config: AffordanceMapConfig) -> dict[str, Any]:
    """Run the study (resumably) and write its tables and figures.

    Args:
        config: Study settings.

    Returns:
        ``{"summary": ..., "files": {name: path}, "computed": maps computed by this call}``.

    Raises:
        InputError: For settings out of range.
    """
    study = StudyRun(config, AffordanceMapConfig)
    config = study.config
    t0 = time.perf_counter()
    store = ResultStore(study.out / "tasks")
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
    settings = {
        "seed": config.seed,
        **{f.name: getattr(config.mrf, f.name) for f in dataclasses.fields(MRFParams)},
        "max_steps": config.max_steps,
        "stop_at_no_gain": config.stop_at_no_gain,
    }
    results = study.tasks(
        map_task,
        [(k, (spec, classifier, i, settings)) for i, k in enumerate(keys)],
        desc="affordance maps",
    )
    summary, csv, curves = summarise(config, results, training)
    entropy_csv = study.write("entropy.csv", csv)
    fig_csv = study.write("fig_3_7.csv", fig_3_7_csv(summary["fig_3_7"]))
    figures = study_figures(
        results, curves, study.out, summary["auc_difference"], summary["fig_3_7"]
    )
    summary["runtime_s"] = time.perf_counter() - t0
    text = markdown(config, spec, summary, config.max_steps)
    files = {
        "entropy_csv": entropy_csv,
        "fig_3_7_csv": fig_csv,
        "summary": study.write("summary.md", text),
        **figures,
    }
    return {"summary": summary, "files": files, "computed": missing}
