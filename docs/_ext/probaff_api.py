"""The reference's pages and name resolution: one page per module, links for names.

``.. probaff-package:: probaff.models`` writes a package's page:

- its docstring and its public face: each name of its ``__all__``, linked to where it is
  described (grouped by the module that defines it), or described here when no public module
  of the package lists it (constants, objects of private modules);
- a "Modules" table of contents with one page per public module (a name starting with ``_`` is
  private), and a "Subpackages" one with one page per nested package, documented the same way
  (the flag ``:no-subpackages:`` leaves them out, for the top-level ``probaff`` page).

``.. probaff-module:: probaff.models.mixture.model`` writes a module's page: its docstring and the
names of its ``__all__`` that it defines, each described once, under the name a user imports it
by (``probaff.models.MixtureOfGPExperts`` for a class the package exports), with links to those
it imports. The pages of modules and nested packages are written into ``api/modules/`` when the
build starts (`write_module_pages`); modules are found with `pkgutil`, so a new module gets its
page without editing the docs. Autodoc records a class's defining module as its canonical
name, so a reference to ``probaff.models.mixture.model.MixtureOfGPExperts`` (as type annotations
write it) finds ``probaff.models.MixtureOfGPExperts``.

Single backticks (the default role, ``probaff-name``) are Python cross-references: a name that
names a probaff object described in the reference is a link, anything else (an argument, a
field, a shape such as ``(N, D)``, a third-party name) stays code, without a warning.

Cross-references that Sphinx cannot resolve by itself are resolved as Python resolves the name
in the module where it is written (`resolve_in_scope`): ``Tensor`` in a module that imports it
from torch is ``torch.Tensor``. The reference links probaff's public names; what resolves to a
third-party or standard-library object, a type variable or a private name (a dotted component
starting with ``_``) is shown as text, unlinked. Written with an explicit role, a name that
resolves to nothing still fails the build (``-n``).
"""

from __future__ import annotations

import builtins
import importlib
import inspect
import pkgutil
import re
import sys
from pathlib import Path
from types import ModuleType
from typing import Any, TypeVar

from docutils import nodes
from docutils.parsers.rst import directives
from docutils.statemachine import StringList
from sphinx import addnodes
from sphinx.application import Sphinx
from sphinx.domains.python import PyXRefRole
from sphinx.environment import BuildEnvironment
from sphinx.pycode import ModuleAnalyzer
from sphinx.transforms.post_transforms import SphinxPostTransform
from sphinx.util.docutils import SphinxDirective
from sphinx.util.nodes import nested_parse_with_titles

# Section adornments below the page title (``=``).
_LEVELS = "-~^\"'`"
# Longest value repr shown after a constant's name; longer values are left to its docstring.
_MAX_VALUE = 72
_MISSING = object()
_NAME = re.compile(r"[A-Za-z_][\w.]*")
_NOT_MODULES: set[str] = set()  # names that failed to import, asked again for each argument


def _heading(text: str, depth: int) -> list[str]:
    return [text, _LEVELS[depth] * len(text), ""]


def _public(module: ModuleType) -> list[str]:
    names = getattr(module, "__all__", None)
    if names is None:
        raise RuntimeError(f"{module.__name__} has no __all__; its public names are undefined")
    return list(names)


def _submodules(package: ModuleType) -> list[ModuleType]:
    """Every public module and subpackage below `package`, depth first, by name."""
    found = []
    for info in sorted(pkgutil.iter_modules(package.__path__), key=lambda i: i.name):
        if not info.name.startswith("_"):
            child = importlib.import_module(f"{package.__name__}.{info.name}")
            found.append(child)
            if info.ispkg:
                found += _submodules(child)
    return found


def _is_api(obj: Any) -> bool:
    """Whether autodoc documents `obj` as a class or function (else it is a constant)."""
    return inspect.isclass(obj) or inspect.isroutine(obj)


def _inside(module_name: str, package: ModuleType) -> bool:
    return module_name == package.__name__ or module_name.startswith(package.__name__ + ".")


