"""`probaff demo`'s settings are checked before any work (the whole demo runs in
tests/test_cli.py::test_demo_smoke).

Covers probaff.demo.
"""

import pytest

from probaff.demo import DemoConfig, run
from probaff.errors import InputError


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("n", 0, "n must be a positive integer, got 0"),
        ("seed", -1, "seed must be an integer >= 0, got -1"),
        ("workers", -1, "workers must be an integer >= 0, got -1"),
    ],
)
def test_bad_settings_are_refused_before_any_work(tmp_path, field, value, message):
    with pytest.raises(InputError, match=message):
        run(DemoConfig(out=str(tmp_path / "demo"), **{field: value}))
    assert not (tmp_path / "demo").exists()
