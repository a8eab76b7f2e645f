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