def _defined_in(obj: Any, package: ModuleType) -> bool:
    """Whether the class or function `obj` is defined inside `package`."""
    return _inside(getattr(obj, "__module__", None) or "", package)


def _documents(package: ModuleType, name: str, obj: Any) -> bool:
    """Whether `package`'s public face describes `obj` as `name`."""
    if name not in _public(package) or getattr(package, name, _MISSING) is not obj:
        return False
    return not _is_api(obj) or _defined_in(obj, package)


def _documented_by(name: str, obj: Any, ancestors: list[ModuleType]) -> ModuleType | None:
    """The outermost enclosing package whose public face describes `obj` as `name`."""
    return next((a for a in ancestors if _documents(a, name, obj)), None)


def _target(obj: Any, name: str, owner: ModuleType) -> str:
    """The reference target of `obj`: its defining name if it has one, else `owner.name`."""
    if _is_api(obj) and getattr(obj, "__qualname__", None):
        return f"{obj.__module__}.{obj.__qualname__}"
    return f"{owner.__name__}.{name}"


def _attr_doc(
    name: str, obj: Any, modules: list[ModuleType]
) -> tuple[list[str], str | None, ModuleType | None]:
    """The docstring and annotation of constant `obj`, and the first module that defines it."""
    for module in modules:
        if vars(module).get(name, _MISSING) is not obj:
            continue
        analyzer = ModuleAnalyzer.for_module(module.__name__)
        doc = analyzer.find_attr_docs().get(("", name))
        annotation = analyzer.annotations.get(("", name))
        if doc is not None or annotation is not None:
            return [line for line in doc or [] if line is not None], annotation, module
    return [], None, None


def _qualified(annotation: str, scope: ModuleType) -> str:
    """`annotation` with each name replaced by ``~`` and the full name it has in `scope`.

    A constant's annotation is read from its defining module's source, while its description
    sits in another module's context (its package's); qualified names resolve anywhere.
    """

    def qualify(match: re.Match[str]) -> str:
        name = match.group(0)
        if hasattr(builtins, name):
            return name
        obj = _lookup(name, vars(scope))
        if obj is _MISSING:
            return name
        if isinstance(obj, ModuleType):
            return f"~{obj.__name__}"
        if _is_api(obj) and getattr(obj, "__qualname__", None):
            return f"~{obj.__module__}.{obj.__qualname__}"
        return f"~{scope.__name__}.{name}"  # a type alias or constant of `scope`

    parts = re.split(r"""("[^"]*"|'[^']*')""", annotation)  # leave string literals alone
    return "".join(p if i % 2 else _NAME.sub(qualify, p) for i, p in enumerate(parts))


def _constant(name: str, obj: Any, owner: str, modules: list[ModuleType]) -> list[str]:
    doc, annotation, scope = _attr_doc(name, obj, modules)
    lines = [f".. py:data:: {name}", f"   :module: {owner}"]
    if annotation and scope is not None:
        lines.append(f"   :type: {_qualified(annotation, scope)}")
    value = repr(obj)
    if len(value) <= _MAX_VALUE and "\n" not in value:
        lines.append(f"   :value: {value}")
    return [*lines, "", *(f"   {line}" for line in doc), ""]


def _member(full_name: str, obj: Any) -> list[str]:
    if inspect.isclass(obj):
        kind = "exception" if issubclass(obj, BaseException) else "class"
        lines = [f".. auto{kind}:: {full_name}", "   :members:"]
        if obj.__bases__ != (object,):  # "Bases: object" says nothing
            lines.append("   :show-inheritance:")
        return [*lines, ""]
    return [f".. autofunction:: {full_name}", ""]


def _page_ancestors(module: ModuleType) -> list[ModuleType]:
    """The enclosing packages whose pages describe names for `module`'s page, outermost first.

    A top-level subpackage's page is its own root (``probaff``'s face describes only what
    ``probaff`` itself holds), so only ``probaff``'s own modules count ``probaff`` itself.
    """
    parts = module.__name__.split(".")
    names = [".".join(parts[:i]) for i in range(1, len(parts))]
    if len(parts) > 2 or hasattr(module, "__path__"):
        names = names[1:]
    return [importlib.import_module(name) for name in names]


