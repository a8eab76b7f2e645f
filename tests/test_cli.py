"""The `probaff` command line."""

import json

from probaff.cli import main


def test_generate_and_describe(tmp_path, capsys, generate_cli):
    out = tmp_path / "ds"
    assert generate_cli("near_obstacle", 6, out, "--seed", "2", "--shard-size", "4") == 0
    capsys.readouterr()
    assert main(["describe", str(out)]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["n_pushes"] == 6
    assert summary["objects"]["o2"]["mean_abs_effect"]["dz_p_m"] < 0.002  # the battery
    assert set(summary["object_counts"]) == {"book", "battery"}
    for key in ("fraction_moved_gt_1cm", "fraction_fell_off"):
        assert key in summary["objects"]["o1"]


def test_existing_output_needs_resume(tmp_path, capsys, generate_cli):
    out = tmp_path / "ds"
    out.mkdir()
    (out / "something").write_text("x")
    code = generate_cli("two_objects", 2, out)
    assert code == 2
    assert "--resume" in capsys.readouterr().err


def test_unknown_scene_and_corrupt_dataset(tmp_path, capsys, generate_cli):
    assert generate_cli("garage", 2, tmp_path / "a") == 2
    assert "unknown scene 'garage'" in capsys.readouterr().err
    assert main(["describe", str(tmp_path)]) == 2
    assert "not a probaff dataset" in capsys.readouterr().err


def test_negative_count(tmp_path, capsys, generate_cli):
    assert generate_cli("two_objects", -3, tmp_path / "a") == 2
    assert "n must be a positive integer" in capsys.readouterr().err


def test_demo_flags_are_checked_before_any_work(tmp_path, capsys):
    # the whole demo runs once, through this command, in tests/test_demo.py
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--n", "0", "--quiet"]) == 2
    assert capsys.readouterr().err == (
        "probaff demo: error: n must be a positive integer, got 0.\n"
    )
    assert not out.exists()
    assert main(["demo", "--out", str(out), "--office-scenes", "1", "--quiet"]) == 2
    assert capsys.readouterr().err == (
        "probaff demo: error: office_scenes must be an integer >= 2, got 1.\n"
    )
    assert not out.exists()


def test_scenes_listing(capsys):
    assert main(["scenes"]) == 0
    assert "two_objects" in capsys.readouterr().out


def test_study_subcommand_runs_the_registered_studies_with_their_flags(capsys, tmp_path):
    from probaff.cli import main
    from probaff.experiments import STUDIES

    assert main(["study", "--help"]) == 0
    assert f"studies: {', '.join(STUDIES)}" in capsys.readouterr().out
    assert main(["study", "nope"]) == 2
    assert "unknown study 'nope'" in capsys.readouterr().err
    out = str(tmp_path / "out")
    assert main(["study", "planning", "--trials", "0", "--out", out]) == 2
    err = capsys.readouterr().err
    assert err == "probaff study planning: error: trials must be a positive integer, got 0.\n"


def test_export_and_import_round_trip_an_hdf5_file(tmp_path, capsys):
    from probaff.data.generation import GenerateConfig, generate

    ds = tmp_path / "ds"
    config = GenerateConfig("two_objects", 5, seed=3, shard_size=2, cloud_points=8)
    generate(config, ds, workers=0, progress=False)
    file = tmp_path / "ds.h5"
    assert main(["export", str(ds), "--to", str(file)]) == 0
    assert capsys.readouterr().out == f"wrote 5 rows of {ds} to {file}\n"
    back = tmp_path / "back"
    assert main(["import", str(file), "--out", str(back)]) == 0
    assert capsys.readouterr().out == f"wrote 5 rows of {file} to {back}\n"
    files = sorted(p.relative_to(ds) for p in ds.rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(back) for p in back.rglob("*") if p.is_file())
    assert all((ds / p).read_bytes() == (back / p).read_bytes() for p in files)
    # bad input: one line each, exit status 2, nothing written or lost
    before = (back / "manifest.json").read_bytes()
    assert main(["import", str(file), "--out", str(back)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("probaff import: error: ") and err.count("\n") == 1
    assert "already holds a push dataset" in err
    assert (back / "manifest.json").read_bytes() == before
    (tmp_path / "junk.h5").write_bytes(b"\x89HDF\r\n" + bytes(100))
    assert main(["import", str(tmp_path / "junk.h5"), "--out", str(tmp_path / "x")]) == 2
    assert "not a readable HDF5 file" in capsys.readouterr().err
    assert main(["export", str(tmp_path / "none"), "--to", str(tmp_path / "y.h5")]) == 2
    assert "not a probaff dataset" in capsys.readouterr().err
    assert not (tmp_path / "x").exists() and not (tmp_path / "y.h5").exists()


def test_generate_with_a_compliant_hand_records_it(tmp_path, capsys):
    from probaff.data.store import read_manifest

    out = tmp_path / "soft"
    argv = ["generate", "--scene", "near_obstacle", "--n", "2", "--seed", "1", "--out"]
    assert main([*argv, str(out), "--workers", "0", "--hand", "compliant", "--quiet"]) == 0
    capsys.readouterr()
    manifest = read_manifest(out)
    assert "compliant" in json.dumps(manifest)
