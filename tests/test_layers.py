"""The import rule of docs/architecture.md, read from the source with ``ast``.

Layers, lowest first (a module imports only modules of its own layer or below):

1. shared ``design/`` (errors, units, schema, atomic, jax_config, parts, cad_units, mass_properties)
2. ``design/<device>/`` — the device columns (params, kinematics, mass, cad, mjcf)
3. ``design/io``, ``design/export`` (they dispatch over devices)
4. shared ``analysis/`` (fidelity, status, interference, control, ``fem/``, ``loop/``)
5. ``analysis/<device>/`` — evaluators, firmware, plants, plots of one device
6. ``analysis/registry``, ``analysis/verify``, ``analysis/warmup`` (they dispatch over devices)
7. ``optim/``
8. ``optim/cli/``

Device columns never import each other. The graph (module-level and function-level imports
alike) has no cycle. A function-level import is allowed only for a heavy or optional dependency:
a third-party package named in ``LAZY`` with its reason, or a hapticopt module that imports one
of those at module level (directly or through other modules; computed here, so the rule cannot
go stale): the CLI pays for it only when a command needs it.
"""

from __future__ import annotations

import ast
import tomllib
from collections import defaultdict
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TOPS = ("design", "analysis", "optim")
DEVICES = ("prrr", "master", "handle")

#: heavy or optional dependencies that may be imported inside a function, and why
LAZY: dict[str, str] = {
    "build123d": "CAD kernel (OCCT), ~1.5 s to import; only export and the CAD FEA need it",
    "OCP": "OCCT bindings under build123d",
    "gmsh": "mesher, only the solid FEA needs it",
    "skfem": "finite elements, only the solid FEA needs it",
    "pyamg": "AMG preconditioner, only the solid FEA needs it",
    "manifold3d": "mesh booleans, only the fine interference check needs it",
    "mujoco": "multibody plant, only verify and the multibody scenes need it",
    "numba": "the compiled MuJoCo loops (analysis/loop/_mujoco_kernels.py) and interference check "
             "(analysis/prrr/collision/_interference_kernels.py); ~0.5 s to import, only a MuJoCo run or a fast interference check needs it",
    "llvmlite": "under numba: loads libmujoco for the compiled loops' linker",
    "pyvista": "VTK rendering, only --render and --plots need it",
    "vtk": "under pyvista",
    "matplotlib": "plots, only --plots and the report need them",
    "dask": "cluster executor, only --scheduler tcp:// needs it",
    "distributed": "cluster executor, only --scheduler tcp:// needs it",
    "jax": "jit-compiled paths; the numpy paths of a short CLI call do not pay jax's import",
    "scipy.optimize": "root finding in a few evaluators; +0.4 s to import",
    "nlopt": "only the optimiser needs it",
    "threadpoolctl": "BLAS thread control around the FEA solve",
    "sksparse": "optional CHOLMOD backend of the FEA's direct solve (scikit-sparse; SuperLU without it)",
}


def module_files() -> dict[str, Path]:
    """hapticopt module name -> file, from the three top-level folders."""
    out = {}
    for top in TOPS:
        for path in (ROOT / top).rglob("*.py"):
            parts = path.relative_to(ROOT).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out["hapticopt." + ".".join(parts)] = path
    return out


def layer(module: str) -> tuple[int, str]:
    """(layer number, column) of a hapticopt module; column is the device or ''."""
    parts = module.split(".")[1:]
    top, rest = parts[0], parts[1:]
    if top == "design":
        if rest and rest[0] in DEVICES:
            return 2, rest[0]
        if rest and rest[0] in ("io", "export", "presets"):
            return 3, ""
        return 1, ""
    if top == "analysis":
        if rest and rest[0] in DEVICES:
            return 5, rest[0]
        if rest and rest[0] in ("registry", "verify", "warmup"):
            return 6, ""
        return 4, ""
    if rest and rest[0] == "cli":
        return 8, ""
    return 7, ""


def resolve(name: str, modules: dict[str, Path]) -> str | None:
    """The hapticopt module an import names (a module, or the module holding the name)."""
    while name and name not in modules:
        name = name.rpartition(".")[0]
    return name or None


def imports_of(path: Path, modules: dict[str, Path], self_name: str):
    """Yield (imported hapticopt module or third-party name, lineno, at function level)."""
    tree = ast.parse(path.read_text())
    package = self_name if path.name == "__init__.py" else self_name.rpartition(".")[0]

    def visit(node, nested):
        for child in ast.iter_child_nodes(node):
            inner = nested or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
            if isinstance(child, ast.Import):
                for alias in child.names:
                    yield alias.name, child.lineno, nested
            elif isinstance(child, ast.ImportFrom):
                if child.level:
                    base = package.rsplit(".", child.level - 1)[0] if child.level > 1 else package
                    mod = f"{base}.{child.module}" if child.module else base
                else:
                    mod = child.module
                for alias in child.names:
                    full = f"{mod}.{alias.name}"
                    yield (full if full in modules else mod), child.lineno, nested
            else:
                yield from visit(child, inner)

    for name, lineno, nested in visit(tree, False):
        target = resolve(name, modules) if name.startswith("hapticopt.") else name
        if target is not None and target != self_name:
            yield target, lineno, nested


