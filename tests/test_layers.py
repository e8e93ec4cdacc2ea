"""The package is layered one way (docs/layout.md): every import of cas_freq by cas_freq,
function-level ones included, points to the same layer or one below, and no modules import
each other in a cycle.

The import graph is read with :mod:`ast`, not by importing: an ``import`` or ``from ... import``
anywhere in a module (at its top, in a function, in a class) is an edge, except under
``if TYPE_CHECKING:`` (annotations only). The package's face, ``cas_freq/__init__.py``, is left
out: Python runs it before any module of the package, and it only holds ``__version__`` and
hands the API's names on when first asked for.

A function-level import of a cas_freq module only defers a heavy library: the module imported
must reach one of :data:`HEAVY_LIBRARIES` through its top-level imports, or the import is the
guard of an optional dependency (in a ``try`` that catches ImportError: the simulator's compiled
engine, where numba does not import). Importing a light module inside a function would only
hide an edge (a cycle, a layer climbed back up); and the command line's start
(``cas-freq --help``) must import none of them.
"""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "cas_freq"

#: The layers, lowest first: each a tuple of the packages and modules of cas_freq (dotted,
#: without ``cas_freq.``) that it holds; a module belongs to the longest name that contains it.
#: docs/layout.md shows the same list (:func:`layers_text`).
LAYERS = (
    ("core",),
    ("config", "drive"),
    ("model",),
    ("simulation",),
    ("analysis",),
    ("identification",),
    ("studies",),
    ("verify", "tuning"),
    ("plots",),
    ("report",),
    ("api",),
    ("design", "cli", "__main__"),
)

#: Libraries too slow to import for a start that does not need them (``cas-freq --help``
#: imports none): a function-level import of a cas_freq module is for deferring one of these.
HEAVY_LIBRARIES = ("numpy", "scipy", "numba", "control", "matplotlib", "dask", "pydantic")

#: numba's cached ``njit``: a module that imports it at its top holds compiled kernels, heavy
#: as numba is (cas_freq.core.jit itself imports numba only when a kernel is first compiled).
KERNEL_MAKER = "cas_freq.core.jit.cached_jit"

#: The start of the command line, which imports what it needs only once its handler of
#: Ctrl-C is in place (cas_freq.__main__.run, cas_freq.cli.main): its deferred imports are
#: about interrupts, not weight.
START = ("cas_freq.__main__", "cas_freq.cli")

#: Pairs of layers' packages that never import each other in the given direction, the rules
#: docs/layout.md names (they follow from :data:`LAYERS`; checked so that a reordering that
#: broke one is seen).
NEVER = (("model", "analysis"), ("analysis", "plots"), ("plots", "report"), ("api", "cli"))


def _modules():
    """Dotted name -> (path, is a package) of every module of cas_freq."""
    found = {}
    for path in PACKAGE.rglob("*.py"):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        package = parts[-1] == "__init__"
        found[".".join(parts[:-1] if package else parts)] = (path, package)
    return found


def _type_checking(node):
    test = node.test
    return ((isinstance(test, ast.Name) and test.id == "TYPE_CHECKING")
            or (isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"))


def _imports(tree, name, package):
    """(imported name, line, at function level) of every import in ``tree`` of the module
    ``name``; at function level is :data:`GUARDED` for an import in a function guarded by a
    ``try`` that catches ImportError (an optional dependency)."""
    found = []

    def visit(node, in_function):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _type_checking(child):
                for other in child.orelse:
                    visit(other, in_function)
                continue
            nested = in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef,
                                                       ast.Lambda))
            if nested and isinstance(child, ast.Try) and _catches_import_error(child):
                for other in child.body:
                    visit_one(other)
                for part in (child.handlers, child.orelse, child.finalbody):
                    for other in part:
                        visit(other, nested)
                continue
            if isinstance(child, ast.Import):
                found.extend((alias.name, child.lineno, nested) for alias in child.names)
            elif isinstance(child, ast.ImportFrom):
                if child.level:
                    base = name.split(".")[:None if package else -1]
                    base = base[:len(base) - child.level + 1]
                    module = ".".join(base + ([child.module] if child.module else []))
                else:
                    module = child.module
                found.extend((f"{module}.{alias.name}", child.lineno, nested)
                             for alias in child.names)
            visit(child, nested)

    def visit_one(node):
        """An import guarded as an optional dependency, or anything else in that ``try``."""
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            before = len(found)
            visit(ast.Module(body=[node], type_ignores=[]), True)
            found[before:] = [(imported, line, GUARDED) for imported, line, _ in found[before:]]
        else:
            visit(ast.Module(body=[node], type_ignores=[]), True)

    visit(tree, False)
    return found


