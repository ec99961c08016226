"""The package's layers: a module imports only from lower layers (DESIGN.md, "Layers")."""

from __future__ import annotations

import ast
import pathlib

import pytest

PACKAGE = pathlib.Path(__file__).resolve().parent.parent / "qube_suite"

ABOVE_DOMAINS = ("qube_suite.baselines", "qube_suite.policies", "qube_suite.training", "qube_suite.cli",
                 "qube_suite.evaluation", "qube_suite.suite")
"""What the domains must never import, not even inside a function: controllers, policies, training, the
CLI, and `suite`, which builds the domains' reset controllers and hands them in."""


def imported_modules(path: pathlib.Path) -> set[str]:
    """Every module `path` imports (absolute names; `from qube_suite import x` counts as qube_suite.x)."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
            names.update(f"{node.module}.{alias.name}" for alias in node.names)
    return names


@pytest.mark.parametrize("path", sorted((PACKAGE / "domains").glob("*.py")), ids=lambda p: p.name)
def test_domains_import_no_controllers_policies_training_or_cli(path):
    forbidden = sorted(name for name in imported_modules(path)
                       if any(name == top or name.startswith(top + ".") for top in ABOVE_DOMAINS))
    assert not forbidden, f"{path.name} imports {forbidden}"
