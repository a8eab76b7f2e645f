"""The study tests' helpers report failed checks in detail, like the tests themselves."""

import pytest

pytest.register_assert_rewrite("study_helpers")
