"""The architecture as checks: the layers of docs/architecture.md hold, lazy imports
included; no module imports itself through others; a function-level import of the
project's own code is rare, and says why it is there.

The contracts live in pyproject.toml (`[tool.importlinter]`); anyone can run them with
`.venv/bin/lint-imports`.
"""

from __future__ import annotations

import ast
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
PACKAGE = REPO / "ita"
#: function-level imports of ita's own modules allowed outside ita/cli/ (each for start-up time)
MAX_LAZY = 10


def _lint_imports() -> str:
    found = shutil.which("lint-imports", path=str(Path(sys.executable).parent)) or shutil.which("lint-imports")
    if found is None:
        pytest.fail("lint-imports is not installed (it comes with the test extras: pip install -e '.[test]')")
    return found


def test_the_import_contracts_hold():
    """Every contract of pyproject.toml: the layers from the commands down to the files,
    packages of one layer that must not know each other, and the measuring code that
    never imports the simulator."""
    proc = subprocess.run([_lint_imports(), "--no-cache"], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    assert "0 broken" in proc.stdout


def test_no_module_imports_itself_through_others():
    """No cycle among ita's modules (the layers rule out cycles between packages; this
    rules them out inside a package too), lazy imports included."""
    import grimp

    graph = grimp.build_graph("ita", exclude_type_checking_imports=True)
    cycles = _cycles(graph)
    assert not cycles, cycles


def _cycles(graph: object) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    counter = 0
    for root in sorted(graph.modules):  # type: ignore[attr-defined]
        if root in index:
            continue
        work = [(root, iter(sorted(graph.find_modules_directly_imported_by(root))))]  # type: ignore[attr-defined]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            for child in children:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.find_modules_directly_imported_by(child)))))  # type: ignore
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            else:
                work.pop()
                if work:
                    parent = work[-1][0]
                    low[parent] = min(low[parent], low[node])
                if low[node] == index[node]:
                    component = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        component.append(member)
                        if member == node:
                            break
                    if len(component) > 1:
                        found.append(sorted(component))
    return found


def _lazy_imports() -> list[tuple[str, int, str, str]]:
    """(file, line, module, comment) of each import of ita's own modules inside a function
    outside ita/cli/; the comment is the one on the import's line or the line above."""
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(REPO).as_posix()
        if rel.startswith("ita/cli/") or "/_resources/" in rel:
            continue
        text = path.read_text(encoding="utf-8")
        lines = text.splitlines()
        tree = ast.parse(text)
        for func in ast.walk(tree):
            if not isinstance(func, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            for node in ast.walk(func):
                if isinstance(node, ast.ImportFrom):
                    names = [node.module or ""] if node.level == 0 else ["ita"]
                elif isinstance(node, ast.Import):
                    names = [a.name for a in node.names]
                else:
                    continue
                for name in names:
                    if name == "ita" or name.startswith("ita."):
                        here = lines[node.lineno - 1]
                        above = lines[node.lineno - 2] if node.lineno > 1 else ""
                        comment = here.partition("#")[2] or above.strip().removeprefix("#")
                        found.append((rel, node.lineno, name, comment.strip()))
    return sorted(set(found))


def test_function_level_imports_are_few_and_say_why():
    """At most MAX_LAZY imports of ita's modules inside functions outside ita/cli/ (the
    CLI imports its commands' code when they run), each for start-up time and saying so."""
    lazy = _lazy_imports()
    listing = "\n".join(f"{f}:{n} {m}  # {c}" for f, n, m, c in lazy)
    assert len(lazy) <= MAX_LAZY, f"{len(lazy)} function-level imports:\n{listing}"
    silent = [f"{f}:{n} {m}" for f, n, m, c in lazy if "start-up" not in c]
    assert not silent, "without a comment saying what start-up time they save:\n" + "\n".join(silent)
