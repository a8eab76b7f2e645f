"""Office scenes of chapter 2: the world file, the ground-truth label rules and the sampler."""

from dataclasses import replace

import numpy as np
import pytest
import yaml

from probaff.affordance_labels import LABELS, label_index
from probaff.errors import ConfigError, InputError
from probaff.sim.office import (
    OfficeScene,
    assemble_office_scene,
    sample_office_scene,
    sample_office_scenes,
)
from probaff.sim.office_config import OfficeLabelRules, load_office
from probaff.sim.office_labels import office_labels
from probaff.sim.office_objects import OfficeObject
from probaff.sim.primitives import PrimitiveScene
from probaff.sim.world_files import worlds_dir

RULES = OfficeLabelRules()
FWD, BWD, LEFT, RIGHT, LIFT, GRASP = range(6)


def _floor() -> OfficeObject:
    return OfficeObject(0, "floor", "floor", boxes=np.array([[0, 0, -0.025, 10, 10, 0.05, 0]]))


def _wall_px() -> OfficeObject:
    # A wall whose face is the plane x = 2.0.
    return OfficeObject(1, "wall", "wall_+x", boxes=np.array([[2.05, 0, 1.2, 0.1, 10, 2.4, 0]]))


def _box(oid, x, y, size, z0=0.0, support=-1, mass=1.0) -> OfficeObject:
    sx, sy, sz = size
    return OfficeObject(
        oid,
        "box",
        f"box_{oid}",
        support,
        boxes=np.array([[x, y, z0 + sz / 2, sx, sy, sz, 0]]),
        mass=mass,
    )


def _table(oid, x, y, length=1.2, depth=0.8, height=0.75) -> OfficeObject:
    t, leg = 0.03, 0.05
    parts = [[x, y, height - t / 2, length, depth, t, 0]]
    for sx in (1, -1):
        for sy in (1, -1):
            parts.append(
                [
                    x + sx * (length / 2 - leg),
                    y + sy * (depth / 2 - leg),
                    (height - t) / 2,
                    leg,
                    leg,
                    height - t,
                    0,
                ]
            )
    return OfficeObject(oid, "table", f"table_{oid}", boxes=np.array(parts), mass=20.0)


@pytest.fixture(scope="module")
def spec():
    return load_office()


@pytest.fixture(scope="module")
def scenes(spec):
    return sample_office_scenes(spec, 20, 7)


# ------------------------------------------------------------------------------- world file


def test_world_file_loads_with_the_thesis_gripper(spec):
    assert spec.labels.gripper_span == pytest.approx(0.15)
    assert spec.labels.max_lift_mass == pytest.approx(1.8)
    assert set(spec.room.walls) <= {"+x", "-x", "+y", "-y"}
    assert spec.tables.count[0] <= spec.tables.count[1]
    assert len(spec.boxes.classes) >= 3


def _write(tmp_path, raw):
    p = tmp_path / "office.yaml"
    p.write_text(yaml.safe_dump(raw))
    return p


def test_malformed_world_file_names_the_field(tmp_path):
    raw = yaml.safe_load((worlds_dir() / "office.yaml").read_text())
    bad = yaml.safe_load(yaml.safe_dump(raw))
    del bad["labels"]["gripper_span"]
    with pytest.raises(ConfigError, match="gripper_span"):
        load_office(_write(tmp_path, bad))
    bad = yaml.safe_load(yaml.safe_dump(raw))
    bad["tables"]["count"] = [1.5, 3]
    with pytest.raises(ConfigError, match=r"tables\.count"):
        load_office(_write(tmp_path, bad))
    bad = yaml.safe_load(yaml.safe_dump(raw))
    bad["room"]["walls"] = ["north"]
    with pytest.raises(ConfigError, match="north"):
        load_office(_write(tmp_path, bad))
    bad = yaml.safe_load(yaml.safe_dump(raw))
    bad["boxes"]["on_table_probability"] = 1.5
    with pytest.raises(ConfigError, match="on_table_probability"):
        load_office(_write(tmp_path, bad))
    bad = yaml.safe_load(yaml.safe_dump(raw))
    bad["chairs"]["colour"] = "red"
    with pytest.raises(ConfigError, match="colour"):
        load_office(_write(tmp_path, bad))
    p = tmp_path / "broken.yaml"
    p.write_text("room: [unclosed")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_office(p)


