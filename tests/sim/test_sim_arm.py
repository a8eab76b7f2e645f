"""The URDF arm: batched IK through pytorch-kinematics, reachability, push paths."""

import math

import numpy as np
import pytest
import torch

from probaff.errors import ConfigError, UnreachablePoseError
from probaff.sim import Arm, load_arm, load_tabletop
from probaff.sim.arm import topdown_pose


@pytest.fixture(scope="module")
def arm():
    return load_arm(load_tabletop().arm)


def test_chain_is_six_dof_with_limits(arm):
    assert arm.dof == 6
    assert torch.all(arm.chain.low < arm.chain.high)


def test_ik_reaches_commanded_poses(arm):
    g = torch.Generator().manual_seed(0)
    xy = torch.rand(64, 2, generator=g, dtype=torch.float64) * 0.4 - 0.2
    yaw = torch.rand(64, generator=g, dtype=torch.float64) * 2 * math.pi - math.pi
    T = topdown_pose(xy, yaw, 0.02)
    sol = arm.ik(T)
    assert sol.converged.all()
    T_hat = arm.fk(sol.q)
    assert (T_hat[:, :3, 3] - T[:, :3, 3]).norm(dim=-1).max() < 1.5e-3
    # the tool points down and its x axis is the push direction
    assert torch.allclose(T_hat[:, 2, 2], torch.full((64,), -1.0, dtype=torch.float64), atol=1e-3)
    assert torch.all((sol.q >= arm.chain.low) & (sol.q <= arm.chain.high))


def test_unreachable_pose_is_refused(arm):
    far = torch.tensor([[1.5, 0.9]], dtype=torch.float64)
    with pytest.raises(UnreachablePoseError, match="outside the arm's reachable workspace"):
        arm.require_reachable(far, torch.zeros(1, dtype=torch.float64))
    assert not arm.reachable(far, torch.zeros(1, dtype=torch.float64)).any()


def test_reachable_mask_comes_from_the_chain(arm):
    mask, xs, ys = arm.reachable_mask((-0.5, 0.5), (-0.4, 0.4), resolution=0.1, n_yaws=2)
    assert mask.shape == (len(ys), len(xs))
    base = np.array(load_tabletop().arm.base_xyz[:2])
    gx, gy = np.meshgrid(xs, ys)
    dist = np.hypot(gx - base[0], gy - base[1])
    assert mask[dist < 0.6].all()  # near the arm everything is reachable
    assert not mask[dist > 1.0].any()  # beyond the arm's length nothing is
    assert 0.3 < mask.mean() < 1.0  # the far table corners are out of reach


def test_push_paths_follow_the_line(arm):
    xy = torch.tensor([[0.0, -0.1], [0.1, 0.0], [-0.2, 0.05]], dtype=torch.float64)
    yaw = torch.tensor([0.3, 2.0, -1.2], dtype=torch.float64)
    sol = arm.solve_pushes(xy, yaw, 0.25)
    assert sol.ok.all()
    path = arm.trace(sol.q, torch.linspace(0, 1, 40, dtype=torch.float64))
    d = torch.stack([torch.cos(yaw), torch.sin(yaw)], -1)
    rel = path[..., :2] - xy[:, None]
    along = (rel * d[:, None]).sum(-1)
    across = rel[..., 0] * -d[:, None, 1] + rel[..., 1] * d[:, None, 0]
    assert across.abs().max() < 3e-3
    assert (along[:, -1] - 0.25).abs().max() < 2e-3
    dyaw = path[..., 2] - yaw[:, None]
    assert torch.atan2(torch.sin(dyaw), torch.cos(dyaw)).abs().max() < 2e-2


def test_out_of_reach_push_is_flagged(arm):
    xy = torch.tensor([[0.0, 0.0], [0.0, 0.3]], dtype=torch.float64)
    yaw = torch.tensor([math.pi / 2, math.pi / 2], dtype=torch.float64)  # away from the arm
    sol = arm.solve_pushes(xy, yaw, 0.25)
    assert sol.ok.tolist() == [True, False]


def test_malformed_urdf_is_reported(tmp_path):
    import dataclasses

    bad = tmp_path / "arm.urdf"
    bad.write_text("<robot name='x'><link name='a'></robot")
    spec = dataclasses.replace(load_tabletop().arm, urdf=bad)
    with pytest.raises(ConfigError, match="not a valid URDF"):
        Arm(spec)
    with pytest.raises(ConfigError, match="cannot read"):
        Arm(dataclasses.replace(spec, urdf=tmp_path / "missing.urdf"))
    with pytest.raises(ConfigError, match=r"cannot read the arm URDF .*make arm\.urdf"):
        Arm(dataclasses.replace(spec, urdf=tmp_path))


def test_ik_rejects_nan(arm):
    T = topdown_pose(
        torch.tensor([[float("nan"), 0.0]], dtype=torch.float64),
        torch.zeros(1, dtype=torch.float64),
        0.02,
    )
    with pytest.raises(ValueError, match="NaN"):
        arm.ik(T)
