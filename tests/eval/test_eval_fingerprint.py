import dataclasses

import pytest

from probaff.eval.fingerprint import config_fingerprint


@dataclasses.dataclass(frozen=True)
class _Options:
    damping: float = 0.5


@dataclasses.dataclass(frozen=True)
class _Config:
    out: str = "results/x"
    workers: int = 0
    seed: int = 0
    sizes: tuple[int, ...] = (1, 2)
    options: _Options = _Options()


RUN_ONLY = ("out", "workers")


def test_run_only_fields_do_not_change_the_fingerprint():
    base = config_fingerprint(_Config(), exclude=RUN_ONLY)
    assert config_fingerprint(_Config(out="elsewhere", workers=4), exclude=RUN_ONLY) == base


@pytest.mark.parametrize(
    "change", [{"seed": 1}, {"sizes": (1, 2, 3)}, {"options": _Options(damping=0.4)}]
)
def test_every_other_field_changes_it(change):
    base = config_fingerprint(_Config(), exclude=RUN_ONLY)
    assert config_fingerprint(_Config(**change), exclude=RUN_ONLY) != base


def test_version_changes_it_and_length_is_kept():
    a = config_fingerprint(_Config(), version=1, length=8)
    assert len(a) == 8 and a != config_fingerprint(_Config(), version=2, length=8)


def test_not_a_dataclass():
    with pytest.raises(TypeError, match="dataclass instance"):
        config_fingerprint({"seed": 0})


def test_settings_by_name_hash_like_the_dataclass():
    from probaff.eval.fingerprint import settings_fingerprint

    fields = {f.name: getattr(_Config(), f.name) for f in dataclasses.fields(_Config())}
    assert settings_fingerprint(fields) == config_fingerprint(_Config())