def _home(name: str, obj: Any, package: ModuleType) -> ModuleType | None:
    """The public module of `package` whose page describes the class or function `obj`.

    That is the module that defines `obj` and lists it as `name` in its ``__all__``, when
    `package` is among the packages its page answers to; else None (`package` describes it).
    """
    if not _is_api(obj):
        return None
    module = sys.modules.get(getattr(obj, "__module__", None) or "")
    if module is None or hasattr(module, "__path__") or not _inside(module.__name__, package):
        return None
    if any(part.startswith("_") for part in module.__name__.split(".")):
        return None
    if name not in getattr(module, "__all__", ()) or getattr(module, name, None) is not obj:
        return None
    return module if package in _page_ancestors(module) else None


def _page(module: ModuleType) -> str:
    """The document of `module`'s page (absolute, for ``:doc:``)."""
    return f"/api/modules/{module.__name__}"


def _names_lines(
    module: ModuleType, ancestors: list[ModuleType], modules: list[ModuleType], face: bool
) -> list[str]:
    """Directives for the names of `module`'s ``__all__`` not described by `ancestors`.

    In a package's public face (`face`), a class or function defined outside the package is
    linked, not described, and so is one that a module of the package describes on its page;
    in a module, one defined in another module is linked.
    """
    lines: list[str] = []
    links: dict[str, list[str]] = {}  # the page's wording -> links to the descriptions
    for name in _public(module):
        obj = getattr(module, name)
        owner = _documented_by(name, obj, ancestors)
        elsewhere = _is_api(obj) and (
            not _defined_in(obj, module) if face else obj.__module__ != module.__name__
        )
        home = _home(name, obj, module) if face and owner is None and not elsewhere else None
        described_here = not face and _is_api(obj) and obj.__module__ == module.__name__
        if owner is not None and not described_here:
            where = f"Described under the name its package :py:mod:`{owner.__name__}` exports"
            links.setdefault(where, []).append(f":py:obj:`{name} <{owner.__name__}.{name}>`")
        elif elsewhere:
            where = "Imported from the module that defines it"
            links.setdefault(where, []).append(f":py:obj:`{name} <{_target(obj, name, module)}>`")
        elif home is not None:
            where = f"From :doc:`{home.__name__} <{_page(home)}>`"
            links.setdefault(where, []).append(f":py:obj:`{name} <{module.__name__}.{name}>`")
        elif _is_api(obj):
            lines += _member(f"{(owner or module).__name__}.{name}", obj)
        else:
            lines += _constant(name, obj, module.__name__, [module, *modules])
    for where, names in links.items():
        lines += [f"{where}: {', '.join(names)}.", ""]
    return lines


def _automodule(module: ModuleType) -> list[str]:
    lines = [f".. automodule:: {module.__name__}"]
    parent, _, leaf = module.__name__.rpartition(".")
    if parent and not isinstance(getattr(importlib.import_module(parent), leaf), ModuleType):
        # The package exports an object under this module's name (``features.action_frame``
        # is a function): the object keeps the name, the module's heading is not indexed.
        lines.append("   :no-index:")
    return [*lines, ""]


def _toctree(modules: list[ModuleType]) -> list[str]:
    return [".. toctree::", "   :maxdepth: 1", "", *(f"   {_page(m)}" for m in modules), ""]


def package_lines(package: ModuleType, subpackages: bool = True) -> list[str]:
    """The reST source of `package`'s page: its public face and its modules' pages.

    Args:
        package: The package to document.
        subpackages: List the pages of nested subpackages as well.

    Returns:
        reST lines.
    """
    children = [m for m in _submodules(package) if "." not in _relative(m, package)]
    lines = _automodule(package)
    lines += _names_lines(package, _page_ancestors(package), children, face=True)
    modules = [m for m in children if not hasattr(m, "__path__")]
    if modules:
        lines += _heading("Modules", 0) + _toctree(modules)
    packages = [m for m in children if hasattr(m, "__path__")]
    if subpackages and packages:
        lines += _heading("Subpackages", 0) + _toctree(packages)
    return lines


