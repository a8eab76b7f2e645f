"""Flags from config fields: types, nested options and their aliases, ``--smoke``.

Covers probaff.experiments.config_cli.
"""

import argparse
import dataclasses

import pytest

from probaff.experiments.config_cli import (
    add_config_arguments,
    config_from_args,
    flag_values,
    parse_study_args,
    with_smoke,
)
from probaff.experiments.push_models import PushModelStudyConfig


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
        "--svi-n-steps",
        "7",
        "--methods",
        "em",
    )
    assert cfg.ch5_experts == (1, 3) and cfg.pose_noise is False and cfg.workers is None
    assert cfg.svi.n_steps == 7 and cfg.methods == ("em",)


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
    from probaff.experiments.config_cli import study_config, study_parser
    from probaff.experiments.modular import SMOKE as SMOKE_OVERRIDES
    from probaff.experiments.modular import ModularStudyConfig

    parser = study_parser(ModularStudyConfig, "doc")
    cfg = study_config(
        ModularStudyConfig,
        parser.parse_args(["--smoke", "--trials", "5", "--n-experts", "3"]),
        SMOKE_OVERRIDES,
    )
    assert cfg.trials == 5 and cfg.settings.n_experts == 3  # the user's
    assert cfg.push_train == SMOKE_OVERRIDES["push_train"]  # the smoke size
    assert cfg.settings.em.max_iter == SMOKE_OVERRIDES["settings"]["em"]["max_iter"]
    # Without --smoke nothing changes; a value equal to the default still counts as given.
    plain = study_config(ModularStudyConfig, parser.parse_args(["--trials", "5"]), SMOKE_OVERRIDES)
    assert plain == dataclasses.replace(ModularStudyConfig(), trials=5)
    given = study_config(
        ModularStudyConfig,
        parser.parse_args(["--smoke", "--push-train", "221"]),
        SMOKE_OVERRIDES,
    )
    assert given.push_train == 221


def test_the_modular_study_takes_its_gp_settings_as_flags_of_one_gp_options():
    from probaff.experiments.config_cli import settings_view, study_config, study_parser
    from probaff.experiments.modular import SMOKE as SMOKE_OVERRIDES
    from probaff.experiments.modular import ModularStudyConfig
    from probaff.models import TRANSITION_GP

    parser = study_parser(ModularStudyConfig, "doc")
    smoke = study_config(ModularStudyConfig, parser.parse_args(["--smoke"]), SMOKE_OVERRIDES)
    assert smoke.settings.gp == dataclasses.replace(
        TRANSITION_GP, max_iter=10, lengthscale_prior=True
    )
    args = parser.parse_args(["--smoke", "--gp-max-iter", "7", "--gp-lengthscale-prior", "0.5"])
    given = study_config(ModularStudyConfig, args, SMOKE_OVERRIDES).settings.gp
    assert (given.max_iter, given.lengthscale_prior, given.noise_floor) == (7, 0.5, "auto")
    view = settings_view(ModularStudyConfig().settings)
    assert view["gp_max_iter"] == 50 and view["gp_lengthscale_prior"] is True


def test_a_bad_value_is_refused_even_under_smoke():
    from probaff.errors import InputError
    from probaff.experiments.config_cli import study_config, study_parser
    from probaff.experiments.modular import SMOKE as SMOKE_OVERRIDES
    from probaff.experiments.modular import ModularStudyConfig

    parser = study_parser(ModularStudyConfig, "doc")
    with pytest.raises(InputError, match="n_experts must be a positive integer, got 0"):
        study_config(
            ModularStudyConfig, parser.parse_args(["--n-experts", "0", "--smoke"]), SMOKE_OVERRIDES
        )


def test_options_flags_keep_the_fit_names():
    cfg = _parse("--em-max-iter", "4", "--em-n-restarts", "2", "--svi-n-steps", "9")
    assert (cfg.em.max_iter, cfg.em.n_restarts, cfg.svi.n_steps) == (4, 2, 9)
    assert _parse("--gp-lengthscale-prior", "false").gp.lengthscale_prior is False
    assert _parse("--gp-lengthscale-prior", "1.5").gp.lengthscale_prior == 1.5
    for old in ("--em-iterations", "--em-restarts", "--vi-steps", "--lengthscale-prior"):
        with pytest.raises(SystemExit):  # no second name for a flag
            _parse(old, "4")
    assert cfg.em.init == "auto" and cfg.em.tol == PushModelStudyConfig().em.tol  # no flag
    values = flag_values(cfg)
    assert values["em_max_iter"] == 4 and values["svi_n_steps"] == 9 and "em_tol" not in values


def test_a_bad_option_is_named_by_the_flag_the_user_typed():
    from probaff.errors import InputError

    with pytest.raises(InputError, match=r"^em_max_iter must be a positive integer, got 0"):
        parse_study_args(PushModelStudyConfig, {}, "doc", ["--em-max-iter", "0"])
    with pytest.raises(InputError, match=r"^em_init: unknown initialisation 'x'"):
        parse_study_args(PushModelStudyConfig, {}, "doc", ["--em-init", "x"])


def test_shorthands_count_as_given_under_smoke():
    from probaff.experiments.push_models import SMOKE

    cfg = parse_study_args(PushModelStudyConfig, SMOKE, "doc", ["--smoke", "--no-ch4"])
    assert cfg.ch4_pushes == 0 and cfg.ch5_pushes == SMOKE["ch5_pushes"]
    assert (
        parse_study_args(PushModelStudyConfig, SMOKE, "doc", ["--exact-poses"]).pose_noise is False
    )


def test_smoke_sizes_of_nested_options_replace_only_their_fields():
    base = PushModelStudyConfig(em=dataclasses.replace(PushModelStudyConfig().em, tol=0.5))
    cfg = with_smoke(base, {"em": {"max_iter": 2}, "gp": {"max_iter": 8}})
    assert (cfg.em.max_iter, cfg.em.tol, cfg.gp.max_iter) == (2, 0.5, 8)
    assert cfg.gp.lengthscale_prior is True  # the study's default, not GPOptions'
    assert with_smoke(base, {"em": {"max_iter": 2}}, given={"em_max_iter"}) == base


def test_settings_are_named_as_their_flags():
    from probaff.experiments.config_cli import settings_view

    view = settings_view(PushModelStudyConfig())
    assert view["em_max_iter"] == 10 and view["em_n_restarts"] == 3 and view["em_init"] == "auto"
    assert view["svi_n_steps"] == 100 and view["gp_max_iter"] == 50
    assert view["gp_lengthscale_prior"] is True
    assert not any(k.startswith(("em_tol", "svi_lr", "gp_noise")) for k in view)
    tuned = PushModelStudyConfig(em=dataclasses.replace(PushModelStudyConfig().em, tol=0.5))
    assert settings_view(tuned)["em_tol"] == 0.5  # a setting with no flag counts once changed
    assert tuned.tag(version=1) != PushModelStudyConfig().tag(version=1)