def test_label_index_and_unknown_label():
    assert [label_index(n) for n in LABELS] == list(range(6))
    with pytest.raises(InputError, match="liftable"):
        label_index("pushable_up")


# ------------------------------------------------------------------------------ label rules


def test_box_against_a_wall_is_not_pushable_towards_it():
    box = _box(2, 1.7, 0.0, (0.4, 0.4, 0.4))  # its +x face 0.1 m from the wall
    scene = assemble_office_scene([_floor(), _wall_px(), box], RULES)
    lab = scene.label_of(2)
    assert not lab[FWD]
    assert lab[BWD] and lab[LEFT] and lab[RIGHT]
    assert not scene.label_of(0).any() and not scene.label_of(1).any()
    far = _box(2, 1.0, 0.0, (0.4, 0.4, 0.4))  # 0.8 m from the wall
    assert assemble_office_scene([_floor(), _wall_px(), far], RULES).label_of(2)[:4].all()


def test_push_directions_follow_the_robot_frame():
    box = _box(2, 1.7, 0.0, (0.4, 0.4, 0.4))
    # Robot turned 90 degrees: its right (-y) points along world +x, towards the wall.
    scene = assemble_office_scene([_floor(), _wall_px(), box], RULES, (0.0, 0.0, np.pi / 2))
    lab = scene.label_of(2)
    assert not lab[RIGHT] and lab[FWD] and lab[BWD] and lab[LEFT]


def test_neighbour_blocks_only_with_overlap_across_the_direction():
    a = _box(1, 0.0, 0.0, (0.4, 0.4, 0.4))
    beside = _box(2, 0.5, 0.1, (0.4, 0.4, 0.4))  # 0.1 m ahead along +x, overlapping in y
    diagonal = _box(2, 0.5, 0.5, (0.4, 0.4, 0.4))  # 0.1 m ahead, but no overlap in y
    s1 = assemble_office_scene([_floor(), a, beside], RULES)
    assert not s1.label_of(1)[FWD] and not s1.label_of(2)[BWD]
    assert s1.label_of(1)[[BWD, LEFT, RIGHT]].all()
    s2 = assemble_office_scene([_floor(), a, diagonal], RULES)
    assert s2.label_of(1)[:4].all()


def test_box_with_another_on_top_is_not_liftable():
    bottom = _box(1, 0.0, 0.0, (0.4, 0.4, 0.3), mass=1.0)
    top = _box(2, 0.0, 0.0, (0.2, 0.2, 0.2), z0=0.3, support=1, mass=0.5)
    wall = _wall_px()
    scene = assemble_office_scene([_floor(), replace_id(wall, 3), bottom, top], RULES)
    assert not scene.label_of(1)[LIFT]
    assert scene.label_of(2)[LIFT]
    alone = assemble_office_scene([_floor(), bottom], RULES)
    assert alone.label_of(1)[LIFT]
    # Its load does not block it: still pushable every way.
    assert scene.label_of(1)[:4].all()


def replace_id(obj: OfficeObject, oid: int) -> OfficeObject:
    return OfficeObject(oid, obj.kind, obj.name, obj.support, obj.boxes, obj.cylinders, obj.mass)


def test_heavy_or_large_box_is_not_liftable():
    heavy = _box(1, 0.0, 0.0, (0.3, 0.3, 0.3), mass=5.0)
    large = _box(2, 3.0, 0.0, (0.9, 0.4, 0.3), mass=1.0)
    scene = assemble_office_scene([_floor(), heavy, large], RULES)
    assert not scene.label_of(1)[LIFT] and not scene.label_of(2)[LIFT]


