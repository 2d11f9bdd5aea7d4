"""The structural rules of docs/architecture.md ("Structural rules") as functions of a source tree.

One checker for both trees: ``tests/test_layers.py`` runs them on the library (``src/sensorless``),
``studies/tests/test_studies_layers.py`` on the studies (``studies/src/sensorless_studies``, which may use
only the library's public names), and both on their test files. Every ``import`` and ``from … import``
(module level and inside functions) is parsed with :mod:`ast`; each function returns one line per
violation, ``file:line: what``, empty when the tree follows the rule.
"""

from __future__ import annotations

import ast
from collections.abc import Iterable, Iterator
from pathlib import Path


def private(name: str) -> bool:
    """``_name`` is private; ``__dunder__`` is not."""
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def module_name(path: Path, root: Path) -> tuple[str, list[str]]:
    """``(dotted name, package)`` of the file ``path`` of the package directory ``root``: a package is
    its ``__init__``; ``package`` (a list of names) is what its relative imports resolve against."""
    parts = list(path.relative_to(root.parent).with_suffix("").parts)
    package = parts[:-1]
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts), package


def modules(*roots: Path) -> dict[str, Path]:
    """``{dotted module name: path}`` of every module of the package directories ``roots``."""
    return {module_name(p, root)[0]: p for root in roots for p in sorted(root.rglob("*.py"))}


def imported(path: Path, known: dict[str, Path], package: list[str] | None = None) -> Iterator[tuple[str, str | None, int]]:
    """``(module, name or None, line)`` for every import by ``path`` of a module of the packages of
    ``known`` (module level and inside functions, relative imports resolved against ``package``);
    ``name`` is the imported name when it is not itself a module of ``known``."""
    tops = {m.split(".")[0] for m in known}
    package = package or []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split(".")[0] in tops:
                    yield a.name, None, node.lineno
        elif isinstance(node, ast.ImportFrom):
            if node.level and node.level > len(package):
                continue  # a relative import outside the packages checked (a test package's own conftest)
            base = ".".join(package[: len(package) - node.level + 1] + ([node.module] if node.module else [])) \
                if node.level else node.module or ""
            if base.split(".")[0] not in tops:
                continue
            for a in node.names:
                full = f"{base}.{a.name}"
                yield (full, None, node.lineno) if full in known else (base, a.name, node.lineno)


def _private_import(mod: str, target: str, name: str | None) -> str | None:
    parts = target.split(".")
    hidden = [".".join(parts[: k + 1]) for k, c in enumerate(parts) if private(c)]
    outside = [h for h in hidden if not (mod == h or mod.startswith(h + "."))]
    if outside:
        return f"{mod} imports private module {outside[0]}" + (f" (name {name})" if name else "")
    if name is not None and private(name) and target != mod:
        return f"{mod} imports private name {name} from {target}"
    return None


def private_imports(root: Path, *libraries: Path) -> list[str]:
    """Imports, by the modules of ``root``, of another module's ``_private`` name or of a ``_private``
    module from outside it, in ``root`` or in the packages ``libraries`` it uses."""
    known, bad = modules(root, *libraries), []
    for path in sorted(root.rglob("*.py")):
        mod, package = module_name(path, root)
        for target, name, line in imported(path, known, package):
            if (why := _private_import(mod, target, name)) is not None:
                bad.append(f"{path.relative_to(root.parent)}:{line}: {why}")
    return bad


def imports_of_tests(tests: Path, *roots: Path) -> list[str]:
    """Imports, by the files of the test folder ``tests``, of a ``_private`` name or module of the
    packages ``roots``, or of a name through a module that only imports it: a test uses what the
    package makes public, from the module that defines it, as its users do."""
    known, bad = modules(*roots), []
    reimported = {m: _reimported(p) for m, p in known.items() if p.name != "__init__.py"}
    for path in sorted(tests.rglob("*.py")):
        where = path.relative_to(tests.parent)
        for target, name, line in imported(path, known):
            if (why := _private_import(f"tests.{path.stem}", target, name)) is not None:
                bad.append(f"{where}:{line}: {why}")
            elif name is not None and name in reimported.get(target, ()):
                bad.append(f"{where}:{line}: imports {name} through {target}, which only imports it")
    return bad


