"""probaff installs as packages are installed: a built wheel carries the world descriptions.

Covers the packaging configuration (pyproject.toml, and setup.py's package discovery) and
probaff.sim.world_files.worlds_dir: the packages are found by the build, not listed, and the
world descriptions (``worlds/``, their one source) ship as the package data ``probaff/worlds``.
A wheel built from a copy of the sources, with a new subpackage and a new folder of world files
added and nothing else edited, carries every package and every world file; installed into a
fresh virtual environment outside the repository, it generates pushes, fits a model and lists
the scenes.
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
NEW_PACKAGE = "probaff/zz_new_subpackage/__init__.py"
NEW_WORLD_FILE = "zz_new_scenes/zz_new.yaml"


def _setuptools_table():
    tomllib = pytest.importorskip("tomllib")  # Python >= 3.11
    return tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """A wheel built offline from a copy of the sources, plus one new package and world folder.

    The new subpackage (``NEW_PACKAGE``) and world file (``NEW_WORLD_FILE``) are added to the
    copy with nothing else edited, as a new study, world or subpackage would be.
    """
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src"
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    shutil.copytree(REPO / "probaff", src / "probaff", ignore=ignore)
    shutil.copytree(REPO / "worlds", src / "worlds", ignore=ignore)
    for name in ("pyproject.toml", "setup.py", "README.md"):
        shutil.copy(REPO / name, src / name)
    for new in (src / NEW_PACKAGE, src / "worlds" / NEW_WORLD_FILE):
        new.parent.mkdir()
        new.write_text("")
    wheels = tmp / "wheels"
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "-q"]
    subprocess.run(
        [*pip, "wheel", str(src), "--no-deps", "--no-build-isolation", "--no-index", "-w", wheels],
        check=True,
        cwd=tmp,
    )
    (built,) = wheels.glob("probaff-*.whl")
    return built


def test_the_packages_are_discovered_and_worlds_is_the_data_package():
    table = _setuptools_table()
    assert "packages" not in table  # setup.py discovers them
    assert table["package-dir"] == {"probaff.worlds": "worlds"}
    assert not (REPO / "probaff" / "worlds").exists()  # worlds/ stays the one source


def test_the_wheel_carries_every_package_module_and_world_file(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    modules = {
        p.relative_to(REPO).as_posix()
        for p in (REPO / "probaff").rglob("*.py")
        if (p.parent / "__init__.py").is_file()
    }
    packages = {p.rsplit("/", 1)[0] for p in modules}
    assert modules and {f"{p}/__init__.py" for p in packages} <= modules
    assert modules <= names
    assert {f"probaff/worlds/{f}" for f in WORLD_FILES} <= names
    assert "probaff/py.typed" in names and "probaff/demo.py" in names
    assert NEW_PACKAGE in names and f"probaff/worlds/{NEW_WORLD_FILE}" in names


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
def test_a_built_wheel_runs_from_a_fresh_environment_outside_the_repository(wheel, tmp_path):
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "-q"]
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
