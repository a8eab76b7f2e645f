"""The build's list of packages, discovered: every package of ``probaff/`` and the world data.

pyproject.toml holds the project's metadata and every other setting; this file only finds the
packages, which the TOML table cannot do here: the world descriptions ship as the data package
``probaff.worlds`` mapped onto the repository's ``worlds/`` folder (their one source, see
``[tool.setuptools.package-dir]``), where setuptools' ``packages.find`` does not look. So a new
subpackage of probaff (a folder with an ``__init__.py``) and a new folder of ``worlds/`` are
packaged with nothing edited; tests/test_packaging.py builds a wheel and checks both.
"""

from pathlib import Path

from setuptools import find_namespace_packages, find_packages, setup

ROOT = Path(__file__).resolve().parent

setup(
    packages=[
        *find_packages(str(ROOT), include=["probaff", "probaff.*"]),
        "probaff.worlds",
        *(
            f"probaff.worlds.{name}"
            for name in find_namespace_packages(str(ROOT / "worlds"), exclude=["*__pycache__*"])
        ),
    ]
)