def import_cycles(root: Path) -> list[str]:
    """Strongly connected components (Tarjan) of the import graph of the modules of ``root`` with more
    than one module, each with the imports that close it."""
    known = modules(root)
    edges: dict[str, dict[str, int]] = {m: {} for m in known}
    for mod, path in known.items():
        for target, _, line in imported(path, known, module_name(path, root)[1]):
            if target in known and target != mod:
                edges[mod].setdefault(target, line)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    sccs: list[list[str]] = []

    def visit(v: str) -> None:  # recursive Tarjan: the graph is a few hundred modules deep at most
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in edges[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                sccs.append(sorted(comp))

    for v in sorted(known):
        if v not in index:
            visit(v)
    out = []
    for comp in sccs:
        links = [f"{known[a].relative_to(root.parent)}:{line}: {a} imports {b}"
                 for a in comp for b, line in sorted(edges[a].items()) if b in comp]
        out.append(f"cycle {' ↔ '.join(comp)}:\n    " + "\n    ".join(links))
    return out


def _lazy_exports_call(node: ast.AST) -> bool:
    return isinstance(node, ast.Call) and getattr(node.func, "id", None) == "lazy_exports"


def _reimported(path: Path) -> set[str]:
    """Names a module binds by a module-level ``from … import`` and does not define itself."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    imported_names, defined = set(), set()
    for node in tree.body:
        if isinstance(node, ast.ImportFrom):
            imported_names |= {a.asname or a.name for a in node.names}
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            defined.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            for t in node.targets if isinstance(node, ast.Assign) else [node.target]:
                defined |= {n.id for n in ast.walk(t) if isinstance(n, ast.Name)}
    return imported_names - defined


def shims(root: Path, *libraries: Path) -> list[str]:
    """Re-export and deprecation shims in ``root``: a module (not a package ``__init__``) that only
    re-imports names, or whose ``__all__`` lists a name it imports; an import of a name through a module
    (of ``root`` or ``libraries``) that only imports it (import it from its owner); a module
    ``__getattr__`` (other than a package's ``lazy_exports`` of its own submodules); a ``_MOVED`` table;
    a ``DeprecationWarning``."""
    bad = []
    known = modules(root, *libraries)
    reimported = {m: _reimported(p) for m, p in known.items() if p.name != "__init__.py"}
    for path in sorted(root.rglob("*.py")):
        mod, package_parts = module_name(path, root)
        for target, name, line in imported(path, known, package_parts):
            if name is not None and name in reimported.get(target, ()):
                bad.append(f"{path.relative_to(root.parent)}:{line}: {mod} imports {name} through {target}, "
                           "which only imports it")
        where = path.relative_to(root.parent)
        tree = ast.parse(path.read_text(encoding="utf-8"))
        package = path.name == "__init__.py"
        imported_at: dict[str, int] = {}
        for node in tree.body:
            if isinstance(node, ast.ImportFrom) and node.module != "__future__":
                imported_at.update({a.asname or a.name: node.lineno for a in node.names})
        code = [n for n in tree.body if not isinstance(n, (ast.Import, ast.ImportFrom))
                and not (isinstance(n, ast.Expr) and isinstance(n.value, ast.Constant))
                and not (isinstance(n, ast.Assign) and [getattr(t, "id", None) for t in n.targets] == ["__all__"])]
        if not package and imported_at and not code:
            bad.append(f"{where}:1: {mod} only re-imports names ({', '.join(sorted(imported_at))})")
        for node in tree.body:
            targets = [getattr(t, "id", None) for t in getattr(node, "targets", [])] + \
                      [getattr(e, "id", None) for t in getattr(node, "targets", []) for e in getattr(t, "elts", [])]
            if not package and "__all__" in targets and isinstance(node.value, (ast.List, ast.Tuple)):
                for e in node.value.elts:
                    if isinstance(e, ast.Constant) and e.value in imported_at:
                        bad.append(f"{where}:{node.lineno}: {mod} re-exports {e.value} "
                                   f"(imported on line {imported_at[e.value]}) in __all__")
            if isinstance(node, ast.FunctionDef) and node.name == "__getattr__" or "__getattr__" in targets and not (
                    package and _lazy_exports_call(node.value)):
                bad.append(f"{where}:{node.lineno}: {mod} defines a module __getattr__ (forwarding names)")
            if "_MOVED" in targets:
                bad.append(f"{where}:{node.lineno}: {mod} keeps a _MOVED table of relocated names")
        for node in ast.walk(tree):
            if isinstance(node, ast.Name) and node.id in ("DeprecationWarning", "PendingDeprecationWarning"):
                bad.append(f"{where}:{node.lineno}: {mod} has a deprecation path ({node.id})")
    return bad


def layer_violations(root: Path, layers: dict[str, int], allowed: Iterable[tuple[str, str]] = ()) -> list[str]:
    """Imports by a module of ``root`` of a module of a higher layer: ``layers`` maps a top-level module
    or package of ``root`` (or ``package.module``, a sub-module given its own layer) to its layer."""
    known, allowed, bad = modules(root), set(allowed), []

    def top(name: str) -> str | None:
        parts = name.split(".")
        if len(parts) > 2 and ".".join(parts[1:3]) in layers:
            return ".".join(parts[1:3])
        return parts[1] if len(parts) > 1 else None

    for path in sorted(root.rglob("*.py")):
        mod, package = module_name(path, root)
        for target, _, line in imported(path, known, package):
            src, dst = top(mod), top(target)
            if src is None or dst is None or src == dst:
                continue
            if layers[dst] > layers[src] and (mod, target) not in allowed:
                bad.append(f"{path.relative_to(root.parent)}:{line}: {mod} (layer {layers[src]}) imports {target} "
                           f"(layer {layers[dst]})")
    return bad


def unlayered(root: Path, layers: dict[str, int]) -> set[str]:
    """Top-level modules and packages of ``root`` without a layer."""
    names = {p.stem for p in root.glob("*.py") if p.stem != "__init__"} | {
        p.name for p in root.iterdir() if (p / "__init__.py").exists()}
    return names - set(layers)