def module_lines(module: ModuleType) -> list[str]:
    """The reST source of `module`'s page: its docstring and the names it defines.

    Returns:
        reST lines.
    """
    return _automodule(module) + _names_lines(module, _page_ancestors(module), [], face=False)


def _relative(module: ModuleType, package: ModuleType) -> str:
    return module.__name__[len(package.__name__) + 1 :]


class _GeneratedDirective(SphinxDirective):
    required_arguments = 1

    def lines(self, target: ModuleType) -> list[str]:
        raise NotImplementedError

    def run(self) -> list[nodes.Node]:
        """Generate the page's reST and parse it in place, section headings included."""
        target = importlib.import_module(self.arguments[0])
        source = self.lines(target)
        where = f"<{self.name} {target.__name__}>"
        content = StringList(source, items=[(where, i + 1) for i in range(len(source))])
        container = nodes.section()
        container.document = self.state.document
        nested_parse_with_titles(self.state, content, container)
        return container.children


class PackageDirective(_GeneratedDirective):
    """``.. probaff-package:: NAME``: a package's page (see the module docstring)."""

    option_spec = {"no-subpackages": directives.flag}  # noqa: RUF012 (docutils API)

    def lines(self, target: ModuleType) -> list[str]:
        """The package's face and the tables of contents of its modules and subpackages."""
        return package_lines(target, subpackages="no-subpackages" not in self.options)


class ModuleDirective(_GeneratedDirective):
    """``.. probaff-module:: NAME``: a module's page (see the module docstring)."""

    def lines(self, target: ModuleType) -> list[str]:
        """The module's docstring and the names it defines."""
        return module_lines(target)


def write_module_pages(app: Sphinx) -> None:
    """Write ``api/modules/NAME.rst`` for each public module and nested package of probaff.

    The top-level subpackages' pages are ``api/NAME.rst``. A page is rewritten only when its
    text changes (incremental builds stay incremental), and pages of modules that are gone
    are removed.
    """
    folder = Path(app.srcdir) / "api" / "modules"
    folder.mkdir(parents=True, exist_ok=True)
    pages = {}
    for module in _submodules(importlib.import_module("probaff")):
        package = hasattr(module, "__path__")
        if package and module.__name__.count(".") == 1:
            continue
        name = module.__name__
        directive = "probaff-package" if package else "probaff-module"
        pages[f"{name}.rst"] = f"{name}\n{'=' * len(name)}\n\n.. {directive}:: {name}\n"
    for stale in folder.glob("*.rst"):
        if stale.name not in pages:
            stale.unlink()
    for file, text in pages.items():
        path = folder / file
        if not path.is_file() or path.read_text() != text:
            path.write_text(text)


def _lookup(dotted: str, scope: dict[str, Any]) -> Any:
    """The object `dotted` names in `scope` (module globals, then importable modules)."""
    head, *rest = dotted.split(".")
    if head in scope:
        obj = scope[head]
    elif hasattr(builtins, head):
        obj = getattr(builtins, head)
    elif head in _NOT_MODULES:
        return _MISSING
    else:
        try:
            obj = importlib.import_module(head)
        except ImportError:
            _NOT_MODULES.add(head)
            return _MISSING
    for part in rest:
        value = getattr(obj, part, _MISSING)
        if value is _MISSING and isinstance(obj, ModuleType):
            try:
                value = importlib.import_module(f"{obj.__name__}.{part}")
            except ImportError:
                return _MISSING
        if value is _MISSING:
            return _MISSING
        obj = value
    return obj


def _scopes(node: addnodes.pending_xref) -> list[dict[str, Any]]:
    """Module globals a reference may be written in: its object's module, then its context."""
    scopes = []
    parent = node.parent
    while parent is not None and not isinstance(
        parent, (addnodes.desc_content, addnodes.desc_signature)
    ):
        parent = parent.parent
    signature = parent
    if isinstance(parent, addnodes.desc_content):
        signature = parent.parent.next_node(addnodes.desc_signature)
    if signature is not None and signature.get("module"):
        owner = _lookup(f"{signature['module']}.{signature.get('fullname', '')}".rstrip("."), {})
        if owner is not _MISSING:
            origin = getattr(getattr(owner, "fget", owner), "__module__", None)  # fget: property
            origin = origin or signature["module"]
            scopes.append(vars(importlib.import_module(origin)))
    if node.get("py:module"):
        scopes.append(vars(importlib.import_module(node["py:module"])))
    return scopes


