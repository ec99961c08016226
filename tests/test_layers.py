"""The package's layers hold: the contract in pyproject.toml ([tool.importlinter], drawn in
docs/architecture.md), checked with import-linter."""

from __future__ import annotations

import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent
CHECK = ("import sys; from importlinter.cli import lint_imports; "
         "sys.exit(lint_imports(config_filename=sys.argv[1], no_cache=True))")


def test_the_layer_contract_holds():
    pytest.importorskip("importlinter")
    result = subprocess.run([sys.executable, "-c", CHECK, str(ROOT / "pyproject.toml")], cwd=ROOT,
                            capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr


def test_the_contract_catches_a_domain_importing_a_controller(tmp_path):
    # The same contracts, with one upward import added to what the checker sees: it must fail.
    pytest.importorskip("importlinter")
    package = tmp_path / "qube_suite"
    subprocess.run(["cp", "-r", str(ROOT / "qube_suite"), str(package)], check=True)
    (package / "domains" / "upward.py").write_text("from qube_suite.devices.qube import controllers\n",
                                                   encoding="utf-8")
    (tmp_path / "pyproject.toml").write_text((ROOT / "pyproject.toml").read_text(encoding="utf-8"),
                                             encoding="utf-8")
    result = subprocess.run([sys.executable, "-c", CHECK, str(tmp_path / "pyproject.toml")], cwd=tmp_path,
                            capture_output=True, text=True, env={"PYTHONPATH": str(tmp_path), "PATH": ""})
    assert result.returncode != 0
    assert "qube_suite.domains.upward -> qube_suite.devices.qube.controllers" in result.stdout
