"""Observation-only datasets: a robot's arrays in, checked; the same features, fits and plans.

Covers probaff.data.observations and probaff.data.observation_checks, the observation-only
schema versions (4 for pushes, 5 for skills) of probaff.data.schema, probaff.data.skill_schema
and probaff.data.store, and probaff.data.store.save_dataset.
"""

import json
import shutil

import numpy as np
import pytest
import torch

from probaff._threads import limit_threads
from probaff.data import (
    OBSERVATION_ARRAYS,
    SIMULATOR_ARRAYS,
    SKILL_SIMULATOR_ARRAYS,
    CloudSampling,
    GenerateConfig,
    PushDataset,
    SkillDataset,
    generate,
    generate_skills,
    load_dataset,
    make_shard,
    observation_dataset,
    observation_versions,
    observations_of,
    readable_versions,
    save_dataset,
    summarize,
)
from probaff.data.queries import world_meta
from probaff.data.store import load_skill_dataset, read_manifest
from probaff.errors import DatasetError, InputError
from probaff.features import (
    chapter4_features,
    chapter5_features,
    pick_interactions,
    push_interactions,
    scene_features,
)
from probaff.models import EMOptions, MixtureOfGPExperts, fit_em
from probaff.planning import plan_astar
from probaff.planning.catalogue import EDGE_PLANNERS, edge_transition, fit_edge_model
from probaff.planning.push_to_edge.planners import PushReachability
from probaff.planning.push_to_edge.task import load_edge_task, sample_episode
from probaff.sim.specs import load_catalogue
from probaff.sim.tabletop_config import load_tabletop

NAMES = sorted(load_catalogue())
META = {**world_meta(load_tabletop()), "cloud_points": 64, "cloud_noise": 0.002}


def _pushes(scene, n, **options):
    config = GenerateConfig(scene, n, seed=4, shard_size=n, cloud_points=64, **options)
    return PushDataset(make_shard(config, 0), NAMES, {**META, "scene": scene})


def _rebuilt(ds, drop=()):
    """`ds` reduced to its observations (less `drop`) and rebuilt through the constructor."""
    arrays = {k: v for k, v in observations_of(ds).items() if k not in drop}
    kind = "skill" if isinstance(ds, SkillDataset) else "push"
    return observation_dataset(arrays, ds.object_names, ds.meta, kind=kind)


@pytest.fixture(scope="module")
def chain():
    return _pushes("chain_3", 12)


@pytest.fixture(scope="module")
def picks(tmp_path_factory):
    root = tmp_path_factory.mktemp("picks") / "ds"
    return generate_skills(GenerateConfig("pick", 6, seed=2, shard_size=6), root, progress=False)


def test_observations_are_what_a_robot_logs(chain):
    obs = observations_of(chain)
    assert set(OBSERVATION_ARRAYS) <= set(obs)
    assert not set(obs) & set(SIMULATOR_ARRAYS)
    assert {"traj_time", "traj_hand", "traj_objects"} <= set(obs)  # observed too
    rebuilt = _rebuilt(chain, drop=("effect",))
    assert rebuilt.observation_only and not chain.observation_only
    assert (rebuilt.schema_version, chain.schema_version) == (4, 6)
    assert rebuilt.missing_simulated == sorted(SIMULATOR_ARRAYS)
    # the effect is computed as the simulator computes it, to the bit
    assert np.array_equal(rebuilt["effect"], chain["effect"])
    for name in OBSERVATION_ARRAYS:
        assert rebuilt[name] is chain[name] or name == "effect"  # kept, not copied
    with pytest.raises(InputError, match=r"needs array \['mass'\].*observation-only"):
        rebuilt["mass"]


