"""`probaff.maps` is a pure factor-graph library.

Importing it must not load learning, physics, kinematics or plotting code, and the agent built
on it (`probaff.planning`) is not reachable from it.
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


def test_unknown_names_still_raise_and_public_names_exist():
    with pytest.raises(AttributeError, match="no_such_name"):
        probaff.maps.no_such_name  # noqa: B018
    assert all(hasattr(probaff.maps, n) for n in probaff.maps.__all__)
    assert "ManipulationLoop" not in probaff.maps.__all__
    assert not hasattr(probaff.maps, "ManipulationLoop")