def test_graspable_needs_a_part_thinner_than_the_span():
    narrow = _box(1, 0.0, 0.0, (0.3, 0.10, 0.2))
    wide = _box(2, 3.0, 0.0, (0.3, 0.25, 0.2))
    handled = OfficeObject(
        3,
        "box",
        "box_with_handle",
        boxes=[[-3.0, 0, 0.1, 0.3, 0.25, 0.2, 0], [-3.0, 0, 0.25, 0.2, 0.03, 0.1, 0]],
        mass=1.0,
    )
    scene = assemble_office_scene([_floor(), narrow, wide, handled], RULES)
    assert scene.label_of(1)[GRASP]
    assert not scene.label_of(2)[GRASP]
    assert scene.label_of(3)[GRASP]
    wider_gripper = replace(RULES, gripper_span=0.3)
    assert assemble_office_scene([_floor(), wide], wider_gripper).label_of(2)[GRASP]


def test_object_on_a_table_is_pushable_every_way():
    table = _table(2, 1.35, 0.0)  # its +x edge 0.05 m from the wall
    box = _box(3, 1.8, 0.0, (0.2, 0.2, 0.2), z0=0.75, support=2, mass=0.5)
    scene = assemble_office_scene([_floor(), _wall_px(), table, box], RULES)
    assert scene.label_of(3)[:4].all() and scene.label_of(3)[LIFT]
    t = scene.label_of(2)
    assert not t[FWD] and t[BWD] and t[LEFT] and t[RIGHT]  # blocked by the wall only
    assert not t[LIFT]  # too heavy, too large, and loaded
    assert t[GRASP]  # by its legs


def test_scene_and_object_errors():
    with pytest.raises(InputError, match="kind"):
        OfficeObject(0, "lamp", "lamp", boxes=[[0, 0, 0, 1, 1, 1, 0]])
    with pytest.raises(InputError, match="no parts"):
        OfficeObject(0, "box", "empty")
    with pytest.raises(InputError, match="NaN"):
        _box(1, float("nan"), 0.0, (0.2, 0.2, 0.2))
    with pytest.raises(InputError, match="id"):
        OfficeObject(1.5, "box", "b", boxes=[[0, 0, 0.1, 0.2, 0.2, 0.2, 0]])
    with pytest.raises(InputError, match="unique"):
        assemble_office_scene([_floor(), _floor()], RULES)
    with pytest.raises(InputError, match="not in the scene"):
        assemble_office_scene([_floor(), _box(1, 0, 0, (0.2, 0.2, 0.2), support=7)], RULES)
    scene = assemble_office_scene([_floor(), _box(1, 0, 0, (0.2, 0.2, 0.2))], RULES)
    with pytest.raises(InputError, match="not in the scene"):
        scene.label_of(9)
    with pytest.raises(InputError, match="object_id"):
        scene.label_of(-1)
    with pytest.raises(InputError, match="labels"):
        OfficeScene(scene.primitives, scene.objects, np.zeros((3, 6), dtype=bool))
    with pytest.raises(ConfigError, match="gripper_span"):
        OfficeLabelRules(gripper_span=-0.1)
    with pytest.raises(InputError, match="robot_pose"):
        assemble_office_scene(scene.objects, RULES, ("a", 0.0, 0.0))
    with pytest.raises(InputError, match="robot_pose"):
        assemble_office_scene(scene.objects, RULES, (0.0, float("inf"), 0.0))


# --------------------------------------------------------------------------------- sampling