def test_reduced_pushes_give_identical_features_fit_and_predictions(chain):
    rebuilt = _rebuilt(chain, drop=("effect",))
    for features in (chapter4_features, chapter5_features, scene_features):
        a, b = features(chain), features(rebuilt)
        a, b = getattr(a, "values", a), getattr(b, "values", b)
        assert np.array_equal(a, b), features.__name__
    for kind in ("hand", "objects"):
        a, b = push_interactions(chain, kind), push_interactions(rebuilt, kind)
        for field in ("features", "effect", "reaction"):
            assert np.array_equal(getattr(a, field), getattr(b, field)), (kind, field)

    def fit(ds):
        f = chapter5_features(ds)
        y = ds["effect"][:, 0]
        model = MixtureOfGPExperts(
            2, groups=f.groups, gate_features=("f_o",), expert_features=("f_o", "f_c")
        )
        with limit_threads(1):
            history = fit_em(model, f.values, y, max_iter=2, n_restarts=1, seed=3, gp_max_iter=10)
            return history, model.predict(f.values)

    (h1, p1), (h2, p2) = fit(chain), fit(rebuilt)
    assert h1.best == h2.best
    assert torch.equal(p1.mean, p2.mean) and torch.equal(p1.variance, p2.variance)


def test_planner_runs_on_a_model_fitted_to_observations():
    full = _pushes("push_to_edge", 12, trajectories=False)
    rebuilt = _rebuilt(full)
    assert rebuilt.observation_only
    fitted = fit_edge_model("gp", rebuilt, em=EMOptions(max_iter=1))
    reference = fit_edge_model("gp", full, em=EMOptions(max_iter=1))
    a, b = fitted.predict(rebuilt), reference.predict(full)
    assert torch.equal(a.mean, b.mean) and torch.equal(a.variance, b.variance)
    task = load_edge_task()
    start = sample_episode(task, np.random.default_rng(1))
    transition = edge_transition(EDGE_PLANNERS["astar-gp"], task, {"gp": fitted})
    plan = plan_astar(
        task, transition, start.poses[0], start.poses[1], PushReachability(task), budget=2
    )
    assert len(plan) >= 1 and plan.predictions >= 1
    assert np.isfinite(plan.predicted).all()


def test_reduced_picks_give_identical_rows(picks):
    ds = picks
    rebuilt = _rebuilt(ds)
    assert rebuilt.observation_only and rebuilt.schema_version == 5
    assert not set(rebuilt.arrays) & set(SKILL_SIMULATOR_ARRAYS)
    with pytest.raises(InputError, match=r"pick_interactions .*needs array \['lifted'\]"):
        pick_interactions(rebuilt)
    flags = observation_dataset(
        {**observations_of(ds), "lifted": ds["lifted"]}, ds.object_names, ds.meta, kind="skill"
    )
    a, b = pick_interactions(ds), pick_interactions(flags)
    for field in ("features", "effect", "reaction", "lifted"):
        assert np.array_equal(getattr(a, field), getattr(b, field)), field
    summary = summarize(rebuilt)
    assert summary["observation_only"] and summary["outcomes"]["fraction_lifted"] is None


def test_saved_observations_load_under_their_own_version(chain, picks, tmp_path):
    assert readable_versions()["push"] == (1, 2, 6)  # 6: the reaction along the path
    assert observation_versions() == {"push": 4, "skill": 5}
    save_dataset(_rebuilt(chain), tmp_path / "push", shard_size=5)
    manifest = read_manifest(tmp_path / "push")
    assert manifest["schema_version"] == 4 and "kind" not in manifest
    assert manifest["plan"] == {
        "scene": "chain_3",
        "n": 12,
        "seed": None,
        "shard_size": 5,
        "trajectories": True,
    }
    back = load_dataset(tmp_path / "push")
    assert back.observation_only and len(back) == 12
    assert np.array_equal(back["cloud_points"], chain["cloud_points"])
    summary = summarize(back)
    assert summary["objects"]["o1"]["fraction_fell_off"] is None
    assert summary["fraction_objects_touching"] is None and summary["observation_only"]
    json.dumps(summary)
    # a simulated dataset saved this way keeps its version and loads as before
    save_dataset(chain, tmp_path / "full")
    assert read_manifest(tmp_path / "full")["schema_version"] == 6
    assert not load_dataset(tmp_path / "full").observation_only
    ds = picks
    save_dataset(_rebuilt(ds), tmp_path / "picks")
    manifest = read_manifest(tmp_path / "picks")
    assert (manifest["kind"], manifest["schema_version"]) == ("skill", 5)
    assert load_skill_dataset(tmp_path / "picks").observation_only


