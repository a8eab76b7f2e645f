"""The registry of world kinds, and a new world kind added end to end from its own files.

A new world kind is three files, and this test writes the first two to a temporary folder on
`probaff.sim`'s path, edits nothing else and finds the kind through the registry:

1. its YAML: its scene templates (``worlds/<folder>/NAME.yaml``, and its world file if it has
   one), here ``puck_scenes/puck_slide.yaml``;
2. its module, ``probaff/sim/<kind>.py`` (here ``puck.py``, imported as
   ``probaff.sim.puck``): its spec and loader, its simulate function, the `SceneRows` that
   turn a scene's draws into dataset rows and its own ``register_world(WorldKind(...))``.
   `probaff.sim.registry` discovers the module (`discover_worlds`) on its next lookup;
   `probaff.data.generate`, the dataset store and the ``probaff scenes | generate |
   describe`` commands then serve it unchanged (a kind with generation options of its own
   registers a `probaff.data.kinds.DatasetKind` instead, see tests/data/test_kinds.py);
3. its test (this one).
"""

import json
import sys
import textwrap
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import probaff.sim
from probaff.cli import main
from probaff.data import GenerateConfig, generate, load_any_dataset
from probaff.errors import ConfigError, InputError
from probaff.sim import kind_of_scene, register_world, world_kind, world_kinds
from probaff.sim.registry import SceneRows, UnknownSceneError, discover_worlds, unregister_world

PUCK_MODULE = '''
"""A puck pushed along x by a paddle: the world kind ``puck`` (a test's world)."""

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pymunk

from probaff.sim.registry import SceneRows, WorldKind, register_world
from probaff.sim.world_files import mapping, number_field, range_field, read_yaml

SCENES = Path(__file__).resolve().parent / "puck_scenes"


@dataclass(frozen=True)
class PuckSpec:
    """A puck scene: ranges of the puck's mass (kg) and of the paddle's speed (m/s)."""

    name: str
    description: str
    mass: tuple[float, float]
    speed: tuple[float, float]
    duration: float


def load_puck_scene(name: str) -> PuckSpec:
    path = SCENES / f"{name}.yaml"
    raw = mapping(path.name, read_yaml(path))
    return PuckSpec(
        name=name,
        description=str(raw.get("description", "")),
        mass=range_field(path.name, raw, "mass", positive=True),
        speed=range_field(path.name, raw, "speed", positive=True),
        duration=number_field(path.name, raw, "duration", positive=True),
    )


def load_puck_world(path: Path | None = None) -> dict[str, float]:
    return {"radius": 0.03, "rate": 120.0}


def simulate_puck(world: dict[str, float], mass: float, speed: float, duration: float) -> float:
    """Push a puck along x with a paddle at `speed` for `duration` s; return how far it went."""
    space = pymunk.Space()
    space.damping = 0.5
    puck = pymunk.Body(mass, pymunk.moment_for_circle(mass, 0.0, world["radius"]))
    space.add(puck, pymunk.Circle(puck, world["radius"]))
    paddle = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
    paddle.position = (-world["radius"] - 0.01, 0.0)
    paddle.velocity = (speed, 0.0)
    space.add(paddle, pymunk.Segment(paddle, (0.0, -0.05), (0.0, 0.05), 0.005))
    for _ in range(round(duration * world["rate"])):
        space.step(1.0 / world["rate"])
    return float(puck.position.x)


def make_rows(scene: str, rows: int, seeds: np.random.SeedSequence) -> dict[str, np.ndarray]:
    spec, world, rng = load_puck_scene(scene), load_puck_world(), np.random.default_rng(seeds)
    mass, speed = rng.uniform(*spec.mass, size=rows), rng.uniform(*spec.speed, size=rows)
    travel = [simulate_puck(world, m, v, spec.duration) for m, v in zip(mass, speed, strict=True)]
    return {
        "object_ids": np.zeros((rows, 1), dtype=np.int16),
        "mass": mass,
        "speed": speed,
        "travel": np.array(travel),
    }


PUCK_ROWS = SceneRows(
    arrays={"mass": "float64", "speed": "float64", "travel": "float64"},
    make=make_rows,
    object_names=lambda scene: ["puck"],
    unit="push",
)

register_world(
    WorldKind(
        name="puck",
        label="puck",
        load_world=load_puck_world,
        simulate=simulate_puck,
        scenes=SCENES,
        load_scene=load_puck_scene,
        dataset_kind="puck",
        actions="push",
        rows=PUCK_ROWS,
    )
)
'''

PUCK_SCENE = """
description: A puck pushed along x by a paddle.
mass: [0.2, 0.5]
speed: [0.1, 0.3]
duration: 0.5
"""


@pytest.fixture
def world_folder(tmp_path, monkeypatch):
    """A folder on `probaff.sim`'s path: a module written there is ``probaff.sim.<stem>``."""
    monkeypatch.setattr(probaff.sim, "__path__", [*probaff.sim.__path__, str(tmp_path)])
    yield tmp_path
    for name in [m for m in sys.modules if m.startswith("probaff.sim.") and "puck" in m]:
        del sys.modules[name]