def _inside_points(scene: PrimitiveScene, rng: np.random.Generator, n: int = 40) -> list:
    """For each primitive: (object id, (n, 3) points strictly inside it)."""
    out = []
    for (cx, cy, cz, sx, sy, sz, yaw), oid in zip(scene.boxes, scene.box_ids, strict=True):
        u = rng.uniform(-0.49, 0.49, (n, 3)) * (sx, sy, sz)
        c, s = np.cos(yaw), np.sin(yaw)
        p = np.column_stack([cx + c * u[:, 0] - s * u[:, 1], cy + s * u[:, 0] + c * u[:, 1]])
        out.append((oid, np.column_stack([p, cz + u[:, 2]])))
    for (cx, cy, cz, r, h), oid in zip(scene.cylinders, scene.cylinder_ids, strict=True):
        rad = 0.98 * r * np.sqrt(rng.uniform(0, 1, n))
        ang = rng.uniform(0, 2 * np.pi, n)
        z = cz + rng.uniform(-0.49, 0.49, n) * h
        out.append((oid, np.column_stack([cx + rad * np.cos(ang), cy + rad * np.sin(ang), z])))
    return out


def _without(scene: PrimitiveScene, oid: int) -> PrimitiveScene:
    kb, kc = scene.box_ids != oid, scene.cylinder_ids != oid
    return PrimitiveScene(
        scene.boxes[kb], scene.box_ids[kb], scene.cylinders[kc], scene.cylinder_ids[kc]
    )


def test_sampled_scenes_have_no_overlapping_objects(spec, scenes):
    rng = np.random.default_rng(0)
    for scene in scenes:
        prims = scene.primitives
        others = {oid: _without(prims, oid) for oid in prims.object_ids}
        for oid, pts in _inside_points(prims, rng):
            assert not others[oid].contains(pts).any(), f"object {oid} overlaps another"
        # Exact footprint test for the objects on the floor (their footprints are axis-aligned).
        floor = [o for o in scene.objects if o.kind in ("table", "chair", "box") and o.support < 0]
        c = spec.placement.min_clearance
        for i, a in enumerate(floor):
            for b in floor[i + 1 :]:
                (alo, ahi), (blo, bhi) = a.bounds[:, :2], b.bounds[:, :2]
                gap = np.maximum(blo - ahi, alo - bhi).max()
                assert gap >= c - 1e-9


def test_every_object_has_an_id_and_labels(spec, scenes):
    for scene in scenes:
        ids = [o.id for o in scene.objects]
        assert ids == list(range(len(ids)))
        assert set(scene.primitives.object_ids.tolist()) == set(ids)
        assert scene.labels.shape == (len(ids), len(LABELS)) and scene.labels.dtype == bool
        kinds = [o.kind for o in scene.objects]
        assert kinds[0] == "floor" and kinds.count("wall") == len(spec.room.walls)
        lo, hi = spec.tables.count
        assert lo <= kinds.count("table") <= hi
        for o, lab in zip(scene.objects, scene.labels, strict=True):
            np.testing.assert_array_equal(scene.label_of(o.id), lab)
            if o.kind in ("floor", "wall"):
                assert not lab.any()
            if o.support >= 0:
                assert lab[:4].all()
                base = scene.objects[o.support]
                assert o.bounds[0, 2] == pytest.approx(base.bounds[1, 2])
                assert not scene.label_of(base.id)[LIFT]


def test_sampling_is_deterministic_by_seed(spec):
    a = sample_office_scenes(spec, 3, 11)
    b = sample_office_scenes(spec, 3, 11)
    c = sample_office_scenes(spec, 3, 12)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x.primitives.boxes, y.primitives.boxes)
        np.testing.assert_array_equal(x.primitives.cylinders, y.primitives.cylinders)
        np.testing.assert_array_equal(x.labels, y.labels)
    assert not np.array_equal(a[0].primitives.boxes, c[0].primitives.boxes)
    child = np.random.SeedSequence(11).spawn(3)[2]
    alone = sample_office_scene(spec, np.random.default_rng(child))
    np.testing.assert_array_equal(alone.primitives.boxes, a[2].primitives.boxes)