def test_a_simulated_version_must_hold_the_simulators_arrays(chain, tmp_path):
    save_dataset(_rebuilt(chain), tmp_path / "obs")
    manifest = read_manifest(tmp_path / "obs")
    manifest["schema_version"] = 1
    (tmp_path / "obs" / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(DatasetError, match=r"00000.npz does not hold .*missing arrays \['contact"):
        load_dataset(tmp_path / "obs")
    manifest["schema_version"] = 3
    (tmp_path / "obs" / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(DatasetError, match="observation-only push datasets of schema version 4"):
        load_dataset(tmp_path / "obs")


def test_saving_never_overwrites(chain, tmp_path):
    save_dataset(chain, tmp_path / "a")
    before = {p: p.read_bytes() for p in (tmp_path / "a").rglob("*") if p.is_file()}
    with pytest.raises(DatasetError, match="already holds a push dataset; nothing was written"):
        save_dataset(_rebuilt(chain), tmp_path / "a")
    assert before == {p: p.read_bytes() for p in (tmp_path / "a").rglob("*") if p.is_file()}
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "notes.txt").write_text("mine")
    with pytest.raises(DatasetError, match="not empty"):
        save_dataset(chain, tmp_path / "b")
    (tmp_path / "c").mkdir()  # an empty folder is fine
    save_dataset(chain, tmp_path / "c")
    assert not list(tmp_path.glob(".*tmp*"))
    with pytest.raises(DatasetError, match="manifest given for the dataset does not fit"):
        save_dataset(chain, tmp_path / "d", manifest=read_manifest(tmp_path / "a") | {"plan": {}})


def test_clouds_are_sampled_from_box_footprints(chain):
    sizes = np.array(
        [
            [(*load_catalogue()[n].size, load_catalogue()[n].height) for n in row]
            for row in (np.array(NAMES)[chain["object_ids"]])
        ]
    )
    arrays = {k: v for k, v in observations_of(chain).items() if not k.startswith("cloud")}
    arrays["object_size"] = sizes
    a = observation_dataset(arrays, NAMES, META, sampling=CloudSampling(points=32, seed=5))
    b = observation_dataset(arrays, NAMES, META, sampling=CloudSampling(points=32, seed=5))
    assert a["cloud_points"].shape == (12, 3, 32, 3) and a["cloud_points"].dtype == np.float32
    assert np.array_equal(a["cloud_points"], b["cloud_points"])
    # the sampled boxes lie where the poses put them: their centroids within the footprints
    centre = a["cloud_points"][..., :2].mean(axis=2)
    assert np.abs(centre - chain["state_before"][..., :2]).max() < 0.05
    assert np.allclose(np.linalg.norm(a["cloud_normals"], axis=-1), 1.0)
    assert chapter4_features(a).values.shape == (12, 631)
    assert a.observation_only and "object_size" in a.arrays
    with pytest.raises(InputError, match=r"CloudSampling.points"):
        CloudSampling(points=0)
    with pytest.raises(InputError, match=r"object_size.*<= 0 in row 2"):
        bad = arrays["object_size"].copy()
        bad[2, 1, 0] = 0.0
        observation_dataset({**arrays, "object_size": bad}, NAMES, META)


def _push_arrays(ds, **changes):
    arrays = dict(observations_of(ds))
    arrays.update(changes)
    return {k: v for k, v in arrays.items() if v is not None}


def _with(ds, name, index, value, dtype=None):
    arr = np.array(ds[name], dtype=dtype)
    arr[index] = value
    return arr


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"push_yaw": None}, r"need arrays \['push_yaw'\]"),
        ({"cloud_normals": None}, "both 'cloud_points' and 'cloud_normals'"),
        ({"cloud_points": None, "cloud_normals": None}, "object clouds .* or box footprints"),
        ({"friction": np.zeros(12)}, r"arrays \['friction'\] are not in the schema"),
        (
            {"push_origin": np.zeros((12, 3))},
            r"'push_origin' has shape \(12, 3\), expected \(N, 2\)",
        ),
        (
            {"effect": np.zeros((12, 2, 3))},
            r"'effect' has shape \(12, 2, 3\), expected \(N, K, 3\) "
            r"with N = 12 .*K = 3 \(from 'object_ids'\)",
        ),
        ({"push_yaw": np.zeros(11)}, "'push_yaw' has shape .11,., expected 12 rows"),
        (
            {"state_before": np.full((12, 3, 3), "a")},
            "'state_before' has dtype <U1, expected numbers",
        ),
        ({"object_ids": np.zeros((12, 3))}, "'object_ids' has dtype float64, expected integers"),
        ({"object_ids": np.full((12, 3), 40000)}, "outside int16's range"),
        (
            {"object_ids": np.full((12, 3), 99, np.int16)},
            r"'object_ids' holds \[99, 99, 99\] in row 0 "
            r"\(and 11 more rows\), outside object_names",
        ),
        ({"push_distance": np.zeros(12)}, r"'push_distance' must be > 0.*row 0"),
        ({"traj_hand": [[1, 2], [3]]}, "ragged"),
    ],
)
def test_bad_arrays_are_named(chain, change, message):
    with pytest.raises(InputError, match=message):
        observation_dataset(_push_arrays(chain, **change), NAMES, META)