class NameRole(PyXRefRole):
    """The default role, ``probaff-name``: a Python cross-reference that may name nothing.

    Docstrings write names of objects, arguments, fields and shapes alike in single backticks
    (`MixtureOfGPExperts`, `n_experts`, `(N, D)`). Each becomes a ``py:obj`` reference,
    marked: where it names a probaff object described in the reference it is a link, and where
    it names nothing (or something outside probaff) it stays code, without a warning.
    """

    def run(self) -> tuple[list[nodes.Node], list[nodes.system_message]]:
        """Make the ``py:obj`` reference and mark it as one that may name nothing."""
        self.name = "py:obj"
        made, messages = super().run()
        for node in made:
            for ref in node.findall(addnodes.pending_xref):
                ref["probaff_name"] = True
                # exact names only: a fuzzy search would warn "more than one target found"
                # for every short name (`fit`, `config`) that several objects have
                if "refspecific" in ref:
                    del ref["refspecific"]
        return made, messages


def _outside_probaff(obj: Any) -> bool:
    """Whether the reference shows `obj` as text: a type variable or no probaff module's."""
    module = getattr(obj, "__module__", None) or ""
    return isinstance(obj, TypeVar) or module.split(".")[0] != "probaff"


def _foreign(target: str) -> bool:
    """Whether `target`, read in no module's scope, names an object outside probaff."""
    head = target.split(".")[0]
    if head == "probaff" or not (hasattr(builtins, head) or head in sys.modules):
        return False
    obj = _lookup(target, {})
    return obj is not _MISSING and _outside_probaff(obj)


class ForeignNames(SphinxPostTransform):
    """Show a fully qualified third-party or built-in name as code before Sphinx looks it up.

    Napoleon's types and autodoc's annotations write ``str``, ``numpy.ndarray`` or
    ``typing.Any`` about 15,000 times. Sphinx would search all of probaff's objects for each
    (its fuzzy search: 3 of the build's 57 s) and then hand it to `resolve_in_scope`, which
    shows it as code: this gives the same pages at once. Names that need a module's scope
    (``Tensor``, imported from torch) are left to `resolve_in_scope`.
    """

    default_priority = 5  # before Sphinx's ReferencesResolver (10)

    def run(self, **kwargs: Any) -> None:
        """Replace each such reference by its text."""
        for node in list(self.document.findall(addnodes.pending_xref)):
            if node.get("refdomain") == "py" and _foreign(node["reftarget"]):
                node.replace_self(node[0].deepcopy())


def resolve_in_scope(
    app: Sphinx, env: BuildEnvironment, node: addnodes.pending_xref, contnode: nodes.Element
) -> nodes.Element | None:
    """Resolve a Python reference Sphinx could not, as Python resolves the name it writes.

    Returns:
        A link to probaff's description of the object, the unlinked text for an object outside
        probaff's public names, or, when the name resolves to nothing, the unlinked text for
        a single-backtick name (`NameRole`) and None (Sphinx then warns) for an explicit role.
    """
    if node.get("refdomain") != "py":
        return None
    quiet = bool(node.get("probaff_name"))
    try:
        found = _resolve(app, env, node, contnode)
    except Exception:  # a single-backtick text that is no Python name, such as "(N, D)"
        if not quiet:
            raise
        found = None
    return contnode if found is None and quiet else found


