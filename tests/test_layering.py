"""The import layering: envs ← planners ← bouncesim ← experiments (and benchmarks), no cycles.

Every module's imports are read with ``ast`` — module-level and function-level alike, since a
function-level import only postpones a cycle to the first call — and resolved to our modules
(relative imports included; ``from pkg import name`` is the submodule pkg.name when there is
one, else pkg). The rules (docs: the README's Layout section):

- no import cycle among our modules;
- ``planners`` imports no ``bouncesim``, ``experiments``, ``matplotlib``, ``pybullet`` or
  ``serial``;
- ``bouncesim`` imports no ``experiments``;
- ``envs`` imports no ``planners``, ``bouncesim`` or ``experiments``;
- ``benchmarks`` imports no ``experiments`` and ``experiments`` no ``benchmarks`` (which is not
  installed); neither imports the CLI (``bouncesim.cli``,
  ``bouncesim.commands``): they call library functions;
- ``planners.navigation`` and ``planners.coverage`` do not import each other;
- no module of ``envs``, ``planners`` or ``bouncesim`` exceeds 600 lines;
- no module imports a private name (``_name``) of another module of ours, and a private
  module (``pkg._mod``) is imported only from its own package;
- in ``envs``, ``planners`` and ``bouncesim`` no planner or coverage-model name is compared
  as a string (``x == "exact"``, ``x in ("step", ...)``): a planner or model says what it is
  through its class (``needs``, ``closed_loop``, ``flights``, ``contact_rule``, ...), and
  its name is read only by its registry (``planners/navigation/registry.py``,
  ``planners/coverage/api.py``). The experiments, which filter result tables by planner,
  are exempt.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("envs", "planners", "bouncesim", "experiments", "benchmarks")
FORBIDDEN = {
    "planners": {"bouncesim", "experiments", "matplotlib", "pybullet", "serial"},
    "bouncesim": {"experiments"},
    "envs": {"planners", "bouncesim", "experiments"},
    "benchmarks": {"experiments", "bouncesim.cli", "bouncesim.commands"},
    # benchmarks/ is not installed: an experiment run outside the checkout could not import it
    "experiments": {"bouncesim.cli", "bouncesim.commands", "benchmarks"},
}
MAX_LINES = 600


def _modules(root: Path = ROOT) -> dict[str, Path]:
    """Dotted name → file of every module of our packages."""
    out = {}
    for pkg in PACKAGES:
        for path in sorted((root / pkg).rglob("*.py")):
            parts = list(path.relative_to(root).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = path
    return out


def _imports(name: str, path: Path, modules: dict) -> list[tuple[str, int]]:
    """(imported dotted name, line) of every import in the module, resolved where it is ours."""
    found = []
    for node, mod, attr in _import_nodes(name, path):
        sub = f"{mod}.{attr}"
        found.append((sub if attr and sub in modules else mod, node.lineno))
    return found


def _package(name: str, path: Path) -> str:
    return name if path.name == "__init__.py" else name.rpartition(".")[0]


def _import_nodes(name: str, path: Path):
    """(node, imported module, imported attribute or None) of every import in the module,
    relative imports resolved.
    """
    package = _package(name, path)
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            for a in node.names:
                yield node, a.name, None
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[:len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            for a in node.names:
                yield node, mod, a.name


def import_graph(root: Path = ROOT):
    """({module: {our imported module: line}}, {module: [(any imported name, line)]})."""
    modules = _modules(root)
    ours, every = {}, {}
    for name, path in modules.items():
        imps = _imports(name, path, modules)
        every[name] = imps
        ours[name] = {}
        for mod, line in imps:
            # an import of a.b.c loads a.b.c; count it as an edge to the deepest module we own
            parts = mod.split(".")
            for i in range(len(parts), 0, -1):
                cand = ".".join(parts[:i])
                if cand in modules:
                    if cand != name:
                        ours[name].setdefault(cand, line)
                    break
    return ours, every


def find_cycles(graph: dict) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan), each sorted."""
    index, low, on, stack, out = {}, {}, set(), [], []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def _describe(cycle: list[str], graph: dict) -> str:
    members = set(cycle)
    edges = [f"{a} -> {b} (line {graph[a][b]})" for a in cycle for b in sorted(graph[a])
             if b in members]
    return "; ".join(edges)


WINGS = {"planners.navigation": "planners.coverage", "planners.coverage": "planners.navigation"}
"""Neither wing imports the other: what they share lives one floor down in ``planners``."""


def layering_violations(root: Path = ROOT) -> list[str]:
    """Every broken rule, one readable line each (empty when the layering holds)."""
    graph, every = import_graph(root)
    problems = [f"import cycle: {_describe(c, graph)}" for c in find_cycles(graph)]
    for name, imps in sorted(every.items()):
        banned = set(FORBIDDEN.get(name.split(".")[0], set()))
        banned |= {other for wing, other in WINGS.items()
                   if name == wing or name.startswith(wing + ".")}
        for mod, line in imps:
            if any(mod == b or mod.startswith(b + ".") for b in banned):
                problems.append(f"{name} imports {mod} (line {line})")
    return problems


def test_modules_are_found():
    mods = _modules()
    assert {"envs", "planners.cells", "bouncesim.cli", "experiments.common"} <= set(mods)


