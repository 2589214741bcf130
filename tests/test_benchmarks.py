"""``python -m benchmarks`` without an optional extra: one line saying which, then the rest."""

from __future__ import annotations

import importlib

import pytest
from conftest import REPO


def test_a_benchmark_whose_extra_is_missing_is_skipped_with_a_line(monkeypatch, capsys):
    import sys

    monkeypatch.syspath_prepend(str(REPO))
    main = importlib.import_module("benchmarks.__main__")
    real = importlib.import_module

    def without_torch(name, *args):
        if name == "benchmarks.bench_needs_torch":
            raise ModuleNotFoundError("No module named 'torch'", name="torch")
        if name == "benchmarks.bench_broken":
            raise ModuleNotFoundError("No module named 'kinectdata.nope'", name="kinectdata.nope")
        return real(name, *args)

    monkeypatch.setattr(main.importlib, "import_module", without_torch)
    monkeypatch.setattr(main, "table", lambda: "", raising=False)
    main.main(["bench_needs_torch"])
    out = capsys.readouterr().out
    assert "skipped: needs pip install 'kinectdata[train]' (torch is not installed)" in out
    with pytest.raises(ModuleNotFoundError):  # a missing module of our own is a bug, not an extra
        main.main(["bench_broken"])
    assert sys.modules.get("benchmarks.bench_needs_torch") is None
