"""pyproject.toml says what the wheel holds and needs: every package folder, every
third-party import (the wheel itself is built and installed in tests/test_wheel.py)."""

from __future__ import annotations

import ast
import re
import sys
import tomllib
from importlib.metadata import packages_distributions
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((REPO / "pyproject.toml").read_text())
SETUPTOOLS = PYPROJECT["tool"]["setuptools"]


def package_folder(name: str) -> Path:
    """The folder of package `name` by pyproject's package-dir (longest prefix wins)."""
    mapping = SETUPTOOLS.get("package-dir", {})
    parts = name.split(".")
    for i in range(len(parts), 0, -1):
        prefix = ".".join(parts[:i])
        if prefix in mapping:
            return REPO / mapping[prefix] / Path(*parts[i:])
    return REPO / Path(*parts)


def test_every_package_folder_is_listed() -> None:
    listed = set(SETUPTOOLS["packages"])
    for name in listed:
        assert package_folder(name).is_dir(), name
    code = {
        ".".join(p.parent.relative_to(root).parts)
        for root in (REPO, REPO / "app")
        for top in ("lightcal", "lightcal_app")
        for p in (root / top).rglob("__init__.py")
        if "__pycache__" not in p.parts
    }
    data = {
        f"{package}.{'.'.join(d.relative_to(package_folder(package)).parts)}"
        for package in ("lightcal.sample_data", "lightcal_app.static")
        for d in package_folder(package).rglob("*")
        if d.is_dir() and d.name != "__pycache__"
    }
    missing = sorted((code | data) - listed)
    assert missing == [], f"add to [tool.setuptools] packages in pyproject.toml: {missing}"


def imported_top_level(folder: Path) -> set[str]:
    """The top-level names of every import in the Python files under `folder`."""
    names = set()
    for path in folder.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                names.update(alias.name.split(".")[0] for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names.add(node.module.split(".")[0])
    return names


def normalise(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def test_every_third_party_import_is_a_declared_dependency_and_back() -> None:
    declared = {
        normalise(re.split(r"[\s<>=!~;\[]", req, maxsplit=1)[0])
        for req in PYPROJECT["project"]["dependencies"]
    }
    third_party = (imported_top_level(REPO / "lightcal") | imported_top_level(REPO / "app")) - {
        "lightcal",
        "lightcal_app",
        *sys.stdlib_module_names,
    }
    by_module = packages_distributions()
    needed = {}
    for module in sorted(third_party):
        assert module in by_module, f"{module} is imported but not installed"
        needed[module] = {normalise(d) for d in by_module[module]}
    undeclared = sorted(m for m, dists in needed.items() if not dists & declared)
    assert undeclared == [], f"imported but not in [project] dependencies: {undeclared}"
    used = set().union(*needed.values())
    assert sorted(declared - used) == [], "declared but never imported"
