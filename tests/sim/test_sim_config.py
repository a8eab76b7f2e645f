"""World descriptions: loading, and clear errors for anything malformed or unknown.

Covers probaff.sim.world_files, probaff.sim.specs and probaff.sim.tabletop_config.
"""

import shutil

import pytest

from probaff.errors import ConfigError
from probaff.sim import load_catalogue, load_scene, load_tabletop
from probaff.sim.tabletop_config import list_scenes
from probaff.sim.world_files import worlds_dir


def test_catalogue_has_the_thesis_objects():
    cat = load_catalogue()
    for name in [
        "cracker_box",
        "tool_box",
        "phone_box",
        "nut_container",
        "waterpot_lid",
        "wood_block",
        "book",
        "battery",
    ]:
        assert name in cat
    assert cat["nut_container"].shape == "circle" and cat["waterpot_lid"].shape == "circle"
    assert cat["battery"].mass > 10 * cat["book"].mass


def test_scenes_load():
    names = list_scenes()
    assert {"single_free", "near_obstacle", "near_wall", "two_objects", "table_edge"} <= set(names)
    for n in names:
        spec = load_scene(n)
        assert spec.push.distance > 0
    assert load_scene("two_objects").push.distance == pytest.approx(0.25)
    assert load_scene("near_obstacle").push.distance == pytest.approx(0.15)


def test_tabletop_gripper_opens_to_15cm():
    w = load_tabletop()
    assert w.gripper.push_opening <= 0.15
    assert w.physics.collision_slop < 0.01


def test_unknown_scene():
    with pytest.raises(ConfigError, match=r"unknown scene 'nope'.*two_objects"):
        load_scene("nope")


@pytest.fixture
def worlds_copy(tmp_path, monkeypatch):
    dst = tmp_path / "worlds"
    shutil.copytree(worlds_dir(), dst)
    monkeypatch.setenv("PROBAFF_WORLDS", str(dst))
    return dst


def test_unknown_object_in_scene(worlds_copy):
    p = worlds_copy / "scenes" / "two_objects.yaml"
    p.write_text(p.read_text().replace("tool_box, phone_box", "tool_box, teapot", 1))
    with pytest.raises(ConfigError, match="unknown object 'teapot'"):
        load_scene("two_objects")


def test_malformed_yaml(worlds_copy):
    (worlds_copy / "scenes" / "broken.yaml").write_text("objects: [unclosed\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_scene("broken")


@pytest.mark.parametrize("bad", ["-0.3", ".nan", "'heavy'"])
def test_bad_parameter_values(worlds_copy, bad):
    p = worlds_copy / "objects.yaml"
    p.write_text(p.read_text().replace("mass: 0.600", f"mass: {bad}"))
    with pytest.raises(ConfigError, match=r"book\.mass"):
        load_catalogue(p)


def test_negative_range_in_scene(worlds_copy):
    p = worlds_copy / "scenes" / "single_free.yaml"
    p.write_text(p.read_text().replace("distance: 0.15", "distance: -0.15"))
    with pytest.raises(ConfigError, match=r"push\.distance must be > 0"):
        load_scene("single_free")


def test_unknown_field(worlds_copy):
    p = worlds_copy / "tabletop.yaml"
    p.write_text(p.read_text().replace("push_opening: 0.06", "push_opening: 0.2"))
    with pytest.raises(ConfigError, match=r"exceeds the 0\.15 m"):
        load_tabletop(p)


def test_missing_worlds_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("PROBAFF_WORLDS", str(tmp_path / "none"))
    with pytest.raises(ConfigError, match="PROBAFF_WORLDS"):
        worlds_dir()


def test_world_file_that_is_binary_a_folder_or_missing(tmp_path):
    binary = tmp_path / "tabletop.yaml"
    binary.write_bytes(b"\xff\xfe\x00\x01 not text")
    with pytest.raises(ConfigError, match=r"world file .*tabletop\.yaml is not UTF-8 text"):
        load_tabletop(binary)
    with pytest.raises(ConfigError, match=r"world file .* is a folder, not a YAML file"):
        load_tabletop(tmp_path)
    with pytest.raises(ConfigError, match=r"missing\.yaml does not exist; give the path"):
        load_tabletop(tmp_path / "missing.yaml")
    folder = tmp_path / "objects.yaml"
    folder.mkdir()
    with pytest.raises(ConfigError, match=r"objects\.yaml is a folder"):
        load_catalogue(folder)