def test_label_frequencies_are_not_degenerate(scenes):
    rows = [
        lab
        for s in scenes
        for o, lab in zip(s.objects, s.labels, strict=True)
        if o.kind in ("table", "chair", "box")
    ]
    freq = np.mean(rows, axis=0)
    assert len(rows) > 100
    assert np.all(freq > 0.1) and np.all(freq < 0.95), dict(zip(LABELS, freq, strict=True))


def test_crowded_room_is_a_config_error_naming_the_range(spec):
    small = replace(spec, room=replace(spec.room, x=(-0.8, 1.2), y=(-1.0, 1.0)))
    crowded = replace(small, tables=replace(spec.tables, count=(4, 4)))
    with pytest.raises(ConfigError, match=r"room\.x.*tables\.count"):
        sample_office_scene(crowded, np.random.default_rng(0))
    with pytest.raises(ConfigError, match=r"OfficeTableSpec\.count"):
        replace(spec.tables, count=(3, 1))


def test_bad_counts_and_streams(spec):
    with pytest.raises(InputError, match="n must be"):
        sample_office_scenes(spec, 0, 1)
    with pytest.raises(InputError, match="n must be"):
        sample_office_scenes(spec, 2.5, 1)
    with pytest.raises(InputError, match="seed"):
        sample_office_scenes(spec, 2, -1)
    with pytest.raises(InputError, match="Generator"):
        sample_office_scene(spec, 3)
    with pytest.raises(InputError, match="OfficeSpec"):
        sample_office_scene("office.yaml", np.random.default_rng(0))


# ------------------------------------------------------------------------ scene consistency


def _round_table(oid, x, y) -> OfficeObject:
    """A pedestal table: a 0.8 m square top 0.75 m high on a 0.1 m-radius cylinder."""
    return OfficeObject(
        oid,
        "table",
        f"table_{oid}",
        boxes=[[x, y, 0.735, 0.8, 0.8, 0.03, 0]],
        cylinders=[[x, y, 0.36, 0.1, 0.72]],
        mass=20.0,
    )


def test_overlapping_objects_are_refused_naming_both():
    a = _box(1, 0.0, 0.0, (0.4, 0.4, 0.4))
    b = _box(2, 0.3, 0.1, (0.4, 0.4, 0.4))  # 0.1 m into box_1 along x
    with pytest.raises(InputError, match=r"box_1 \(id 1\) and box_2 \(id 2\) overlap by 100\.0 mm"):
        assemble_office_scene([_floor(), a, b], RULES)
    turned = OfficeObject(2, "box", "box_2", boxes=[[0.3, 0.0, 0.2, 0.4, 0.1, 0.4, 0.7]], mass=1)
    with pytest.raises(InputError, match=r"box_1 \(id 1\) and box_2 \(id 2\) overlap"):
        office_labels([_floor(), a, turned], RULES)
    # a box pushed into a pedestal, and one stacked into the table top
    with pytest.raises(InputError, match=r"table_3 \(id 3\) and box_4 \(id 4\) overlap"):
        assemble_office_scene(
            [_floor(), _round_table(3, 2, 0), _box(4, 2.15, 0, (0.2,) * 3)], RULES
        )
    sunk = _box(4, 2.0, 0.0, (0.2, 0.2, 0.2), z0=0.74, support=3)
    with pytest.raises(
        InputError, match=r"table_3 \(id 3\) and box_4 \(id 4\) overlap by 10\.0 mm"
    ):
        assemble_office_scene([_floor(), _round_table(3, 2, 0), sunk], RULES)
    # touching faces and a box under the table top, beside the pedestal, are fine
    touching = _box(2, 0.4, 0.0, (0.4, 0.4, 0.4))
    clear = OfficeObject(2, "box", "box_2", boxes=[[0.45, 0.0, 0.2, 0.4, 0.1, 0.4, 0.7]], mass=1)
    assemble_office_scene([_floor(), a, clear], RULES)  # turned, 6.5 cm clear of box_1
    under = _box(4, 2.25, 0.0, (0.2, 0.2, 0.2))
    assemble_office_scene([_floor(), a, touching, _round_table(3, 2, 0), under], RULES)