@pytest.fixture
def puck_kind(world_folder):
    """The ``puck`` kind, from its two files alone (its module and its scene template)."""
    (world_folder / "puck_scenes").mkdir()
    (world_folder / "puck_scenes" / "puck_slide.yaml").write_text(PUCK_SCENE.lstrip())
    (world_folder / "puck.py").write_text(textwrap.dedent(PUCK_MODULE))
    kind = world_kind("puck")  # found by the registry's discovery, named nowhere else
    yield kind
    unregister_world("puck")


# --- its test ------------------------------------------------------------------------------


def test_a_new_world_is_its_module_and_its_yaml(puck_kind):
    assert puck_kind.simulate.__module__ == "probaff.sim.puck"
    assert [k.name for k in world_kinds()][-1] == "puck"  # after the built-in kinds
    assert discover_worlds() == []  # every module is imported once


def test_a_module_registering_a_taken_name_is_refused(world_folder):
    (world_folder / "puck_again.py").write_text(
        "from dataclasses import replace\n"
        "from probaff.sim.registry import register_world, world_kind\n"
        "register_world(replace(world_kind('tabletop'), order=9))\n"
    )
    with pytest.raises(InputError, match="world kind 'tabletop' is registered already"):
        world_kinds()


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*.*"))}


def test_a_new_scene_kind_generates_through_the_one_generate(puck_kind, tmp_path, capsys):
    assert kind_of_scene("puck_slide") is puck_kind
    config = GenerateConfig("puck_slide", n=5, seed=3, shard_size=2)
    ds = generate(config, tmp_path / "a", progress=False)
    assert len(ds) == 5 and ds.object_names == ["puck"] and ds.rows_label == "rows"
    assert np.all(ds["travel"] > 0)  # the paddle moved every puck
    generate(config, tmp_path / "b", progress=False)
    assert _files(tmp_path / "a") == _files(tmp_path / "b")
    again = load_any_dataset(tmp_path / "a")
    assert np.array_equal(again["travel"], ds["travel"])
    manifest = json.loads((tmp_path / "a" / "manifest.json").read_text())
    assert manifest["kind"] == "puck" and manifest["meta"] == {"scene": "puck_slide"}

    assert main(["scenes"]) == 0
    assert "puck_slide       A puck pushed along x by a paddle." in capsys.readouterr().out
    argv = ["generate", "--scene", "puck_slide", "--n", "3", "--out", str(tmp_path / "c")]
    assert main([*argv, "--workers", "0", "--quiet"]) == 0
    assert "wrote 3 rows" in capsys.readouterr().out
    assert main(["describe", str(tmp_path / "c")]) == 0
    assert json.loads(capsys.readouterr().out)["n_rows"] == 3


def test_the_built_in_kinds():
    names = [k.name for k in world_kinds()]
    assert names[:4] == ["tabletop", "sideview", "warehouse", "office"]
    assert [world_kind(name).simulate.__module__ for name in names[:4]] == [
        f"probaff.sim.{name}" for name in names[:4]
    ]  # each kind registers itself in its own module
    assert world_kind("tabletop").dataset_kind == "push"
    assert world_kind("sideview").dataset_kind == "skill"
    assert world_kind("office").scene_names() == []
    assert kind_of_scene("two_objects").name == "tabletop"
    assert kind_of_scene("pick").name == "sideview"
    assert world_kind("sideview").describe("place").startswith("side view, place: ")
    assert world_kind("tabletop").scene_path("two_objects").is_file()


def test_unknown_names_and_clashes(tmp_path):
    with pytest.raises(UnknownSceneError, match=r"tabletop \(push\).*side-view \(pick/place\)"):
        kind_of_scene("kitchen")
    with pytest.raises(InputError, match="scene must be"):
        kind_of_scene(3)
    with pytest.raises(InputError, match="unknown world kind 'moon'"):
        world_kind("moon")
    with pytest.raises(InputError, match="registered already"):
        register_world(world_kind("tabletop"))
    with pytest.raises(InputError, match="no scene templates"):
        world_kind("warehouse").scene_path("x")
    (tmp_path / "pick.yaml").write_text("name: pick\n")
    clash = replace(world_kind("warehouse"), name="clash", scenes=tmp_path, load_scene=str)
    register_world(clash)
    try:
        with pytest.raises(ConfigError, match=r"defined twice.*sideview_scenes/pick\.yaml"):
            kind_of_scene("pick")
    finally:
        unregister_world("clash")


ROWS = SceneRows({"x": "float64"}, lambda scene, rows, seeds: {}, lambda scene: [])


@pytest.mark.parametrize(
    "change,message",
    [
        ({"name": ""}, "name must be a non-empty string"),
        ({"simulate": 3}, "simulate of 'tabletop' must be callable"),
        ({"load_scene": None}, "no load_scene"),
        ({"dataset_kind": 7}, "dataset_kind"),
        ({"scenes": None, "rows": ROWS}, "rows but no scene templates"),
        ({"order": 1.5}, "order of 'tabletop' must be an integer"),
    ],
)
def test_bad_world_kinds_are_refused(change, message):
    with pytest.raises(InputError, match=message):
        replace(world_kind("tabletop"), **change)


def test_bad_scene_rows_are_refused():
    with pytest.raises(InputError, match="at least one array"):
        SceneRows({}, ROWS.make, lambda scene: [])
    with pytest.raises(InputError, match="make must be callable"):
        SceneRows({"a": "float64"}, 3, lambda scene: [])  # type: ignore[arg-type]
