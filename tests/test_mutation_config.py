"""The mutation-testing map (``[tool.hier_ssl.mutation]``, read by ``.ci/mutation``) names modules and
test files that exist, each module with tests of its own."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

tomllib = pytest.importorskip("tomllib" if sys.version_info >= (3, 11) else "tomli")

ROOT = Path(__file__).parents[1]


def test_every_mapped_module_and_test_file_exists() -> None:
    with open(ROOT / "pyproject.toml", "rb") as f:
        mapping = tomllib.load(f)["tool"]["hier_ssl"]["mutation"]
    assert mapping
    for module, tests in mapping.items():
        assert module.startswith("hier_ssl/") and (ROOT / module).is_file()
        assert tests
        assert all((ROOT / test).is_file() and Path(test).name.startswith("test_") for test in tests)


def test_mutmut_settings_leave_the_module_and_its_tests_to_the_script() -> None:
    with open(ROOT / "pyproject.toml", "rb") as f:
        settings = tomllib.load(f)["tool"]["mutmut"]
    assert "only_mutate" not in settings and "pytest_add_cli_args_test_selection" not in settings