#: The "at function level" of an import that guards an optional dependency (:func:`_imports`).
GUARDED = "guarded"


def _catches_import_error(node):
    """True if the ``try`` ``node`` has a handler for ImportError (or ModuleNotFoundError)."""
    names = []
    for handler in node.handlers:
        kinds = handler.type.elts if isinstance(handler.type, ast.Tuple) else [handler.type]
        names += [kind.id for kind in kinds if isinstance(kind, ast.Name)]
    return bool({"ImportError", "ModuleNotFoundError"} & set(names))


def import_graph():
    """The import graph of cas_freq.

    Returns
    -------
    edges : dict
        (importer, imported) -> list of (line, at function level), between modules of cas_freq
        (dotted names), the package's face left out.
    libraries : dict
        Module -> set of the libraries it imports at its top.
    """
    modules = _modules()
    edges, libraries = {}, {}
    for name, (path, package) in modules.items():
        if name == "cas_freq":
            continue
        libraries[name] = set()
        targets = {}
        for imported, line, nested in _imports(ast.parse(path.read_text(encoding="utf-8")),
                                               name, package):
            if imported == KERNEL_MAKER and not nested:
                libraries[name].add("kernels")
            if imported.split(".")[0] != "cas_freq":
                if not nested:
                    libraries[name].add(imported.split(".")[0])
                continue
            target = imported
            while target not in modules:  # a name imported from a module: the module
                target = target.rsplit(".", 1)[0]
            if target not in ("cas_freq", name):
                targets.setdefault((line, target), nested)
        for (line, target), nested in targets.items():
            edges.setdefault((name, target), []).append((line, nested))
    return edges, libraries


def layer_of(module):
    """Index in :data:`LAYERS` of a module of cas_freq (dotted)."""
    name = module.removeprefix("cas_freq.")
    best = None
    for index, members in enumerate(LAYERS):
        for member in members:
            if (name == member or name.startswith(member + ".")) and (
                    best is None or len(member) > len(best[1])):
                best = (index, member)
    assert best is not None, f"{module} is in no layer of LAYERS"
    return best[0]


def layers_text():
    """:data:`LAYERS` as docs/layout.md lists them, one numbered line a layer."""
    return "\n".join(f"{index}. " + ", ".join(f"`{member}`" for member in members)
                     for index, members in enumerate(LAYERS, 1))


def cycles(edges):
    """The strongly connected components of more than one module (Tarjan's algorithm)."""
    successors = {}
    for a, b in edges:
        successors.setdefault(a, set()).add(b)
        successors.setdefault(b, set())
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def connect(node):  # iterative: the graph is deep enough for Python's recursion limit
        work = [(node, iter(sorted(successors[node])))]
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        while work:
            current, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(successors[child]))))
                elif child in on_stack:
                    low[current] = min(low[current], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[current])
            if low[current] == index[current]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == current:
                        break
                if len(component) > 1:
                    found.append(sorted(component))

    for node in sorted(successors):
        if node not in index:
            connect(node)
    return found


def loaded_by(importer, imported, modules):
    """The modules that ``importer`` runs by importing ``imported``: it, and the packages
    above it that ``importer`` is not inside of (importing ``a.b.c`` runs ``a/__init__.py``
    and ``a/b/__init__.py`` first)."""
    parts = imported.split(".")
    parents = {".".join(parts[:end]) for end in range(2, len(parts))} & set(modules)
    return {imported} | {parent for parent in parents if not importer.startswith(parent + ".")}


