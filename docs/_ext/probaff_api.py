"""The ``probaff-package`` directive and the reference's name resolution.

``.. probaff-package:: probaff.models`` writes, in order:

- the package's public face: its docstring and every name of its ``__all__``;
- a "Modules" section with one subsection per public module (a name starting with ``_`` is
  private): the module's docstring, the names of its ``__all__`` that no enclosing package
  already documents, and links to those it does;
- a "Subpackages" section, each nested package documented the same way, recursively (the flag
  ``:no-subpackages:`` leaves them out, for the top-level ``probaff`` page).

Modules and subpackages are found with `pkgutil`, so a new module appears in the reference
without editing the docs. Each object is documented once, under the name a user imports it by:
a class or function that a package exports is described in the package's public face, and a
name that a package re-exports from outside itself links to where it is described. Autodoc
records a class's defining module as its canonical name, so a reference to
``probaff.models.mixture.MixtureOfGPExperts`` (as type annotations write it) finds
``probaff.models.MixtureOfGPExperts``.

Cross-references that Sphinx cannot resolve by itself are resolved as Python resolves the name
in the module where it is written (`resolve_in_scope`): ``Tensor`` in a module that imports it
from torch is ``torch.Tensor``. The reference links probaff's public names; what resolves to a
third-party or standard-library object, a type variable or a private name (a dotted component
starting with ``_``) is shown as text, unlinked. A name that resolves to nothing still fails the
build (``-n``).
"""

from __future__ import annotations

import builtins
import importlib
import inspect
import pkgutil
import re
from types import ModuleType
from typing import Any, TypeVar

from docutils import nodes
from docutils.parsers.rst import directives
from docutils.statemachine import StringList
from sphinx import addnodes
from sphinx.application import Sphinx
from sphinx.environment import BuildEnvironment
from sphinx.pycode import ModuleAnalyzer
from sphinx.util.docutils import SphinxDirective
from sphinx.util.nodes import nested_parse_with_titles

# Section adornments below the page title (``=``).
_LEVELS = "-~^\"'`"
# Longest value repr shown after a constant's name; longer values are left to its docstring.
_MAX_VALUE = 72
_MISSING = object()
_NAME = re.compile(r"[A-Za-z_][\w.]*")


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


def _names_lines(
    module: ModuleType, ancestors: list[ModuleType], modules: list[ModuleType], face: bool
) -> list[str]:
    """Directives for the names of `module`'s ``__all__`` not described by `ancestors`.

    In a package's public face (`face`), a class or function defined outside the package is
    linked, not described; in a module, one defined in another module is linked.
    """
    lines: list[str] = []
    links: dict[str, list[str]] = {}  # the page's wording -> links to the descriptions
    for name in _public(module):
        obj = getattr(module, name)
        owner = _documented_by(name, obj, ancestors)
        elsewhere = _is_api(obj) and (
            not _defined_in(obj, module) if face else obj.__module__ != module.__name__
        )
        if owner is not None:
            where = f"Described with its package :py:mod:`{owner.__name__}`"
            links.setdefault(where, []).append(f":py:obj:`{name} <{owner.__name__}.{name}>`")
        elif elsewhere:
            where = "Imported from the module that defines it"
            links.setdefault(where, []).append(f":py:obj:`{name} <{_target(obj, name, module)}>`")
        elif _is_api(obj):
            lines += _member(f"{module.__name__}.{name}", obj)
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


def package_lines(
    package: ModuleType, ancestors: list[ModuleType], depth: int, subpackages: bool = True
) -> list[str]:
    """The reST source documenting `package` below `ancestors`, with headings from `depth`.

    Args:
        package: The package to document.
        ancestors: Enclosing packages already documented on the page, outermost first.
        depth: Index into the heading adornments of this package's section headings.
        subpackages: Document nested subpackages as well.

    Returns:
        reST lines.
    """
    inside = [m for m in _submodules(package) if subpackages or "." not in _relative(m, package)]
    lines = _automodule(package) + _names_lines(package, ancestors, inside, face=True)
    inner = [*ancestors, package]
    children = [m for m in inside if "." not in _relative(m, package)]
    modules = [m for m in children if not hasattr(m, "__path__")]
    if modules:
        lines += _heading("Modules", depth)
        for module in modules:
            lines += _heading(f"``{module.__name__}``", depth + 1) + _automodule(module)
            lines += _names_lines(module, inner, [], face=False)
    packages = [m for m in children if hasattr(m, "__path__")]
    if subpackages and packages:
        lines += _heading("Subpackages", depth)
        for sub in packages:
            lines += _heading(f"``{sub.__name__}``", depth + 1)
            lines += package_lines(sub, inner, depth + 2)
    return lines


