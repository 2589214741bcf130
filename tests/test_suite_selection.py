"""Which tests a run selects: a plain ``pytest`` leaves out the long tests (marked ``slow``), CI and
``--slow`` run them first; so CI cannot lose them unseen (tests/conftest.py)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest
from conftest import pytest_collection_modifyitems


class Item:
    def __init__(self, name: str, slow: bool):
        self.name, self.slow = name, slow

    def get_closest_marker(self, name: str):
        return object() if name == "slow" and self.slow else None


def _selected(monkeypatch, ci: bool, args=("tests",), **options) -> tuple[list[str], list[str]]:
    if ci:
        monkeypatch.setenv("CI", "1")
    else:
        monkeypatch.delenv("CI", raising=False)
    left_out: list[str] = []
    config = SimpleNamespace(
        args=list(args),
        getoption=lambda name: options.get(name.lstrip("-"), {"markexpr": ""}.get(name, False)),
        hook=SimpleNamespace(pytest_deselected=lambda items: left_out.extend(i.name for i in items)),
    )
    items = [Item("quick_a", False), Item("long_a", True), Item("quick_b", False), Item("long_b", True)]
    pytest_collection_modifyitems(config, items)
    return [i.name for i in items], left_out


def test_ci_runs_every_test_the_long_ones_first(monkeypatch):
    assert _selected(monkeypatch, ci=True) == (["long_a", "long_b", "quick_a", "quick_b"], [])


def test_a_plain_run_leaves_out_the_long_tests_and_says_so(monkeypatch):
    assert _selected(monkeypatch, ci=False) == (["quick_a", "quick_b"], ["long_a", "long_b"])


@pytest.mark.parametrize(
    ("args", "options"),
    [(("tests",), {"slow": True}), (("tests",), {"markexpr": "slow"}), (("tests/x.py::test_long",), {})],
    ids=["--slow", "-m", "named"],
)
def test_asking_for_them_runs_them(monkeypatch, args, options):
    assert _selected(monkeypatch, False, args, **options)[0] == ["long_a", "long_b", "quick_a", "quick_b"]