def weights(edges, libraries):
    """Module -> the heavy libraries its import loads (:data:`HEAVY_LIBRARIES` reached
    through top-level imports; ``"kernels"`` for compiled kernels, :data:`KERNEL_MAKER`)."""
    top = {}
    for (a, b), lines in edges.items():
        if any(not nested for _, nested in lines):
            top.setdefault(a, set()).update(loaded_by(a, b, libraries))
    weight = {name: used & {*HEAVY_LIBRARIES, "kernels"} for name, used in libraries.items()}
    grown = True
    while grown:
        grown = False
        for name, used in top.items():
            reached = set().union(*(weight[other] for other in used))
            if not reached <= weight[name]:
                weight[name] |= reached
                grown = True
    return weight


def heavy_modules(edges, libraries):
    """The modules of cas_freq whose import loads a heavy library (:func:`weights`)."""
    return {name for name, weight in weights(edges, libraries).items() if weight}


def test_every_module_is_in_a_layer_and_the_docs_list_the_layers():
    edges, libraries = import_graph()
    for module in libraries:
        layer_of(module)
    text = (ROOT / "docs" / "layout.md").read_text(encoding="utf-8")
    assert layers_text() in text, "docs/layout.md must list the layers of tests/test_layers.py"


def test_no_import_cycle():
    edges, _ = import_graph()
    found = cycles(edges)
    assert not found, "modules importing each other: " + "; ".join(
        " <-> ".join(cycle) for cycle in found)


def test_no_import_climbs_a_layer():
    edges, _ = import_graph()
    up = [f"{a}:{line} -> {b}" for (a, b), lines in sorted(edges.items())
          for line, _ in lines if layer_of(a) < layer_of(b)]
    assert not up, "imports from a lower layer to a higher one:\n" + "\n".join(up)


def test_the_named_rules_hold():
    edges, _ = import_graph()
    for low, high in NEVER:
        below, above = layer_of(f"cas_freq.{low}"), layer_of(f"cas_freq.{high}")
        assert below < above, (low, high)
        broken = [f"{a} -> {b}" for a, b in edges if layer_of(a) == below
                  and layer_of(b) == above]
        assert not broken, f"{low} imports {high}: {broken}"


def test_function_level_imports_only_defer_heavy_libraries():
    edges, libraries = import_graph()
    weight = weights(edges, libraries)
    light = [f"{a}:{line} imports {b} in a function (a heavy library it needs is loaded "
             f"already)" for (a, b), lines in sorted(edges.items()) for line, nested in lines
             if nested and nested != GUARDED and a not in START and set().union(
                 *(weight[other] for other in loaded_by(a, b, libraries))) <= weight[a]]
    assert not light, "\n".join(light)


def test_the_command_line_starts_without_the_heavy_libraries():
    # cas-freq imports every command's module to build its parser (cas_freq.cli.COMMANDS)
    from cas_freq.cli import COMMANDS

    edges, libraries = import_graph()
    start = {*START, "cas_freq.cli.common",
             *(f"cas_freq.cli.{name.replace('-', '_')}" for name in COMMANDS)}
    assert start <= set(libraries)
    heavy = heavy_modules(edges, libraries) & start
    assert not heavy, f"the start of cas-freq imports a heavy library through {sorted(heavy)}"


def test_the_graph_sees_function_level_and_relative_imports():
    tree = ast.parse("from typing import TYPE_CHECKING\n"
                     "from . import b\n"
                     "if TYPE_CHECKING:\n    from cas_freq.x import y\n"
                     "def f():\n    from cas_freq.z import w\n")
    found = _imports(tree, "cas_freq.pkg.a", False)
    assert ("cas_freq.pkg.b", 2, False) in found
    assert ("cas_freq.z.w", 6, True) in found
    assert not any(name.startswith("cas_freq.x") for name, _, _ in found)
    assert cycles({("a", "b"): [], ("b", "c"): [], ("c", "a"): [], ("c", "d"): []}) == [
        ["a", "b", "c"]]
