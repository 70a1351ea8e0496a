"""The package's layout: docs/architecture.md lists every module, the library never reaches into
the pipeline, studies or tests, and stages do not import one another."""

from __future__ import annotations

import ast
import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / "msk"
#: the modules the top level of ``msk/`` may hold besides its subpackages: the package's face
#: and the core types every room shares
TOP_LEVEL = {
    "__init__.py",
    "analogs.py",
    "exceptions.py",
    "metrics.py",
    "quality.py",
    "signal.py",
    "status.py",
    "timeseries.py",
    "trial.py",
    "units.py",
}


def _modules() -> set[str]:
    return {p.relative_to(REPO).as_posix() for p in PACKAGE.rglob("*.py")}


def _imports(path: Path) -> set[str]:
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
            names.update(f"{node.module}.{a.name}" for a in node.names)
    return names


def test_module_map_lists_every_module():
    text = (REPO / "docs" / "architecture.md").read_text(encoding="utf-8")
    listed = set(re.findall(r"^\| `(msk/[\w/]+\.py)` \|", text, flags=re.M))
    modules = _modules()
    assert not modules - listed, f"modules missing from docs/architecture.md: {modules - listed}"
    gone = listed - modules
    assert not gone, f"docs/architecture.md lists modules that do not exist: {gone}"


def test_top_level_holds_only_core_modules():
    top = {p.name for p in PACKAGE.glob("*.py")}
    assert top <= TOP_LEVEL, f"new top-level modules (give them a room): {top - TOP_LEVEL}"


def test_library_never_imports_studies_tests_or_the_pipeline():
    for path in PACKAGE.rglob("*.py"):
        rel = path.relative_to(PACKAGE).parts
        for name in _imports(path):
            root = name.split(".")[0]
            assert root not in {"studies", "tests"}, f"{path} imports {name}"
            below = rel[0] not in {"pipeline", "cli", "report", "__init__.py"}
            if below and name.startswith("msk.pipeline"):
                # the library below the pipeline never calls back into it
                raise AssertionError(f"{path} imports {name}")


def test_stages_do_not_import_one_another():
    infrastructure = {
        "__init__",
        "graph",
        "runner",
        "session",
        "inputs",
        "records",
        "batch",
        # a session-level runner like batch: runs the graph per trial, then pools the rows the
        # strength stage selects (msk strength)
        "pooled_strength",
    }
    stages = {p.stem for p in (PACKAGE / "pipeline").glob("*.py")} - infrastructure
    for stage in stages:
        for name in _imports(PACKAGE / "pipeline" / f"{stage}.py"):
            parts = name.split(".")
            if parts[:2] == ["msk", "pipeline"] and len(parts) > 2:
                assert parts[2] not in stages - {stage}, f"stage {stage} imports stage {parts[2]}"


def test_every_module_declares_its_public_names():
    missing = [
        p.relative_to(REPO).as_posix()
        for p in PACKAGE.rglob("*.py")
        if p.name != "__main__.py" and "__all__" not in p.read_text(encoding="utf-8")
    ]
    assert not missing, f"modules without __all__: {missing}"


def test_the_package_face_is_light_and_complete():
    """``import msk`` loads no numerical library; every name of ``msk.__all__`` resolves."""
    import subprocess
    import sys

    code = (
        "import sys, msk; heavy = [m for m in ('pinocchio', 'scipy', 'casadi') if m in sys.modules]"
        "; assert not heavy, heavy; [getattr(msk, n) for n in msk.__all__]"
    )
    subprocess.run([sys.executable, "-c", code], check=True, cwd=REPO)
