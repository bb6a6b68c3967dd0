"""The layering of the package (DESIGN.md, "Layering"), checked on the source.

The core (scan, features, graph, correspondence, clique, pose, refine, match, validation,
uncertainty, config, geometry, errors, the kernels, the simulator) never imports file
formats, the data registry, plotting, the command line or the applications; applications
import the core, never the command line; only the command line imports typer and rich;
``import scanclique`` imports no numba and no application dependency.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[1] / "src" / "scanclique"

#: top-level parts of the package that are not the core
EDGE = {"io", "datasets", "plot", "cli", "tools", "eval", "pairsets", "__main__"}
APPLICATIONS = {"mapping", "slam", "places"}
#: the one allowed crossing: the clique engine is also a general solver that reads the
#: DIMACS format (DESIGN.md, stage 6), through the reader in io/, imported lazily
ALLOWED = {
    "clique/files.py": {"scanclique.io.dimacs", "scanclique.io.dimacs.read_dimacs"},
    "clique/graphs.py": {"scanclique.io.dimacs", "scanclique.io.dimacs.read_dimacs"},
}


def _module_name(path: Path) -> str:
    rel = path.relative_to(PKG.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _imports(path: Path) -> set[str]:
    """Fully qualified modules that ``path`` imports (relative imports resolved)."""
    name = _module_name(path)
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            out.add(mod)
            out.update(f"{mod}.{a.name}" for a in node.names)
    return out


def _part(module: str) -> str | None:
    """The top-level part of scanclique a module belongs to (``scanclique.io.carmen`` ->
    ``io``), None outside the package."""
    parts = module.split(".")
    if parts[0] != "scanclique" or len(parts) < 2:
        return None
    return parts[1]


SOURCES = sorted(p for p in PKG.rglob("*.py") if "__pycache__" not in p.parts)


def _part_of_file(path: Path) -> str:
    rel = path.relative_to(PKG)
    return rel.parts[0].removesuffix(".py")


CORE = [p for p in SOURCES if _part_of_file(p) not in EDGE | APPLICATIONS | {"__init__"}]
APPS = [p for p in SOURCES if _part_of_file(p) in APPLICATIONS]


def test_the_split_finds_the_core_and_the_applications():
    names = {_module_name(p) for p in CORE}
    assert {"scanclique.match", "scanclique.validation", "scanclique.clique"} <= names
    assert not any(_part(n) in {"io", "cli", "tools"} for n in names)
    assert {_part_of_file(p) for p in APPS} == APPLICATIONS


@pytest.mark.parametrize("path", CORE, ids=lambda p: str(p.relative_to(PKG)))
def test_core_imports_no_edge_and_no_application(path):
    bad = {m for m in _imports(path) if _part(m) in EDGE | APPLICATIONS}
    bad -= ALLOWED.get(str(path.relative_to(PKG)), set())
    assert not bad, f"{path.relative_to(PKG)} imports {sorted(bad)}"
    ui = {m for m in _imports(path) if m.split(".")[0] in {"typer", "rich", "matplotlib"}}
    assert not ui, f"{path.relative_to(PKG)} imports {sorted(ui)}"


@pytest.mark.parametrize("path", APPS, ids=lambda p: str(p.relative_to(PKG)))
def test_applications_import_no_command_line(path):
    bad = {m for m in _imports(path) if _part(m) in {"cli"}}
    bad |= {m for m in _imports(path) if m.split(".")[0] in {"typer"}}
    assert not bad, f"{path.relative_to(PKG)} imports {sorted(bad)}"


def test_import_scanclique_is_light():
    code = (
        "import sys, scanclique as sc; sc.__version__; "
        "heavy = [m for m in ('numba', 'gtsam', 'dask', 'distributed', 'sqlite3', 'typer', "
        "'matplotlib', 'scanclique.mapping', 'scanclique.slam', 'scanclique.places') "
        "if m in sys.modules]; print(heavy)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout + out.stderr


def test_public_names_load_on_first_use():
    import scanclique as sc

    assert callable(sc.match_scans) and callable(sc.read_scans)
    assert sc.places.__name__ == "scanclique.places"
    assert callable(sc.map_scans) and callable(sc.slam.ekf_slam)
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        sc.nope  # noqa: B018
