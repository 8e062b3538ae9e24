"""The package's shape: no import cycles (function-level imports included), nothing imports the CLI, the command
line answers ``--help`` without loading the simulation, and the docs name only files of the repository."""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def _module_files() -> dict[str, Path]:
    """Module name -> source file of every module of the installed layout (kernels/ is aca_warp.kernels)."""
    out: dict[str, Path] = {}
    for root, prefix in ((REPO / "aca_warp", "aca_warp"), (REPO / "kernels", "aca_warp.kernels")):
        for f in root.rglob("*.py"):
            parts = list(f.relative_to(root).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join([prefix, *parts])] = f
    return out


def _imports(name: str, path: Path, modules: set[str]) -> set[str]:
    """The aca_warp modules ``name`` imports anywhere in its source (a ``from X import y`` of a submodule y
    counts as importing X.y)."""
    found: set[str] = set()
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            found.add(base)
            found.update(f"{base}.{a.name}" for a in node.names)
    return {m for m in found if m in modules and m != name}


def _graph() -> dict[str, set[str]]:
    files = _module_files()
    return {name: _imports(name, path, set(files)) for name, path in files.items()}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
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


def _package_parents(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    """The graph without the edge from a module to its own package (``import a.b`` runs ``a/__init__``, which is
    not a dependency of the code in a.b)."""
    return {m: {d for d in deps if not m.startswith(d + ".")} for m, deps in graph.items()}


def test_no_import_cycles() -> None:
    cycles = _cycles(_package_parents(_graph()))
    assert cycles == [], f"import cycles: {cycles}"


def test_cycle_finder_finds_a_cycle() -> None:
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_nothing_imports_the_cli() -> None:
    users = sorted(m for m, deps in _graph().items() if "aca_warp.cli" in deps)
    assert users == []


def test_help_loads_no_simulation_code() -> None:
    """Building the whole parser imports neither Warp nor SciPy nor h5py nor the sweep's code (``--help`` answers at
    once); an HF run's modules and a scene's checks (equal heights: no height law to draw) import no SciPy (it costs
    every ``aca-warp hf`` and ``lf`` process ≈ 0.4 s of CPU to start)."""
    code = (
        "import sys, aca_warp.cli as c; c.build_parser(); "
        "print(sorted(m for m in ('warp', 'scipy', 'h5py', 'matplotlib', 'aca_warp.sweep.run') if m in sys.modules)); "
        "import aca_warp.hf.runner, aca_warp.hf.general, aca_warp.hf.onchip, aca_warp.hf.rerun, aca_warp.lf.solver; "
        "from aca_warp.scene import preset; preset('hf1_equal'); "
        "print(sorted(m for m in sys.modules if m.split('.')[0] == 'scipy'))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["[]", "[]"], out


def test_docs_name_no_issue_numbers_or_outside_files() -> None:
    pattern = re.compile(r"\bissues? #?\d+\b|\.\./shared/|/work/shared", re.IGNORECASE)
    files = [REPO / "README.md", *(REPO / "docs").glob("*.md"), *REPO.glob("aca_warp/**/*.py")]
    files += [*REPO.glob("kernels/*.py"), *REPO.glob("scripts/*.py")]
    hits = [
        f"{f.relative_to(REPO)}:{i}: {line.strip()}"
        for f in files
        for i, line in enumerate(f.read_text().splitlines(), 1)
        if pattern.search(line)
    ]
    assert hits == []


def _package_map(text: str) -> set[str]:
    """Repository paths of the modules the package map of docs/architecture.md names: a ``### `folder/` `` heading,
    then one table row ``| `module.py` | ... |`` per module."""
    section = text.split("## Package map", 1)[1].split("\n## ", 1)[0]
    named: set[str] = set()
    folder = None
    for line in section.splitlines():
        heading = re.match(r"### `([\w/]+/)`", line)
        row = re.match(r"\| `([\w.]+\.py)` \|", line)
        if heading:
            folder = heading.group(1)
        elif row:
            assert folder is not None, f"row before any folder heading: {line}"
            named.add(folder + row.group(1))
    return named


def _needs_a_row(path: Path) -> bool:
    """Every module but an ``__init__.py`` that holds only its docstring (and the ``__future__`` import)."""
    if path.name != "__init__.py":
        return True
    body = ast.parse(path.read_text()).body
    docstring = [n for n in body if isinstance(n, ast.Expr) and isinstance(n.value, ast.Constant)]
    future = [n for n in body if isinstance(n, ast.ImportFrom) and n.module == "__future__"]
    return len(body) > len(docstring) + len(future)


def test_package_map_names_every_module() -> None:
    """docs/architecture.md has a row for every module of aca_warp/ and kernels/, and no row for a missing one."""
    named = _package_map((REPO / "docs" / "architecture.md").read_text())
    files = {str(p.relative_to(REPO)) for root in ("aca_warp", "kernels") for p in (REPO / root).rglob("*.py")}
    needed = {f for f in files if _needs_a_row(REPO / f)}
    assert sorted(needed - named) == [], "modules without a row in docs/architecture.md"
    assert sorted(named - files) == [], "rows of docs/architecture.md without a module"


def test_package_map_reader_finds_rows() -> None:
    text = "## Package map\n\n### `a/`\n\n| module | what |\n|---|---|\n| `b.py` | x |\n\n"
    text += "### `a/c/`\n\n| `d.py` | y |\n"
    assert _package_map(text + "\n## Next\n\n### `e/`\n\n| `f.py` | z |\n") == {"a/b.py", "a/c/d.py"}
