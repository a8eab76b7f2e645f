"""probaff installs as packages are installed: a built wheel carries the world descriptions.

Covers the packaging configuration in pyproject.toml and probaff.sim.world_files.worlds_dir:
the world descriptions (``worlds/``, their one source) ship as the package data
``probaff/worlds``; a wheel built from a copy of the sources, installed into a fresh virtual
environment outside the repository, generates pushes, fits a model and lists the scenes.
"""

import os
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest

from probaff.errors import ConfigError
from probaff.sim.world_files import worlds_dir

REPO = Path(__file__).resolve().parents[1]
WORLD_FILES = sorted(
    p.relative_to(REPO / "worlds").as_posix()
    for p in (REPO / "worlds").rglob("*")
    if p.is_file() and "__pycache__" not in p.parts
)


def _setuptools_table():
    tomllib = pytest.importorskip("tomllib")  # Python >= 3.11
    return tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]


def test_every_package_folder_is_listed_and_worlds_is_the_data_package():
    table = _setuptools_table()
    folders = {
        ".".join(p.parent.relative_to(REPO).parts) for p in (REPO / "probaff").rglob("__init__.py")
    }
    data = {"probaff.worlds"} | {
        f"probaff.worlds.{p.name}" for p in (REPO / "worlds").iterdir() if p.is_dir()
    }
    assert set(table["packages"]) == folders | data
    assert table["package-dir"] == {"probaff.worlds": "worlds"}
    assert not (REPO / "probaff" / "worlds").exists()  # worlds/ stays the one source


def test_a_checkout_reads_its_worlds_folder_unless_probaff_worlds_is_set(tmp_path, monkeypatch):
    monkeypatch.delenv("PROBAFF_WORLDS", raising=False)
    assert worlds_dir() == REPO / "worlds"
    shutil.copy(REPO / "worlds" / "tabletop.yaml", tmp_path / "tabletop.yaml")
    monkeypatch.setenv("PROBAFF_WORLDS", str(tmp_path))
    assert worlds_dir() == tmp_path
    monkeypatch.setenv("PROBAFF_WORLDS", str(tmp_path / "missing"))
    with pytest.raises(
        ConfigError, match=r"PROBAFF_WORLDS is .*missing, which holds no world descriptions"
    ):
        worlds_dir()


_INSTALLED_RUN = """
import os, pathlib, shutil, sys
import numpy as np
import probaff
from probaff.data import GenerateConfig, generate
from probaff.features import chapter4_features
from probaff.models import MixtureOfGPExperts, fit_em
from probaff.sim.world_files import worlds_dir

site = pathlib.Path(sys.argv[1]).resolve()
assert pathlib.Path(probaff.__file__).resolve().is_relative_to(site), probaff.__file__
assert worlds_dir().resolve().is_relative_to(site), worlds_dir()
os.environ["PROBAFF_WORLDS"] = str(shutil.copytree(worlds_dir(), "my_worlds"))
assert worlds_dir() == pathlib.Path("my_worlds")
ds = generate(GenerateConfig("single_free", 4, seed=0, shard_size=4), "ds", progress=False)
model = MixtureOfGPExperts(1)
fit_em(model, chapter4_features(ds).values, ds["effect"][:, 0], max_iter=1, seed=0)
mean = model.predict(chapter4_features(ds).values).mean.numpy()
assert mean.shape == (4, 3) and np.isfinite(mean).all()
print("installed run:", len(ds), "pushes")
"""


def _venv_with_dependencies(root: Path) -> tuple[Path, Path]:
    """A fresh virtual environment at `root` whose dependencies are those of this interpreter.

    Returns:
        Its python and its site-packages. A ``.pth`` line adds this interpreter's
        site-packages after the environment's own (the ``.pth`` files there, among them an
        editable install's finder, are not run), so the environment's probaff is the one
        imported.
    """
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(root)], check=True)
    python = root / ("Scripts/python.exe" if os.name == "nt" else "bin/python")
    site = subprocess.run(
        [str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    ours = {sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]}
    (Path(site) / "_probaff_test_dependencies.pth").write_text("\n".join(sorted(ours)) + "\n")
    return python, Path(site)


@pytest.mark.slow
def test_a_built_wheel_runs_from_a_fresh_environment_outside_the_repository(tmp_path):
    src = tmp_path / "src"
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    shutil.copytree(REPO / "probaff", src / "probaff", ignore=ignore)
    shutil.copytree(REPO / "worlds", src / "worlds", ignore=ignore)
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(REPO / name, src / name)
    wheels = tmp_path / "wheels"
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "-q"]
    subprocess.run(
        [*pip, "wheel", str(src), "--no-deps", "--no-build-isolation", "--no-index", "-w", wheels],
        check=True,
        cwd=tmp_path,
    )
    (wheel,) = wheels.glob("probaff-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    assert {f"probaff/worlds/{f}" for f in WORLD_FILES} <= names
    assert "probaff/py.typed" in names and "probaff/demo.py" in names

    python, site = _venv_with_dependencies(tmp_path / "venv")
    install = [*pip, "--python", str(python), "install", "--no-deps", "--no-index", str(wheel)]
    subprocess.run(install, check=True, cwd=tmp_path)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PROBAFF_WORLDS")}
    work = tmp_path / "work"
    work.mkdir()
    run = subprocess.run(
        [str(python), "-c", _INSTALLED_RUN, str(site)],
        capture_output=True,
        text=True,
        cwd=work,
        env=env,
    )
    assert run.returncode == 0, run.stderr
    assert "installed run: 4 pushes" in run.stdout
    scenes = subprocess.run(
        [str(python.parent / "probaff"), "scenes"],
        capture_output=True,
        text=True,
        cwd=work,
        env=env,
    )
    assert scenes.returncode == 0, scenes.stderr
    listed = {line.split()[0] for line in scenes.stdout.splitlines()}
    assert {"two_objects", "single_free", "pick", "place"} <= listed
