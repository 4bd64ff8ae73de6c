"""The layering of docs/architecture.md, enforced.

Every module of `lightcal/` and `app/lightcal_app/` is parsed with `ast`; every import in
it counts, function-local ones included (a lazy import is still a dependency). Three rules:

1. A module imports only from its own layer and the layers `ALLOWED` lists for it.
2. No import cycle between modules (imports under `if TYPE_CHECKING:` do not run and are
   left out of this one).
3. A file over `MAX_LINES` lines states why at its top: a line of its module docstring
   that starts with `Over 500 lines for a reason:` (see lightcal/core/kernels/wall.py).

The checker is plain functions of a source folder, so the tests at the end can show that
it flags a violation in a small tree written for the purpose.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

# Where each top-level package's source lives, relative to the repository.
PACKAGE_FOLDERS = {"lightcal": Path("lightcal"), "lightcal_app": Path("app/lightcal_app")}

# The layers, bottom to top, and what each may import besides itself (docs/architecture.md).
# `base` is the leaves every layer may use: the package's version, its errors, the colour map.
ALLOWED: dict[str, frozenset[str]] = {
    "base": frozenset(),
    "core": frozenset({"base"}),
    "io": frozenset({"base", "core"}),
    "capture": frozenset({"base", "core", "io"}),
    # synthetic data of what is photographed draws printed boards (capture) on the wall
    "synthetic": frozenset({"base", "core", "io", "capture"}),
    "pipeline": frozenset({"base", "core", "io"}),
    "report": frozenset({"base", "core", "io", "pipeline"}),
    "resources": frozenset({"base", "io"}),
    "warmup": frozenset({"base", "core", "io", "synthetic", "pipeline", "report"}),
    "app": frozenset({"base", "core", "io", "capture", "pipeline", "report", "resources"}),
    # lightcal.api, the Python API (docs/api.md): what the CLI's commands do, as functions.
    "api": frozenset({"base", "core", "io", "pipeline", "report", "warmup"}),
    "cli": frozenset(
        {
            "base",
            "core",
            "io",
            "capture",
            "synthetic",
            "pipeline",
            "report",
            "resources",
            "warmup",
            "api",
            "app",
        }
    ),
}

# Imports across the rules, each with its reason (keep this short).
EXCEPTIONS: dict[tuple[str, str], str] = {
    ("lightcal", "lightcal.api"): (
        "the package's API attributes, loaded from lightcal.api on first use (PEP 562); "
        "imported for type checkers only, so importing lightcal imports nothing of it"
    ),
    ("lightcal.io.board_file", "lightcal.capture.boards"): (
        "the board file format reads and writes capture's board records; "
        "lightcal.capture.boards imports nothing of lightcal but its errors"
    ),
}

MAX_LINES = 500
REASON = "Over 500 lines for a reason:"

# Files over MAX_LINES without a reason yet (none now); test_pending_list_is_current fails
# once an entry is no longer needed.
PENDING_REASON: frozenset[str] = frozenset()


def layer_of(module: str) -> str | None:
    """The layer of a module of lightcal or lightcal_app (None: not in any layer)."""
    parts = module.split(".")
    if parts[0] == "lightcal_app":
        return "app"
    if parts[0] != "lightcal":
        return None
    if len(parts) == 1 or parts[1] in ("errors", "colormap"):
        return "base"
    if parts[1] == "__main__":
        return "cli"
    if parts[1] in ("core", "io", "capture", "synthetic", "pipeline", "cli", "report"):
        return parts[1]
    if parts[1] in ("resources", "warmup", "api"):
        return parts[1]
    if parts[1] == "warmup_families":
        return "warmup"
    return None


@dataclass(frozen=True)
class Import:
    source: str  # the importing module
    target: str  # the imported module (or package)
    line: int
    runs: bool  # False under `if TYPE_CHECKING:`


def module_files(root: Path) -> dict[str, Path]:
    """Module name -> file, for every .py file of the packages under `root`."""
    modules: dict[str, Path] = {}
    for package, folder in PACKAGE_FOLDERS.items():
        for path in sorted((root / folder).rglob("*.py")):
            rel = path.relative_to(root / folder).with_suffix("").parts
            parts = [package, *rel]
            if parts[-1] == "__init__":
                parts.pop()
            modules[".".join(parts)] = path
    return modules


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def imports_of(module: str, path: Path, known: set[str]) -> list[Import]:
    """Every import of `lightcal`/`lightcal_app` in one file, at any depth."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found: list[Import] = []

    def add(target: str, node: ast.stmt, runs: bool) -> None:
        if target.split(".")[0] in PACKAGE_FOLDERS:
            found.append(Import(module, target, node.lineno, runs))

    def visit(node: ast.AST, runs: bool) -> None:
        if isinstance(node, ast.If) and _is_type_checking(node.test):
            for child in node.body:
                visit(child, False)
            for child in node.orelse:
                visit(child, runs)
            return
        if isinstance(node, ast.Import):
            for alias in node.names:
                add(alias.name, node, runs)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                origin = ".".join([*base, *([node.module] if node.module else [])])
            else:
                origin = node.module or ""
            for alias in node.names:
                # `from pkg import mod` imports the module pkg.mod; otherwise a name of pkg.
                sub = f"{origin}.{alias.name}"
                add(sub if sub in known else origin, node, runs)
        for child in ast.iter_child_nodes(node):
            visit(child, runs)

    visit(tree, True)
    return found


def all_imports(root: Path) -> list[Import]:
    files = module_files(root)
    known = set(files)
    return [imp for module, path in files.items() for imp in imports_of(module, path, known)]