def _relative(module: ModuleType, package: ModuleType) -> str:
    return module.__name__[len(package.__name__) + 1 :]


class PackageDirective(SphinxDirective):
    """``.. probaff-package:: NAME``: the reference of one package (see the module docstring)."""

    required_arguments = 1
    option_spec = {"no-subpackages": directives.flag}  # noqa: RUF012 (docutils API)

    def run(self) -> list[nodes.Node]:
        """Generate the package's reST and parse it in place, section headings included."""
        package = importlib.import_module(self.arguments[0])
        source = package_lines(package, [], 0, subpackages="no-subpackages" not in self.options)
        where = f"<probaff-package {package.__name__}>"
        content = StringList(source, items=[(where, i + 1) for i in range(len(source))])
        container = nodes.section()
        container.document = self.state.document
        nested_parse_with_titles(self.state, content, container)
        return container.children


def _lookup(dotted: str, scope: dict[str, Any]) -> Any:
    """The object `dotted` names in `scope` (module globals, then importable modules)."""
    head, *rest = dotted.split(".")
    if head in scope:
        obj = scope[head]
    elif hasattr(builtins, head):
        obj = getattr(builtins, head)
    else:
        try:
            obj = importlib.import_module(head)
        except ImportError:
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


def resolve_in_scope(
    app: Sphinx, env: BuildEnvironment, node: addnodes.pending_xref, contnode: nodes.Element
) -> nodes.Element | None:
    """Resolve a Python reference Sphinx could not, as Python resolves the name it writes.

    Returns:
        A link to probaff's description of the object, the unlinked text for an object outside
        probaff's public names, or None (Sphinx then warns) when the name resolves to nothing.
    """
    if node.get("refdomain") != "py":
        return None
    target = node["reftarget"]
    for scope in [*_scopes(node), {}]:
        obj = _lookup(target, scope)
        if obj is not _MISSING:
            break
    else:
        return None
    module = getattr(obj, "__module__", None) or ""
    qualname = getattr(obj, "__qualname__", None)
    if isinstance(obj, TypeVar) or module.split(".")[0] != "probaff":
        return contnode
    if isinstance(obj, ModuleType):
        canonical = obj.__name__
    elif qualname:
        canonical = f"{module}.{qualname}"
    else:
        return None
    if any(part.startswith("_") for part in canonical.split(".")):
        return contnode
    documented = _documented_names(env).get(canonical, canonical)
    if documented == target:
        return None
    domain = env.get_domain("py")
    return domain.resolve_xref(
        env, node["refdoc"], app.builder, node["reftype"], documented, node, contnode
    )


def _documented_names(env: BuildEnvironment) -> dict[str, str]:
    """Defining name -> the name it is described under, for the functions of the reference.

    Autodoc records a class's defining name as an alias (``:canonical:``); this does the same
    for functions, which a package's public face describes under the package's name.
    """
    # (name, display name, type, page, anchor, priority); priority -1 marks an alias
    objects = list(env.get_domain("py").get_objects())
    cache = getattr(env, "_probaff_documented", None)
    if cache is not None and cache[0] == len(objects):
        return cache[1]
    names: dict[str, str] = {}
    for name, _display, objtype, _page, _anchor, priority in objects:
        if objtype == "function" and priority != -1:
            obj = _lookup(name, {})
            if inspect.isroutine(obj) and getattr(obj, "__qualname__", None):
                names.setdefault(f"{obj.__module__}.{obj.__qualname__}", name)
    env._probaff_documented = (len(objects), names)  # type: ignore[attr-defined]
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
    app.connect("missing-reference", resolve_in_scope)
    app.connect("autodoc-skip-member", skip_foreign_members)
    app.connect("autodoc-process-docstring", keep_attribute_prose, priority=600)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