def test_support_cycles_and_impossible_supports_are_refused():
    one = _box(1, 0.0, 0.0, (0.4, 0.4, 0.3), z0=0.3, support=2)
    two = _box(2, 0.0, 0.0, (0.4, 0.4, 0.3), support=1)
    with pytest.raises(InputError, match=r"cycle, box_1 \(id 1\) on box_2 \(id 2\) on box_1"):
        assemble_office_scene([_floor(), one, two], RULES)
    on_wall = _box(2, 1.7, 0.0, (0.2, 0.2, 0.2), support=1)
    with pytest.raises(InputError, match=r"has support 1, the wall wall_\+x; .* support -1"):
        assemble_office_scene([_floor(), _wall_px(), on_wall], RULES)
    on_floor = _box(2, 1.0, 0.0, (0.2, 0.2, 0.2), support=0)
    with pytest.raises(InputError, match=r"has support 0, the floor floor"):
        assemble_office_scene([_floor(), on_floor], RULES)
    carried = OfficeObject(1, "wall", "wall_+x", 2, boxes=[[2.05, 0, 1.2, 0.1, 10, 2.4, 0]])
    with pytest.raises(InputError, match=r"wall_\+x \(id 1\) is a wall and stands on nothing"):
        assemble_office_scene([_floor(), carried, _box(2, 1.0, 0, (0.2,) * 3)], RULES)


def test_floating_sunk_or_unsupported_objects_are_refused():
    floating = _box(1, 0.0, 0.0, (0.2, 0.2, 0.2), z0=0.5)
    with pytest.raises(InputError, match=r"box_1 \(id 1\) has support -1 .* z=0\.500 m"):
        assemble_office_scene([_floor(), floating], RULES)
    off = _box(1, 4.9, 0.0, (0.4, 0.4, 0.4))  # the floor ends at x = 5
    with pytest.raises(InputError, match=r"box_1 \(id 1\) reaches off the floor"):
        assemble_office_scene([_floor(), off], RULES)
    beside = _box(4, 3.0, 0.0, (0.2, 0.2, 0.2), z0=0.75, support=3)  # 1 m from the table
    with pytest.raises(InputError, match=r"box_4 \(id 4\) stands on table_3 \(id 3\), but"):
        assemble_office_scene([_floor(), _round_table(3, 2, 0), beside], RULES)
    hovering = _box(4, 2.0, 0.0, (0.2, 0.2, 0.2), z0=0.9, support=3)
    with pytest.raises(InputError, match=r"z=0\.900 m\) is not on a top face of table_3"):
        assemble_office_scene([_floor(), _round_table(3, 2, 0), hovering], RULES)


def test_objects_must_be_office_objects():
    with pytest.raises(InputError, match=r"objects\[1\] must be an OfficeObject, got dict"):
        assemble_office_scene([_floor(), {"id": 1}], RULES)
    with pytest.raises(InputError, match="objects must be a list of OfficeObject, got str"):
        office_labels("floor", RULES)


def test_sampler_never_builds_a_scene_the_checks_refuse(spec):
    # assemble_office_scene checks every sampled scene; 150 scenes exercise every rule
    scenes = sample_office_scenes(spec, 150, 2)
    stacked = [o for s in scenes for o in s.objects if o.support >= 0]
    assert len(stacked) > 50
    # a box drawn for a table whose tops are full goes to the floor (this draw filled them)
    crowded = sample_office_scene(spec, np.random.default_rng(583))
    assert sum(o.kind == "box" for o in crowded.objects) >= 3