def test_cycle_finder_on_a_small_graph():
    g = {"a": {"b": 1}, "b": {"c": 1}, "c": {"a": 1, "d": 1}, "d": {}, "e": {"e": 1}}
    assert find_cycles(g) == [["a", "b", "c"]]


def test_relative_and_function_level_imports_are_seen(tmp_path):
    for pkg in PACKAGES:
        (tmp_path / pkg).mkdir()
        (tmp_path / pkg / "__init__.py").write_text("")
    (tmp_path / "planners" / "a.py").write_text("from . import b\n")
    (tmp_path / "planners" / "b.py").write_text("def f():\n    from .a import x\n"
                                                "    import matplotlib.pyplot\n")
    (tmp_path / "planners" / "navigation").mkdir()
    (tmp_path / "planners" / "navigation" / "__init__.py").write_text(
        "from planners.coverage import x\n")
    problems = layering_violations(tmp_path)
    assert any(p.startswith("import cycle: planners.a -> planners.b") for p in problems)
    assert "planners.b imports matplotlib.pyplot (line 3)" in problems
    assert "planners.navigation imports planners.coverage (line 1)" in problems


def test_layering_holds():
    problems = layering_violations()
    assert not problems, "\n".join(problems)



def test_modules_stay_small():
    long = {name: n for name, path in _modules().items()
            if name.split(".")[0] in ("envs", "planners", "bouncesim")
            and (n := path.read_text(encoding="utf-8").count("\n")) > MAX_LINES}
    assert not long, f"modules over {MAX_LINES} lines: {long}"


# ---------------------------------------------------------------- private names, dispatch
REGISTRIES = {"planners.navigation.registry", "planners.coverage.api"}
LIBRARY = ("envs", "planners", "bouncesim")


def registry_names() -> set[str]:
    from planners.coverage import MODELS
    from planners.navigation import PLANNERS
    return set(PLANNERS) | set(MODELS)


def private_imports(root: Path = ROOT) -> list[str]:
    """Every import of another module's private name, or of a private module from outside
    its package, one readable line each.
    """
    modules = _modules(root)
    problems = []
    for name, path in sorted(modules.items()):
        own_pkg = _package(name, path)
        for node, mod, attr in _import_nodes(name, path):
            if mod.split(".")[0] not in PACKAGES:
                continue
            full = f"{mod}.{attr}" if attr and f"{mod}.{attr}" in modules else mod
            parts = full.split(".")
            for i, part in enumerate(parts):
                if part.startswith("_") and not part.startswith("__"):
                    pkg = ".".join(parts[:i])
                    if not (own_pkg == pkg or own_pkg.startswith(pkg + ".")):
                        problems.append(f"{name} imports the private module {full} "
                                        f"(line {node.lineno})")
                    break
            if attr and full == mod and attr.startswith("_") and not attr.startswith("__"):
                problems.append(f"{name} imports the private name {mod}.{attr} "
                                f"(line {node.lineno})")
    return problems


def name_dispatch(root: Path = ROOT, names: set[str] | None = None) -> list[str]:
    """Every comparison of a string to a planner or model name in the library packages
    outside the registries, one readable line each.
    """
    names = registry_names() if names is None else names
    problems = []
    for name, path in sorted(_modules(root).items()):
        if name.split(".")[0] not in LIBRARY or name in REGISTRIES:
            continue
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if not isinstance(node, ast.Compare):
                continue
            consts = set()
            for c in (node.left, *node.comparators):
                elts = c.elts if isinstance(c, (ast.Tuple, ast.List, ast.Set)) else [c]
                consts |= {e.value for e in elts
                           if isinstance(e, ast.Constant) and isinstance(e.value, str)}
            if consts & names:
                problems.append(f"{name} compares a name as a string: {ast.unparse(node)} "
                                f"(line {node.lineno})")
    return problems


def test_no_private_names_cross_modules():
    problems = private_imports()
    assert not problems, "\n".join(problems)


def test_no_planner_or_model_name_dispatch_outside_the_registries():
    assert {"step", "exact", "reliable", "feedback", "sampled", "event"} <= registry_names()
    problems = name_dispatch()
    assert not problems, "\n".join(problems)


def test_the_new_rules_catch_what_they_should(tmp_path):
    for pkg in PACKAGES:
        (tmp_path / pkg).mkdir()
        (tmp_path / pkg / "__init__.py").write_text("")
    (tmp_path / "planners" / "sub").mkdir()
    (tmp_path / "planners" / "sub" / "__init__.py").write_text("from ._hidden import f\n")
    (tmp_path / "planners" / "sub" / "_hidden.py").write_text("def f():\n    pass\n")
    (tmp_path / "planners" / "a.py").write_text("from .b import _secret, shown\n")
    (tmp_path / "planners" / "b.py").write_text("_secret = shown = 1\n")
    (tmp_path / "bouncesim" / "c.py").write_text(
        "from planners.sub._hidden import f\n"
        "def g(args):\n    return args.planner == 'exact' or args.model in ('step', 'x')\n")
    priv = private_imports(tmp_path)
    assert priv == ["bouncesim.c imports the private module planners.sub._hidden (line 1)",
                    "planners.a imports the private name planners.b._secret (line 1)"]
    found = name_dispatch(tmp_path, {"exact", "step"})
    assert len(found) == 2 and all(p.startswith("bouncesim.c compares") for p in found)

