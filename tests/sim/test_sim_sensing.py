"""Simulated point clouds from known geometry."""

import numpy as np
import pytest

from probaff.errors import InputError
from probaff.sim import load_catalogue
from probaff.sim.sensing import object_cloud, scan_scene, table_cloud


@pytest.mark.parametrize("name", ["cracker_box", "nut_container"])
def test_noise_free_cloud_lies_on_the_surface(name, rng):
    obj = load_catalogue()[name]
    pose = np.array([0.1, -0.05, 0.7])
    pts, nrm = object_cloud(obj, pose, 2000, 0.0, rng)
    assert pts.shape == (2000, 3) and nrm.shape == (2000, 3)
    np.testing.assert_allclose(np.linalg.norm(nrm, axis=1), 1.0)
    c, s = np.cos(-pose[2]), np.sin(-pose[2])
    rel = pts[:, :2] - pose[:2]
    local = np.stack([c * rel[:, 0] - s * rel[:, 1], s * rel[:, 0] + c * rel[:, 1]], -1)
    assert pts[:, 2].min() >= -1e-12 and pts[:, 2].max() <= obj.height + 1e-12
    if obj.shape == "circle":
        assert np.hypot(*local.T).max() <= obj.radius + 1e-9
    else:
        assert np.all(np.abs(local) <= np.array(obj.size) / 2 + 1e-9)
    top = nrm[:, 2] > 0.5
    np.testing.assert_allclose(pts[top, 2], obj.height)
    assert 0.1 < top.mean() < 0.95  # tops and sides are both seen


def test_noise_level(rng):
    obj = load_catalogue()["book"]
    clean, _ = object_cloud(obj, np.zeros(3), 4000, 0.0, np.random.default_rng(0))
    noisy, _ = object_cloud(obj, np.zeros(3), 4000, 0.004, np.random.default_rng(0))
    assert np.std(noisy - clean) == pytest.approx(0.004, rel=0.1)


def test_table_cloud_excludes_footprints(rng):
    cat = load_catalogue()
    scan = scan_scene((cat["book"],), np.array([[0.0, 0.0, 0.0]]), (1.0, 0.8), rng, noise=0.0)
    t = scan.table_points
    assert not np.any((np.abs(t[:, 0]) < 0.11) & (np.abs(t[:, 1]) < 0.075))
    assert scan.object_points.shape == (1, 256, 3)
    assert len(table_cloud((1.0, 0.8), 0.02, 0.0, rng)) == 50 * 40


def test_negative_noise_is_rejected(rng):
    with pytest.raises(InputError, match="noise"):
        object_cloud(load_catalogue()["book"], np.zeros(3), 10, -0.1, rng)