def layer_violations(root: Path) -> list[str]:
    """One line per import that breaks the layering (or a module outside every layer)."""
    problems = []
    for module in module_files(root):
        if layer_of(module) is None:
            problems.append(f"{module}: in no layer (give it one in docs/architecture.md)")
    for imp in all_imports(root):
        src, dst = layer_of(imp.source), layer_of(imp.target)
        if src is None or dst is None or src == dst or dst in ALLOWED[src]:
            continue
        if (imp.source, imp.target) in EXCEPTIONS:
            continue
        problems.append(
            f"{imp.source} (line {imp.line}, layer {src}) imports {imp.target} (layer {dst})"
        )
    return problems


def import_cycles(root: Path) -> list[list[str]]:
    """The import cycles between modules (strongly connected components, Tarjan)."""
    graph: dict[str, set[str]] = {m: set() for m in module_files(root)}
    for imp in all_imports(root):
        if imp.runs and imp.target in graph and imp.target != imp.source:
            graph[imp.source].add(imp.target)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles: list[list[str]] = []

    def connect(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                connect(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            connect(v)
    return cycles


def has_reason(path: Path) -> bool:
    doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or ""
    return any(
        line.strip().startswith(REASON) and line.strip() != REASON for line in doc.splitlines()
    )


def oversized_without_reason(root: Path) -> list[str]:
    """Files over MAX_LINES lines whose docstring gives no reason, relative to `root`."""
    out = []
    for path in module_files(root).values():
        n_lines = len(path.read_text(encoding="utf-8").splitlines())
        if n_lines > MAX_LINES and not has_reason(path):
            out.append(f"{path.relative_to(root).as_posix()}: {n_lines} lines")
    return sorted(out)


# --- the project itself ---------------------------------------------------------------


def test_imports_follow_the_layers():
    assert layer_violations(REPO) == []


def test_no_import_cycle():
    assert import_cycles(REPO) == []


def test_exceptions_are_used():
    used = {(i.source, i.target) for i in all_imports(REPO)}
    assert set(EXCEPTIONS) <= used


def test_long_files_state_a_reason():
    pending = {f"{p}:" for p in PENDING_REASON}
    rest = [line for line in oversized_without_reason(REPO) if line.split()[0] not in pending]
    assert rest == []


def test_pending_list_is_current():
    over = {line.split(":")[0] for line in oversized_without_reason(REPO)}
    assert over >= PENDING_REASON, "drop the files that now state a reason or got shorter"


# --- the checker flags what it should -------------------------------------------------


def _tree(root: Path, files: dict[str, str]) -> Path:
    for rel, text in files.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    for folder in PACKAGE_FOLDERS.values():
        (root / folder).mkdir(parents=True, exist_ok=True)
    return root


def test_checker_flags_an_upward_import_even_inside_a_function(tmp_path: Path):
    root = _tree(
        tmp_path,
        {
            "lightcal/__init__.py": "",
            "lightcal/core/__init__.py": "",
            "lightcal/core/maths.py": (
                "def f():\n    from lightcal.pipeline.solve import solve\n    return solve\n"
            ),
            "lightcal/pipeline/__init__.py": "",
            "lightcal/pipeline/solve.py": "from ..core import maths\n\ndef solve(): ...\n",
        },
    )
    problems = layer_violations(root)
    assert problems == [
        "lightcal.core.maths (line 2, layer core) imports lightcal.pipeline.solve (layer pipeline)"
    ]


def test_checker_flags_a_module_outside_the_layers(tmp_path: Path):
    root = _tree(tmp_path, {"lightcal/__init__.py": "", "lightcal/misc.py": ""})
    assert layer_violations(root) == [
        "lightcal.misc: in no layer (give it one in docs/architecture.md)"
    ]


def test_checker_flags_a_cycle_but_not_a_type_checking_import(tmp_path: Path):
    files = {
        "lightcal/__init__.py": "",
        "lightcal/io/__init__.py": "",
        "lightcal/io/a.py": "from lightcal.io import b\n",
        "lightcal/io/b.py": "def g():\n    import lightcal.io.c\n",
        "lightcal/io/c.py": "from . import a\n",
        "lightcal/io/d.py": "from lightcal.io import e\n",
        "lightcal/io/e.py": (
            "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from lightcal.io import d\n"
        ),
    }
    root = _tree(tmp_path, files)
    assert import_cycles(root) == [["lightcal.io.a", "lightcal.io.b", "lightcal.io.c"]]


def test_checker_flags_a_long_file_without_a_reason(tmp_path: Path):
    body = "x = 1\n" * MAX_LINES
    root = _tree(
        tmp_path,
        {
            "lightcal/__init__.py": "",
            "lightcal/core/__init__.py": "",
            "lightcal/core/long.py": '"""Long."""\n' + body,
            "lightcal/core/reasoned.py": (
                '"""Long.\n\nOver 500 lines for a reason: one table.\n"""\n' + body
            ),
            "lightcal/core/short.py": '"""Short."""\n' + "x = 1\n" * (MAX_LINES - 1),
        },
    )
    assert oversized_without_reason(root) == [f"lightcal/core/long.py: {MAX_LINES + 1} lines"]


@pytest.mark.parametrize(
    ("module", "layer"),
    [
        ("lightcal", "base"),
        ("lightcal.errors", "base"),
        ("lightcal.core.kernels.wall", "core"),
        ("lightcal.report", "report"),
        ("lightcal.__main__", "cli"),
        ("lightcal_app.panels.light", "app"),
        ("lightcal.somewhere_new", None),
    ],
)
def test_layer_of(module: str, layer: str | None):
    assert layer_of(module) == layer