def _resolve(
    app: Sphinx, env: BuildEnvironment, node: addnodes.pending_xref, contnode: nodes.Element
) -> nodes.Element | None:
    target = node["reftarget"]
    for scope in [*_scopes(node), {}]:
        obj = _lookup(target, scope)
        if obj is not _MISSING:
            break
    else:
        return None
    if _outside_probaff(obj):
        return contnode
    module = obj.__module__
    qualname = getattr(obj, "__qualname__", None)
    if isinstance(obj, ModuleType):
        canonical = obj.__name__
    elif qualname:
        canonical = f"{module}.{qualname}"
    else:
        return None
    if any(part.startswith("_") for part in canonical.split(".")):
        return contnode
    names = _documented_names(env)
    documented = names.get(canonical, canonical)
    owner, _, member = canonical.rpartition(".")
    if canonical not in names and owner in names:  # a method of a class described elsewhere
        documented = f"{names[owner]}.{member}"
    if documented == target:
        return None
    domain = env.get_domain("py")
    return domain.resolve_xref(
        env, node["refdoc"], app.builder, node["reftype"], documented, node, contnode
    )


def _documented_names(env: BuildEnvironment) -> dict[str, str]:
    """Defining name -> the name it is described under, for classes and functions.

    Autodoc records a class's defining name as an alias (``:canonical:``); this does the same
    for functions, which a package's public face describes under the package's name, and
    lets a class's methods be found under the name the class is described by.
    """
    domain = env.get_domain("py")
    size = len(domain.objects)  # type: ignore[attr-defined]
    cache = getattr(env, "_probaff_documented", None)
    if cache is not None and cache[0] == size:
        return cache[1]
    names: dict[str, str] = {}
    # (name, display name, type, page, anchor, priority); priority -1 marks an alias
    for name, _display, objtype, _page, _anchor, priority in domain.get_objects():
        if objtype in ("function", "class", "exception") and priority != -1:
            obj = _lookup(name, {})
            if (inspect.isroutine(obj) or inspect.isclass(obj)) and getattr(
                obj, "__qualname__", None
            ):
                names.setdefault(f"{obj.__module__}.{obj.__qualname__}", name)
    env._probaff_documented = (size, names)  # type: ignore[attr-defined]
    return names


def skip_foreign_members(
    app: Sphinx, what: str, name: str, obj: Any, skip: bool, options: Any
) -> bool | None:
    """Leave out class members that a third-party base gives a class.

    scikit-learn, for one, adds ``set_*_request`` methods to every estimator subclass; they are
    scikit-learn's to document.
    """
    function = getattr(obj, "fget", obj)  # a property's getter
    if what not in ("class", "exception") or not inspect.isroutine(function):
        return None
    origin = getattr(function, "__module__", None)
    if isinstance(origin, str) and origin.split(".")[0] not in ("probaff", "builtins"):
        return True
    return None


def keep_attribute_prose(
    app: Sphinx, what: str, name: str, obj: Any, options: Any, lines: list[str]
) -> None:
    """Undo napoleon's reading of an attribute docstring's ``text: more`` as ``type: more``.

    Napoleon takes what precedes the first colon of a property's, attribute's or constant's
    docstring for its type. probaff's docstrings give types as annotations (autodoc shows
    them) and write prose or shapes there (``"(N, K) bool: which slots hold an object"``), so
    the text goes back in front of the description it was taken from. Runs after napoleon.
    """
    if what not in ("attribute", "data", "property") or len(lines) < 2:
        return
    if lines[-2] != "" or not lines[-1].startswith(":type: "):
        return
    taken = lines[-1][len(":type: ") :]
    del lines[-2:]
    first = next((i for i, line in enumerate(lines) if line.strip()), None)
    if first is None:
        lines.append(taken)
    else:
        lines[first] = f"{taken}: {lines[first]}"


def setup(app: Sphinx) -> dict[str, Any]:
    """Register the directive and the resolvers."""
    app.setup_extension("sphinx.ext.napoleon")
    app.add_directive("probaff-package", PackageDirective)
    app.add_directive("probaff-module", ModuleDirective)
    app.add_role("probaff-name", NameRole())
    app.connect("builder-inited", write_module_pages)
    app.connect("missing-reference", resolve_in_scope)
    app.add_post_transform(ForeignNames)
    app.connect("autodoc-skip-member", skip_foreign_members)
    app.connect("autodoc-process-docstring", keep_attribute_prose, priority=600)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
