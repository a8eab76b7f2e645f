"""The Open3D-backed perception refuses bad clouds before importing Open3D, and says how to
install Open3D when it is missing.

Covers probaff.perception.open3d_backend.
"""

import importlib.util

import numpy as np
import pytest

from probaff.errors import InputError
from probaff.perception.open3d_backend import (
    o3d_cast,
    o3d_dbscan,
    o3d_knn,
    o3d_normals,
    require_open3d,
)
from probaff.sim.primitives import PrimitiveScene

_CLOUD = np.random.default_rng(0).uniform(size=(40, 3))


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: o3d_normals(_CLOUD.astype(np.int64), 5), "dtype int64"),
        (lambda: o3d_normals(_CLOUD[:, :2], 5), r"shape \(N, 3\)"),
        (lambda: o3d_normals(_CLOUD[:3], 5), "at least 5"),
        (lambda: o3d_normals(np.where(_CLOUD > 0.9, np.inf, _CLOUD), 5), "NaN or inf"),
        (lambda: o3d_knn(_CLOUD > 0.5, 5), "floating-point"),
        (lambda: o3d_dbscan(_CLOUD, 0.0, 5), "eps"),
        (lambda: o3d_dbscan(_CLOUD[None], 0.1, 5), r"shape \(N, 3\)"),
        (lambda: o3d_cast("boxes", _CLOUD, np.eye(4)), "PrimitiveScene"),
        (
            lambda: o3d_cast(
                PrimitiveScene(boxes=[[0, 0, 0, 1, 1, 1, 0]], box_ids=[0]), _CLOUD, np.eye(3)
            ),
            r"\(4, 4\)",
        ),
    ],
)
def test_bad_clouds_are_named(call, message):
    with pytest.raises(InputError, match=message):
        call()


@pytest.mark.skipif(importlib.util.find_spec("open3d") is not None, reason="open3d installed")
def test_missing_open3d_says_how_to_install():
    with pytest.raises(ImportError, match="pip install open3d-cpu"):
        require_open3d()
    with pytest.raises(ImportError, match="pip install open3d-cpu"):
        o3d_knn(_CLOUD, 5)