def import_graph(modules: dict[str, Path] | None = None):
    modules = modules or module_files()
    edges: dict[str, set[str]] = defaultdict(set)
    lazy: list[tuple[str, int, str]] = []
    for name, path in modules.items():
        for target, lineno, nested in imports_of(path, modules, name):
            if target.startswith("hapticopt."):
                edges[name].add(target)
            if nested:
                lazy.append((name, lineno, target))
    return modules, edges, lazy


def upward_imports(edges) -> list[str]:
    bad = []
    for src, targets in edges.items():
        ls, cs = layer(src)
        for dst in targets:
            ld, cd = layer(dst)
            if ld > ls:
                bad.append(f"{src} (layer {ls}) imports {dst} (layer {ld})")
            elif ld == ls and cs and cd and cs != cd:
                bad.append(f"{src} imports the other device's {dst}")
    return sorted(bad)


def cycles(edges) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    counter = [0]

    def strong(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in edges.get(v, ()):
            if w not in index:
                strong(w)
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

    for v in sorted(set(edges) | {w for t in edges.values() for w in t}):
        if v not in index:
            strong(v)
    return out


def _is_lazy_package(name: str) -> bool:
    return any(name == k or name.startswith(k + ".") for k in LAZY)


def heavy_modules(modules: dict[str, Path]) -> set[str]:
    """hapticopt modules that import a ``LAZY`` package at module level, directly or transitively."""
    top: dict[str, set[str]] = {}
    heavy: set[str] = set()
    for name, path in modules.items():
        targets = {t for t, _, nested in imports_of(path, modules, name) if not nested}
        top[name] = {t for t in targets if t.startswith("hapticopt.")}
        if any(_is_lazy_package(t) for t in targets if not t.startswith("hapticopt.")):
            heavy.add(name)
    changed = True
    while changed:
        changed = False
        for name, targets in top.items():
            if name not in heavy and targets & heavy:
                heavy.add(name)
                changed = True
    return heavy


def lazy_not_allowed(lazy, heavy: set[str] = frozenset()) -> list[str]:
    bad = []
    for src, lineno, target in lazy:
        if not (_is_lazy_package(target) or target in heavy):
            bad.append(f"{src}:{lineno} imports {target} inside a function")
    return sorted(bad)


def test_no_cycles_and_no_upward_imports():
    _, edges, _ = import_graph()
    found = cycles(edges)
    up = upward_imports(edges)
    print(f"cycles: {len(found)}, upward imports: {len(up)}")
    assert found == [], f"{len(found)} import cycles: {found}"
    assert up == [], f"{len(up)} upward imports:\n" + "\n".join(up)


def test_function_level_imports_only_for_heavy_dependencies():
    modules, _, lazy = import_graph()
    bad = lazy_not_allowed(lazy, heavy_modules(modules))
    assert bad == [], "\n".join(bad)


def test_every_jax_user_configures_float64_first():
    """float64 must not depend on import order: each jax-using module imports jax_config."""
    modules = module_files()
    missing = []
    for name, path in modules.items():
        if name == "hapticopt.design.jax_config":
            continue
        targets = [t for t, _, _ in imports_of(path, modules, name)]
        if any(t == "jax" or t.startswith("jax.") for t in targets) and "hapticopt.design.jax_config" not in targets:
            missing.append(name)
    assert missing == []


def test_the_checker_sees_a_cycle_and_an_upward_import(tmp_path):
    """The rule's own test, on scratch modules: a cycle and an upward import are reported."""
    root = tmp_path
    (root / "design").mkdir()
    (root / "analysis").mkdir()
    (root / "design" / "a.py").write_text("from hapticopt.design import b\n")
    (root / "design" / "b.py").write_text("from hapticopt.design import a\nfrom hapticopt.analysis import c\n")
    (root / "analysis" / "c.py").write_text("import os\n\ndef f():\n    from hapticopt.design import d\n")
    (root / "design" / "d.py").write_text("import os\n")
    modules = {
        "hapticopt.design.a": root / "design" / "a.py",
        "hapticopt.design.b": root / "design" / "b.py",
        "hapticopt.analysis.c": root / "analysis" / "c.py",
        "hapticopt.design.d": root / "design" / "d.py",
    }
    _, edges, lazy = import_graph(modules)
    assert cycles(edges) == [["hapticopt.design.a", "hapticopt.design.b"]]
    assert upward_imports(edges) == ["hapticopt.design.b (layer 1) imports hapticopt.analysis.c (layer 4)"]
    assert lazy_not_allowed(lazy) == ["hapticopt.analysis.c:4 imports hapticopt.design.d inside a function"]


def test_the_package_list_names_every_package():
    """pyproject lists the packages explicitly (the namespace mapping needs it): none missing."""
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    on_disk = {"hapticopt." + ".".join(p.parent.relative_to(ROOT).parts)
               for top in TOPS for p in (ROOT / top).rglob("__init__.py")}
    assert listed == on_disk


@pytest.mark.parametrize("device", ["prrr", "master"])
def test_devices_never_import_each_other(device):
    _, edges, _ = import_graph()
    other = {"prrr": "master", "master": "prrr"}[device]
    crossing = [(s, d) for s, ts in edges.items() for d in ts
                if f".{device}." in s + "." and f".{other}." in d + "."]
    assert crossing == []
