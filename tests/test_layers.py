"""The layering the code keeps (pyproject.toml's ``[tool.importlinter]``): ``flow/`` imports nothing from
``nodes/``; ``nodes/`` is in layers, app > evaluation > method > photo > model > geometry, each importing
only those below it; writing a run's files (``app/outputs``) imports neither the report nor the photo's page."""
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def test_the_import_contracts_are_kept():
    pytest.importorskip("importlinter")
    proc = subprocess.run([sys.executable, "-c", "import sys; from importlinter.cli import lint_imports_command; "
                           "sys.argv = ['lint-imports', '--no-cache']; lint_imports_command()"],
                          capture_output=True, text=True, cwd=REPO, timeout=120)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:]
    assert "4 kept, 0 broken" in proc.stdout, proc.stdout[-3000:]


def _functions(root: Path):
    """(file, qualified name, lines) of every function and method under ``root``."""
    import ast

    for path in sorted(root.rglob("*.py")):
        tree = ast.parse(path.read_text())
        stack = [(tree, "")]
        while stack:
            node, prefix = stack.pop()
            for child in ast.iter_child_nodes(node):
                if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                    name = f"{prefix}{child.name}"
                    if not isinstance(child, ast.ClassDef):
                        yield path.relative_to(REPO), name, child.end_lineno - child.lineno + 1
                    stack.append((child, name + "."))


def test_no_function_of_the_product_is_too_long_or_too_branched():
    """The house stays changeable in one place (issue 40): no function in flow/ or nodes/ longer than 80
    lines or with a cyclomatic complexity (radon's) above 15."""
    cc = pytest.importorskip("radon.complexity")
    long = [f"{f}:{name} ({n} lines)" for root in ("flow", "nodes") for f, name, n in _functions(REPO / root) if n > 80]
    branched = []
    for root in ("flow", "nodes"):
        for path in sorted((REPO / root).rglob("*.py")):
            for block in cc.cc_visit(path.read_text()):
                for b in [block, *getattr(block, "methods", []), *getattr(block, "closures", [])]:
                    if b.complexity > 15:
                        branched.append(f"{path.relative_to(REPO)}:{b.fullname} ({b.complexity})")
    assert not long, long
    assert not branched, sorted(set(branched))


def test_no_file_of_the_product_is_too_long_and_no_class_too_large():
    """Each thing in its own place (issue 63): no file in flow/ or nodes/ over 500 lines, no class over 150
    (runner.py's StoredRun was 360, relight/face.py's FaceRelight 343; photo/loader.py 701 lines)."""
    import ast

    long_files, large_classes = [], []
    for root in ("flow", "nodes"):
        for path in sorted((REPO / root).rglob("*.py")):
            text = path.read_text()
            if len(text.splitlines()) > 500:
                long_files.append(f"{path.relative_to(REPO)} ({len(text.splitlines())} lines)")
            for node in ast.walk(ast.parse(text)):
                if isinstance(node, ast.ClassDef) and node.end_lineno - node.lineno + 1 > 150:
                    large_classes.append(f"{path.relative_to(REPO)}:{node.name} ({node.end_lineno - node.lineno + 1})")
    assert not long_files, long_files
    assert not large_classes, large_classes
