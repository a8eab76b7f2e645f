"""The API reference builds from the docstrings without a warning, broken references included."""

import html
import importlib
import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
SUBPACKAGES = (
    "models",
    "maps",
    "sim",
    "data",
    "perception",
    "features",
    "planning",
    "eval",
    "experiments",
)
MISSING = [
    name for name in ("sphinx", "myst_parser", "furo") if importlib.util.find_spec(name) is None
]
needs_sphinx = pytest.mark.skipif(
    bool(MISSING),
    reason=f"the docs need {', '.join(MISSING)}: pip install -e '.[docs]' (or '.[test]')",
)


def _extension():
    spec = importlib.util.spec_from_file_location("probaff_api", DOCS / "_ext" / "probaff_api.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def build(tmp_path_factory):
    """The HTML reference, built as the README says: any warning fails it, but it is written.

    One setting differs: Sphinx's plain theme instead of furo. The pages, their anchors,
    links and warnings are the same; furo's navigation tree, drawn again for each of the
    230 pages, is half of the build's time and nothing here checks it.
    """
    out = tmp_path_factory.mktemp("docs") / "html"
    cmd = [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-n", "-b", "html"]
    cmd += ["-D", "html_theme=basic"]
    done = subprocess.run(
        [*cmd, str(DOCS), str(out)], cwd=ROOT, capture_output=True, text=True, timeout=600
    )
    return done, out


@pytest.fixture(scope="module")
def site(build):
    return build[1]


def _public_modules(sub):
    """The public modules and nested packages of `probaff.SUB`, by dotted name."""
    for path in sorted((ROOT / "probaff" / sub).rglob("*.py")):
        parts = path.relative_to(ROOT).with_suffix("").parts
        if path.name == "__init__.py":
            parts = parts[:-1]
        if not any(part.startswith("_") for part in parts):
            yield ".".join(parts)


def _page(site, module):
    """The page of `module`: ``api/SUB.html`` for a subpackage, else ``api/modules/NAME.html``."""
    if module.count(".") == 1:
        return site / "api" / f"{module.split('.')[1]}.html"
    return site / "api" / "modules" / f"{module}.html"


@needs_sphinx
@pytest.mark.slow
def test_docs_build_without_warnings(build):
    done, out = build
    assert done.returncode == 0, done.stderr[-8000:]
    assert "build succeeded." in done.stdout, done.stdout[-2000:]
    pages = {p.relative_to(out).as_posix() for p in out.rglob("*.html")}
    expected = {"index.html", "getting_started.html", "api/index.html", "api/probaff.html"}
    assert expected | {f"api/{sub}.html" for sub in SUBPACKAGES} <= pages


@needs_sphinx
@pytest.mark.slow
def test_every_public_name_is_described(site):
    ids = {
        i
        for p in (site / "api").rglob("*.html")
        for i in re.findall(r'id="([^"]+)"', p.read_text())
    }
    for sub in SUBPACKAGES:
        package = importlib.import_module(f"probaff.{sub}")
        for name in package.__all__:
            obj = getattr(package, name)
            home = getattr(obj, "__module__", None) or package.__name__
            if home.startswith(package.__name__):  # else: described where it is defined
                assert f"{package.__name__}.{name}" in ids, f"{package.__name__}.{name}"


@needs_sphinx
@pytest.mark.slow
def test_every_public_module_has_a_page(site):
    for sub in SUBPACKAGES:
        index = (site / "api" / f"{sub}.html").read_text()
        for module in _public_modules(sub):
            page = _page(site, module)
            assert page.is_file(), module
            # the module's index target, or its title's slug where the package exports an
            # object under the module's name (not indexed)
            slug = re.sub(r"[._]", "-", module)
            assert any(f'id="{i}"' in page.read_text() for i in (f"module-{module}", slug))
            if module.count(".") == 2:  # listed on its subpackage's page
                assert f'href="modules/{module}.html"' in index, module


@needs_sphinx
@pytest.mark.slow
def test_pages_are_per_module(site):
    largest = max(p.stat().st_size for p in (site / "api").rglob("*.html"))
    assert largest < 300_000, largest  # one page per subpackage was up to 900 kB


@needs_sphinx
@pytest.mark.slow
def test_single_backtick_names_are_links(site):
    page = (site / "api" / "modules" / "probaff.models.mixture.model.html").read_text()
    # `fit_em` in MixtureOfGPExperts's docstring names the function it is described under
    assert re.search(
        r'<a class="reference internal" href="probaff\.models\.mixture\.em\.html#'
        r'probaff\.models\.fit_em"[^>]*><code class="xref py py-obj',
        page,
    )
    # an argument's name stays code
    assert (
        '<code class="xref py py-obj docutils literal notranslate"><span class="pre">'
        "n_experts</span></code>" in page
    )


@needs_sphinx
@pytest.mark.slow
def test_getting_started_shows_the_readme_examples(site):
    page = (site / "getting_started.html").read_text()
    readme = (ROOT / "README.md").read_text()
    before = readme.split("## Studies, notebooks, benchmarks", 1)[0]
    blocks = re.findall(r"```python\n(.*?)```", before, re.S)
    assert blocks
    text = html.unescape(re.sub(r"<[^>]+>", "", page))
    for block in blocks:
        for line in filter(None, map(str.strip, block.splitlines())):
            assert line in text, line


@needs_sphinx
@pytest.mark.slow
def test_type_annotations_link_to_the_reference(site):
    page = (site / "api" / "modules" / "probaff.models.mixture.em.html").read_text()
    # fit_em's `model` is annotated with the class where its module defines it; the link goes
    # to the class's description, under the name the package exports it by.
    href = 'href="probaff.models.mixture.model.html#probaff.models.MixtureOfGPExperts"'
    assert f'{href} title="probaff.models.mixture.model.MixtureOfGPExperts"' in page


@needs_sphinx
def test_attribute_docstrings_keep_their_leading_words():
    from sphinx.ext.napoleon import Config
    from sphinx.ext.napoleon.docstring import GoogleDocstring

    doc = ["(N, K) bool: which object slots hold an object."]
    lines = GoogleDocstring(doc, Config(), what="property", name="present").lines()
    assert lines[-1].startswith(":type: (N, K) bool")  # napoleon took the words for a type
    _extension().keep_attribute_prose(None, "property", "present", None, None, lines)
    assert [line for line in lines if line] == doc


@needs_sphinx
def test_names_resolve_in_the_module_that_writes_them():
    ext = _extension()
    import numpy as np
    import torch

    from probaff.models.mixture import model as mixture
    from probaff.models.transitions import chain

    assert ext._lookup("Tensor", vars(mixture)) is torch.Tensor
    assert ext._lookup("np.ndarray", vars(chain)) is np.ndarray
    assert ext._lookup("probaff.models.MixtureOfGPExperts", {}) is mixture.MixtureOfGPExperts
    assert ext._lookup("Tensor", vars(chain)) is ext._MISSING
