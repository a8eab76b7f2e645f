"""Every count argument is checked the same way: integers only, no booleans, no fractions."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml
from torch.distributions import Normal

from probaff._dask import check_workers
from probaff._threads import limit_threads
from probaff.data import GenerateConfig, generate
from probaff.errors import ConfigError, InputError
from probaff.eval.metrics import interval_coverage
from probaff.eval.selection import select_n_experts
from probaff.experiments.affordance_map import AffordanceMapConfig, train_classifier
from probaff.experiments.affordance_map.demo import demo
from probaff.experiments.affordance_map.run import map_task
from probaff.features.cells import cell_features
from probaff.features.ch4 import chapter4_features
from probaff.maps.bp import loopy_belief_propagation
from probaff.maps.components import component_labels
from probaff.maps.evidence import make_evidence, single_variable_evidence
from probaff.maps.exact import component_widths, elimination_width, exact_marginals
from probaff.maps.graph import AffordanceGraph
from probaff.maps.grid_bp import grid_belief_propagation
from probaff.maps.inference import affordance_marginals
from probaff.perception.occupancy import OccupancyGrid
from probaff.planning.manipulation.classifier import AffordanceClassifier, collect_voxels, evaluate
from probaff.sim import load_catalogue, load_tabletop, load_warehouse
from probaff.sim.arm import load_arm
from probaff.sim.geometry import friction_points
from probaff.sim.runner import PushSimulator
from probaff.sim.sensing import object_cloud, scan_scene
from probaff.sim.tabletop import SceneInstance
from probaff.sim.warehouse import WarehouseMap, generate_map, push_box
from probaff.sim.world_files import worlds_dir

BAD = [0.5, True, -1]
CFG = GenerateConfig(scene="two_objects", n=2, seed=0, shard_size=2, cloud_points=8)
SPEC = load_warehouse()
GRAPH = AffordanceGraph(np.ones((2, 2), dtype=bool), np.full((2, 2, 4), 0.5))
BOOK = load_catalogue()["book"]


def _gen(tmp: Path, **kw):
    generate(dataclasses.replace(CFG, **kw), tmp / "ds", workers=0, progress=False)


def _threads(v):
    with limit_threads(v):
        pass


def _bp(v):
    loopy_belief_propagation(
        torch.zeros(2, 2), torch.tensor([[0, 1]]), torch.zeros(1, 2, 2), max_iterations=v
    )


def _coverage(v):
    interval_coverage(Normal(torch.zeros(4, 1), torch.ones(4, 1)), torch.zeros(4, 1), iterations=v)


def _select(**kw):
    x, y = torch.randn(12, 2), torch.randn(12, 1)
    select_n_experts(x, y, **{"candidates": (1,), **kw})


def _map_task(**kw):
    settings = {"seed": 0, "max_steps": 1, **kw.pop("settings", {})}
    map_task(SPEC, AffordanceClassifier(), kw.get("index", 0), settings)


WRITES = ("generate.", "affordance_map.demo.")  # entry points that take an output folder
ENTRY_POINTS = {
    "limit_threads.n": _threads,
    "check_workers": check_workers,
    "generate.n": lambda v, tmp: _gen(tmp, n=v),
    "generate.seed": lambda v, tmp: _gen(tmp, seed=v),
    "generate.shard_size": lambda v, tmp: _gen(tmp, shard_size=v),
    "generate.cloud_points": lambda v, tmp: _gen(tmp, cloud_points=v),
    "generate.workers": lambda v, tmp: generate(CFG, tmp / "ds", workers=v, progress=False),
    "AffordanceClassifier.max_iter": lambda v: AffordanceClassifier(max_iter=v),
    "collect_voxels.n_maps": lambda v: collect_voxels(SPEC, v, np.random.default_rng(0)),
    "evaluate.n_maps": lambda v: evaluate(n_maps=v),
    "evaluate.folds": lambda v: evaluate(folds=v),
    "evaluate.seed": lambda v: evaluate(seed=v),
    "cell_features.n_layers": lambda v: cell_features(
        np.zeros((0, 3)), OccupancyGrid((2, 2)), n_layers=v
    ),
    "cell_features.min_points": lambda v: cell_features(
        np.zeros((0, 3)), OccupancyGrid((2, 2)), min_points=v
    ),
    "chapter4_features.chunk": lambda v: chapter4_features(None, chunk=v),
    "OccupancyGrid.shape": lambda v: OccupancyGrid((v, 3)),
    "loopy_belief_propagation.max_iterations": _bp,
    "grid_belief_propagation.max_iterations": lambda v: grid_belief_propagation(
        torch.zeros(2, 2, 2), 0.4, max_iterations=v
    ),
    "affordance_marginals.max_iterations": lambda v: affordance_marginals(GRAPH, max_iterations=v),
    "affordance_marginals.max_exact_width": lambda v: affordance_marginals(
        GRAPH, max_exact_width=v
    ),
    "exact_marginals.max_width": lambda v: exact_marginals(GRAPH, max_width=v),
    "component_widths.limit": lambda v: component_widths(GRAPH, limit=v),
    "elimination_width.num_variables": lambda v: elimination_width(v, np.zeros((0, 2))),
    "component_labels.num_nodes": lambda v: component_labels(v, np.zeros((0, 2))),
    "make_evidence.num_variables": lambda v: make_evidence(v, []),
    "single_variable_evidence.num_variables": lambda v: single_variable_evidence(v),
    "interval_coverage.iterations": _coverage,
    "select_n_experts.folds": lambda v: _select(folds=v),
    "select_n_experts.seed": lambda v: _select(seed=v),
    "select_n_experts.candidates": lambda v: _select(candidates=(v,)),
    "friction_points.n": lambda v: friction_points(BOOK, v),
    "SceneInstance.nominal.friction_grid": lambda v: SceneInstance.nominal(
        [BOOK], np.zeros(3), np.zeros(2), 0.0, 0.1, friction_grid=v
    ),
    "object_cloud.n_points": lambda v: object_cloud(
        BOOK, np.zeros(3), v, 0.0, np.random.default_rng(0)
    ),
    "scan_scene.n_points": lambda v: scan_scene(
        (BOOK,), np.zeros((1, 3)), (1.0, 0.8), np.random.default_rng(0), n_points=v
    ),
    "Arm.reachable_mask.n_yaws": lambda v: load_arm(load_tabletop().arm).reachable_mask(
        (0.0, 0.1), (0.0, 0.1), n_yaws=v
    ),
    "generate_map.shape": lambda v: generate_map(SPEC, np.random.default_rng(0), shape=(v, 4)),
    "generate_map.n_boxes": lambda v: generate_map(SPEC, np.random.default_rng(0), n_boxes=(v, 2)),
    "push_box.neighbourhood": lambda v: push_box(
        SPEC, WarehouseMap.from_boxes((3, 3), [(1, 1)]), (1, 1), 0, neighbourhood=v
    ),
    "AffordanceMapConfig.n_maps": lambda v: AffordanceMapConfig(n_maps=v).validate(),
    "AffordanceMapConfig.train_maps": lambda v: AffordanceMapConfig(train_maps=v).validate(),
    "AffordanceMapConfig.max_steps": lambda v: AffordanceMapConfig(max_steps=v).validate(),
    "AffordanceMapConfig.seed": lambda v: AffordanceMapConfig(seed=v).validate(),
    "AffordanceMapConfig.workers": lambda v: AffordanceMapConfig(workers=v).validate(),
    "train_classifier.n_maps": lambda v: train_classifier(SPEC, v, 0),
    "train_classifier.seed": lambda v: train_classifier(SPEC, 1, v),
    "map_task.index": lambda v: _map_task(index=v),
    "map_task.seed": lambda v: _map_task(settings={"seed": v}),
    "map_task.max_steps": lambda v: _map_task(settings={"max_steps": v}),
    "affordance_map.demo.steps": lambda v, tmp: demo(tmp, steps=v),
    "affordance_map.demo.seed": lambda v, tmp: demo(tmp, seed=v),
}


@pytest.fixture(scope="module")
def simulator():
    return PushSimulator("two_objects")


@pytest.mark.parametrize("value", BAD, ids=repr)
@pytest.mark.parametrize("name", sorted(ENTRY_POINTS))
def test_bad_counts_are_refused(name, value, tmp_path):
    fn = ENTRY_POINTS[name]
    args = (value, tmp_path) if name.startswith(WRITES) else (value,)
    with pytest.raises(InputError, match=r"must be (a positive integer|an integer >= \d|None)"):
        fn(*args)
    assert not (tmp_path / "ds").exists()


@pytest.mark.parametrize("value", BAD, ids=repr)
def test_simulator_push_count(simulator, value):
    with pytest.raises(InputError, match="n must be"):
        list(simulator.run(value, np.random.default_rng(0)))


@pytest.mark.parametrize("value", [np.int64(2), 2.0])
def test_integral_counts_of_other_types_are_accepted(value, tmp_path):
    ds = generate(
        dataclasses.replace(CFG, n=value, shard_size=value),
        tmp_path / "ds",
        workers=0,
        progress=False,
    )
    assert len(ds) == 2
    assert type(ds.meta["n"]) is int and type(ds.meta["shard_size"]) is int
    assert check_workers(np.int64(3)) == 3 and check_workers(None) is None
    cfg = AffordanceMapConfig(n_maps=np.int64(2), max_steps=3.0).validate()
    assert type(cfg.n_maps) is int and type(cfg.max_steps) is int
    assert cfg.fingerprint() == AffordanceMapConfig(n_maps=2, max_steps=3).fingerprint()


@pytest.mark.parametrize(
    "loader,file,section,key,value",
    [
        (load_tabletop, "tabletop.yaml", "physics", "substeps", 2.5),
        (load_tabletop, "tabletop.yaml", "physics", "friction_grid", True),
        (load_warehouse, "warehouse.yaml", "sensor", "azimuths", -1),
        (load_warehouse, "warehouse.yaml", None, "grid", [7.5, 7]),
        (load_warehouse, "warehouse.yaml", None, "boxes", [0.5, 3]),
    ],
)
def test_world_file_counts(tmp_path, loader, file, section, key, value):
    raw = yaml.safe_load((worlds_dir() / file).read_text())
    (raw[section] if section else raw)[key] = value
    path = tmp_path / file
    path.write_text(yaml.safe_dump(raw))
    with pytest.raises(ConfigError, match=key):
        loader(path)
