"""The package's layers (docs/architecture.md), enforced: the import-linter contracts in
pyproject.toml hold for the package as installed, and they do break on an upward import."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import kinectdata

REPO = Path(__file__).resolve().parents[1]
PYPROJECT = REPO / "pyproject.toml"

pytest.importorskip("importlinter")


def _lint(config: Path, package_parent: Path | None = None) -> subprocess.CompletedProcess:
    """Run import-linter with ``config`` in a fresh interpreter (so the package it analyses is the one
    found first on the path, not one this process has imported); no cache is written."""
    env = {"PYTHONPATH": str(package_parent)} if package_parent else {}
    code = "import sys; from importlinter.cli import lint_imports_command; sys.exit(lint_imports_command())"
    return subprocess.run(
        [sys.executable, "-c", code, "--config", str(config), "--no-cache"],
        capture_output=True,
        text=True,
        cwd=config.parent,
        env={**_base_env(), **env},
        timeout=120,
    )


def _base_env() -> dict[str, str]:
    import os

    return {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}


def test_layers_and_no_cycles_hold():
    result = _lint(PYPROJECT)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "2 kept, 0 broken" in result.stdout


def test_an_upward_import_breaks_the_contract(tmp_path):
    copy = tmp_path / "pkg" / "kinectdata"
    shutil.copytree(Path(kinectdata.__file__).parent, copy, ignore=shutil.ignore_patterns("__pycache__"))
    with open(copy / "core" / "motion.py", "a") as f:
        f.write("\nfrom kinectdata.dataset.layout import MANIFEST  # noqa: E402,F401  core importing a higher layer\n")
    config = tmp_path / "pyproject.toml"
    config.write_text(PYPROJECT.read_text())
    result = _lint(config, tmp_path / "pkg")
    assert result.returncode != 0
    assert "kinectdata.core is not allowed to import kinectdata.dataset" in result.stdout
    assert "kinectdata.core.motion -> kinectdata.dataset.layout" in result.stdout
