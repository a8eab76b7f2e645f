"""`probaff.maps` is a pure factor-graph library, and the agent's old names there are deprecated.

Importing it must not load learning, physics, kinematics or plotting code; the names that moved
to `probaff.planning` resolve lazily with a `DeprecationWarning`.
"""

import json
import subprocess
import sys

import pytest

import probaff.maps
import probaff.planning

HEAVY = ("sklearn", "pymunk", "pytorch_kinematics", "matplotlib")
AGENT = ("probaff.planning", "probaff.perception", "probaff.sim", "probaff.features")

_PROBE = (
    "import json, sys, warnings\n"
    "warnings.simplefilter('error', DeprecationWarning)\n"
    "import probaff.maps\n"
    "print(json.dumps(sorted(sys.modules)))\n"
)


def test_importing_maps_loads_no_heavy_or_agent_module():
    out = subprocess.run(
        [sys.executable, "-c", _PROBE], capture_output=True, text=True, check=True, timeout=120
    )
    loaded = json.loads(out.stdout.strip().splitlines()[-1])
    heavy = [m for m in loaded if m.split(".")[0] in HEAVY]
    agent = [m for m in loaded if m.startswith(AGENT)]
    assert not heavy, f"import probaff.maps loaded {heavy[:10]}"
    assert not agent, f"import probaff.maps loaded {agent[:10]}"


@pytest.mark.parametrize(
    "name",
    [
        "ManipulationLoop",
        "LoopResult",
        "POLICIES",
        "detect_push",
        "AffordanceClassifier",
        "AffordanceEvaluation",
        "collect_voxels",
        "evaluate",
        "PushPlan",
    ],
)
def test_moved_names_warn_and_resolve_to_planning(name):
    with pytest.warns(DeprecationWarning, match=rf"probaff\.maps\.{name} is deprecated"):
        obj = getattr(probaff.maps, name)
    assert obj is getattr(probaff.planning, name)


def test_old_plan_pushes_keeps_its_grid_signature():
    with pytest.warns(DeprecationWarning, match="plan_pushes"):
        old = probaff.maps.plan_pushes
    assert old is probaff.planning.plan_pushes_on_grid


def _isort_key(name):
    """Constants, then classes, then functions, each alphabetical (ruff's RUF022 order)."""
    return (0 if name.isupper() else 1 if name[0].isupper() else 2, name)


def test_unknown_names_still_raise_and_public_names_are_sorted():
    with pytest.raises(AttributeError, match="no_such_name"):
        probaff.maps.no_such_name  # noqa: B018
    for module in (probaff.maps, probaff.planning):
        assert list(module.__all__) == sorted(module.__all__, key=_isort_key)
        assert all(hasattr(module, n) for n in module.__all__)
    assert "ManipulationLoop" not in probaff.maps.__all__
    assert "ManipulationLoop" in dir(probaff.maps)
