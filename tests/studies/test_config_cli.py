import argparse
import dataclasses

import pytest

from probaff.studies.config_cli import add_config_arguments, config_from_args
from probaff.studies.push_models import PushModelStudyConfig


def _parse(*argv: str) -> PushModelStudyConfig:
    parser = argparse.ArgumentParser()
    add_config_arguments(parser, PushModelStudyConfig)
    return config_from_args(PushModelStudyConfig, parser.parse_args(list(argv)))


def test_defaults_are_the_config_defaults():
    assert _parse() == PushModelStudyConfig()


def test_every_field_has_a_flag_with_its_help():
    parser = argparse.ArgumentParser()
    add_config_arguments(parser, PushModelStudyConfig)
    text = parser.format_help()
    for f in dataclasses.fields(PushModelStudyConfig):
        assert "--" + f.name.replace("_", "-") in text
    assert "Two-object pushes." in text


def test_types_tuples_booleans_and_none():
    cfg = _parse(
        "--ch5-experts",
        "1,3",
        "--no-pose-noise",
        "--workers",
        "none",
        "--vi-steps",
        "7",
        "--methods",
        "em",
    )
    assert cfg.ch5_experts == (1, 3) and cfg.pose_noise is False and cfg.workers is None
    assert cfg.vi_steps == 7 and cfg.methods == ("em",)


def test_a_malformed_value_exits_2(capsys):
    with pytest.raises(SystemExit) as err:
        _parse("--ch5-experts", "1,x")
    assert err.value.code == 2
    assert "comma-separated int" in capsys.readouterr().err


def test_overrides_win():
    parser = argparse.ArgumentParser()
    add_config_arguments(parser, PushModelStudyConfig, skip=("out",))
    cfg = config_from_args(PushModelStudyConfig, parser.parse_args([]), out="elsewhere")
    assert cfg.out == "elsewhere"


def test_smoke_sizes_never_replace_a_value_the_user_gave():
    from probaff.studies.config_cli import study_config, study_parser
    from probaff.studies.modular import SMOKE_OVERRIDES, ModularStudyConfig

    parser = study_parser(ModularStudyConfig, "doc")
    cfg = study_config(
        ModularStudyConfig,
        parser.parse_args(["--smoke", "--trials", "5", "--n-experts", "3"]),
        SMOKE_OVERRIDES,
    )
    assert cfg.trials == 5 and cfg.settings.n_experts == 3  # the user's
    assert cfg.push_train == SMOKE_OVERRIDES["push_train"]  # the smoke size
    assert cfg.settings.em_iterations == SMOKE_OVERRIDES["settings"].em_iterations
    # Without --smoke nothing changes; a value equal to the default still counts as given.
    plain = study_config(ModularStudyConfig, parser.parse_args(["--trials", "5"]), SMOKE_OVERRIDES)
    assert plain == dataclasses.replace(ModularStudyConfig(), trials=5)
    given = study_config(
        ModularStudyConfig,
        parser.parse_args(["--smoke", "--push-train", "221"]),
        SMOKE_OVERRIDES,
    )
    assert given.push_train == 221


def test_a_bad_value_is_refused_even_under_smoke():
    from probaff.errors import InputError
    from probaff.studies.config_cli import study_config, study_parser
    from probaff.studies.modular import SMOKE_OVERRIDES, ModularStudyConfig

    parser = study_parser(ModularStudyConfig, "doc")
    with pytest.raises(InputError, match="n_experts must be a positive integer, got 0"):
        study_config(
            ModularStudyConfig, parser.parse_args(["--n-experts", "0", "--smoke"]), SMOKE_OVERRIDES
        )