def test_nan_units_and_frames_are_named_with_their_row(chain):
    def refused(message, **change):
        with pytest.raises(InputError, match=message):
            observation_dataset(_push_arrays(chain, **change), NAMES, META)

    refused(
        r"'state_before' holds NaN or inf in row 4;",
        state_before=_with(chain, "state_before", (4, 1, 2), np.nan),
    )
    refused(
        r"'traj_hand' holds NaN or inf in row 7",
        traj_hand=_with(chain, "traj_hand", (7, 3, 0), np.inf),
    )
    refused(
        r"'push_origin' \(m\) holds -?\d+.* in row 0 \(and 11 more rows\).*millimetres",
        push_origin=chain["push_origin"] * 1000,
    )
    refused(r"'push_yaw' \(rad\) holds .* degrees", push_yaw=_with(chain, "push_yaw", 3, 270.0))
    refused(
        r"'cloud_normals' holds normals of length .* in row 0",
        cloud_normals=chain["cloud_normals"] * 2,
    )
    local = chain["cloud_points"] - np.concatenate(
        [chain["state_before"][..., :2], np.zeros((12, 3, 1))], -1
    )[:, :, None].astype(np.float32)
    refused(
        r"'cloud_points' in row \d.*object \d: the cloud spans .*not in an object's",
        cloud_points=local,
    )
    turned = _with(chain, "effect", (5, 0, 2), chain["effect"][5, 0, 2] + 0.3)
    refused(
        r"'effect' differs from the pushing-frame difference .* by up to 0.3 in row 5",
        effect=turned,
    )
    with pytest.raises(
        InputError,
        match=r"'state_before' is given in 'mm, mm, deg', but probaff expects 'm, m, rad'",
    ):
        observation_dataset(_push_arrays(chain), NAMES, META, units={"state_before": "mm, mm, deg"})
    # the schema's own units, however spaced, are accepted
    ds = observation_dataset(_push_arrays(chain), NAMES, META, units={"state_before": "m,m, rad"})
    assert len(ds) == 12


