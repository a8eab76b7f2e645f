"""Fixtures of the planning tests: the push-to-edge task, its reachability and training pushes."""

import pytest

from probaff.data.generation import GenerateConfig, make_shard
from probaff.data.queries import world_meta
from probaff.data.schema import PushDataset
from probaff.planning.push_to_edge.planners import PushReachability
from probaff.planning.push_to_edge.task import load_edge_task
from probaff.sim.specs import load_catalogue
from probaff.sim.tabletop_config import load_tabletop


@pytest.fixture(scope="session")
def task():
    """The push-to-edge task of ``worlds/tasks/push_to_edge.yaml``."""
    return load_edge_task()


@pytest.fixture(scope="session")
def reach(task):
    """The arm's push reachability, shared: its answers do not depend on what was asked before."""
    return PushReachability(task)


@pytest.fixture(scope="session")
def edge_data():
    """48 pushes of the push-to-edge scene, generated in process."""
    arrays = make_shard(GenerateConfig("push_to_edge", 48, shard_size=48, trajectories=False), 0)
    meta = {**world_meta(load_tabletop()), "cloud_points": 256, "cloud_noise": 0.002}
    return PushDataset(arrays, sorted(load_catalogue()), meta)