def test_bad_options_are_named(chain, picks):
    arrays = _push_arrays(chain)
    with pytest.raises(InputError, match="kind must be one of"):
        observation_dataset(arrays, NAMES, META, kind="grasp")
    with pytest.raises(InputError, match="object_names must be a non-empty list of distinct"):
        observation_dataset(arrays, ["a", "a"], META)
    with pytest.raises(InputError, match="meta must be JSON-serialisable"):
        observation_dataset(arrays, NAMES, {"when": object()})
    with pytest.raises(InputError, match="arrays must be a mapping"):
        observation_dataset([1, 2], NAMES, META)
    ds = picks
    skill = dict(observations_of(ds))
    with pytest.raises(InputError, match=r"'target' must be the slot of a present object.*row 0"):
        observation_dataset(
            {**skill, "target": np.full(6, 7, np.int16)}, ds.object_names, ds.meta, kind="skill"
        )
    with pytest.raises(InputError, match=r"'size' holds a length, depth or height <= 0 .*row 1"):
        observation_dataset(
            {**skill, "size": _with(ds, "size", (1, 0, 2), 0.0)},
            ds.object_names,
            ds.meta,
            kind="skill",
        )
    with pytest.raises(InputError, match="meta\\['skill'\\] must be 'pick' or 'place'"):
        observation_dataset(skill, ds.object_names, {**ds.meta, "skill": "poke"}, kind="skill")
    partial = {k: v for k, v in skill.items() if k != "ee_actual"}
    with pytest.raises(InputError, match="trajectory arrays"):
        observation_dataset(partial, ds.object_names, ds.meta, kind="skill")


def test_a_generated_dataset_reloads_bit_identically(tmp_path):
    """Today's dataset, saved and loaded. Files written by earlier releases (schema versions 1
    and 2) are committed fixtures, checked in tests/data/test_old_files.py."""
    out = tmp_path / "old"
    ds = generate(
        GenerateConfig("two_objects", 3, seed=1, shard_size=2, cloud_points=8),
        out,
        workers=0,
        progress=False,
    )
    again = load_dataset(out)
    assert not again.observation_only and set(again.arrays) == set(ds.arrays)
    for name, arr in ds.arrays.items():
        assert arr.dtype == again[name].dtype and arr.tobytes() == again[name].tobytes()
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    assert read_manifest(copy) == read_manifest(out)


def test_meta_units_and_names_of_the_wrong_kind_are_named(chain, picks):
    """Issue 38: refused when the dataset is built, naming the entry and what it must be."""
    arrays = _push_arrays(chain)

    def refused(message, meta=META, names=NAMES, **options):
        with pytest.raises(InputError, match=message):
            observation_dataset(arrays, names, meta, **options)

    refused(r"^meta must be a mapping of names to values .*got list", meta=[("push_height", 1)])
    refused(r"^meta must be a mapping .*got str 'near_wall'", meta="near_wall")
    refused(r"^units must be a mapping .*got list", units=["m", "m", "rad"])
    fix = r"; record the world's geometry as numbers in metres, radians and Hz"
    for key, value, want in [
        ("push_height", "two cm", r"a finite number > 0 \(m\), got 'two cm'"),
        ("push_height", float("nan"), r"a finite number > 0 \(m\), got nan"),
        ("push_height", True, r"a finite number > 0 \(m\), got True"),
        ("gripper_opening", -0.1, r"a finite number > 0 \(m\), got -0.1"),
        ("table_size", [1.0], r"2 numbers \(length, width\) > 0 \(m\), got \[1.0\]"),
    ]:
        refused(rf"^meta\['{key}'\] must be {want}{fix}", meta={**META, key: value})
    refused(
        r"^meta\['table_size'\]\[1\] must be a finite number > 0 \(m\), got '0.8'",
        meta={**META, "table_size": [1.0, "0.8"]},
    )
    refused(r"^meta\['hand'\] must be a mapping", meta={**META, "hand": "stiff"})
    refused(r"^object_names must be a list of names, not one string, got 'phone'", names="phone")
    skill = dict(observations_of(picks))
    with pytest.raises(
        InputError, match=rf"^meta\['lift'\] must be a finite number > 0 \(m\), got 'high'{fix}"
    ):
        observation_dataset(skill, picks.object_names, {**picks.meta, "lift": "high"}, kind="skill")
    with pytest.raises(
        InputError,
        match=r"^observations_of needs a dataset, got the path '.*ds'; load it first: "
        r"observations_of\(probaff.data.load_any_dataset\(path\)\)",
    ):
        observations_of("data/ds")
    with pytest.raises(InputError, match=r"^observations_of needs a dataset .*got dict"):
        observations_of({"effect": np.zeros(3)})


def _shifted_and_wrapped(ds):
    """The arrays of `ds` with every object yaw turned by one constant so that a push crosses
    +-pi, then wrapped into [-pi, pi) as a robot logging atan2 would; and the shifted ones."""
    arrays = _push_arrays(ds)
    turn = ds["state_after"][:, 0, 2] - ds["state_before"][:, 0, 2]
    row = int(np.argmax(np.abs(turn)))
    c = np.pi - ds["state_before"][row, 0, 2] - turn[row] / 2
    shifted, wrapped = dict(arrays), dict(arrays)
    for name in ("state_before", "state_after", "traj_objects"):
        arr = arrays[name].astype(np.float64)
        arr[..., 2] += c
        shifted[name] = arr.astype(arrays[name].dtype)
        arr[..., 2] = (arr[..., 2] + np.pi) % (2 * np.pi) - np.pi
        wrapped[name] = arr.astype(arrays[name].dtype)
    return shifted, wrapped, row


def test_scene_scale_and_wrapped_yaws_are_caught_or_unwrapped(chain):
    def refused(message, arrays=None, meta=META, **change):
        with pytest.raises(InputError, match=message):
            observation_dataset(arrays or _push_arrays(chain, **change), NAMES, meta)

    mm = r"it looks like millimetres: give lengths in metres"
    refused(
        r"'push_distance' \(m\) holds 60 in row 3: a push longer than the table's diagonal, "
        r"1\.281 m for a 1 x 0\.8 m table \(meta\['table_size'\]\); " + mm,
        push_distance=_with(chain, "push_distance", 3, 60.0),
    )
    refused(  # the default table without meta's table_size
        r"'push_distance' \(m\) holds 60 in row 3: .*table \(the default\)",
        meta={k: v for k, v in META.items() if k != "table_size"},
        push_distance=_with(chain, "push_distance", 3, 60.0),
    )
    boxes = np.full((12, 3, 3), 0.05)
    boxes[7, 2] = (60.0, 40.0, 30.0)
    refused(
        r"'object_size' \(m\) holds 60 in row 7: a box longer than the table's diagonal",
        cloud_points=None,
        cloud_normals=None,
        object_size=boxes,
    )
    refused(  # a turn of 20 degrees given in degrees
        r"'state_after' turns object 0 by 20 rad from 'traj_objects' in row 2: consecutive yaws "
        r"of one push differ by more than pi, .*wrapped into \(-pi, pi\] or given in degrees.*"
        r"angles='wrapped'",
        state_after=_with(chain, "state_after", (2, 0, 2), chain["traj_objects"][2, -1, 0, 2] + 20),
    )
    shifted, wrapped, row = _shifted_and_wrapped(chain)
    refused(r"turns object \d by -?6\.\d+ rad from .* in row \d+.*look wrapped", arrays=wrapped)
    reference = observation_dataset(shifted, NAMES, META)
    back = observation_dataset(wrapped, NAMES, META, angles="wrapped")
    turn = back["state_after"][row, 0, 2] - back["state_before"][row, 0, 2]
    assert abs(turn) < np.pi
    np.testing.assert_allclose(back["effect"], reference["effect"], atol=1e-9)
    np.testing.assert_allclose(back["effect"], chain["effect"], atol=1e-9)
    series = np.concatenate(
        [
            back["state_before"][:, None, :, 2],
            back["traj_objects"][..., 2],
            back["state_after"][:, None, :, 2],
        ],
        axis=1,
    )
    assert np.abs(np.diff(series, axis=1)).max() < np.pi  # every step within pi
    assert wrapped["state_after"][row, 0, 2] != back["state_after"][row, 0, 2]  # not changed
    with pytest.raises(InputError, match=r"angles must be 'unwrapped' .* or 'wrapped'"):
        observation_dataset(_push_arrays(chain), NAMES, META, angles="radians")
