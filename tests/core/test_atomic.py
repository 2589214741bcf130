"""Atomic writes flush to disk unless KINECTDATA_FSYNC says not to, and stay atomic either way."""

from __future__ import annotations

import os

import pytest

from kinectdata.core import atomic
from kinectdata.core.atomic import atomic_output, durable


@pytest.fixture
def fsyncs(monkeypatch):
    """The file descriptors os.fsync was given, in order (the real call still made)."""
    seen = []
    real = os.fsync

    def counting(fd):
        seen.append(fd)
        real(fd)

    monkeypatch.setattr(atomic.os, "fsync", counting)
    return seen


@pytest.mark.parametrize(
    ("value", "flushed"), [(None, True), ("1", True), ("0", False), ("off", False), ("False", False)]
)
def test_the_environment_decides_whether_writes_are_flushed(monkeypatch, value, flushed):
    if value is None:
        monkeypatch.delenv("KINECTDATA_FSYNC", raising=False)
    else:
        monkeypatch.setenv("KINECTDATA_FSYNC", value)
    assert durable() is flushed


def test_a_durable_write_flushes_the_file_and_its_folder(monkeypatch, tmp_path, fsyncs):
    monkeypatch.delenv("KINECTDATA_FSYNC", raising=False)
    with atomic_output(tmp_path / "out.txt") as tmp:
        tmp.write_text("done")
    assert (tmp_path / "out.txt").read_text() == "done"
    assert len(fsyncs) == (2 if os.name == "posix" else 1)  # the file, then the folder's rename


def test_without_flushing_a_write_is_still_atomic(monkeypatch, tmp_path, fsyncs):
    monkeypatch.setenv("KINECTDATA_FSYNC", "0")
    (tmp_path / "out.txt").write_text("old")
    with pytest.raises(RuntimeError), atomic_output(tmp_path / "out.txt") as tmp:
        tmp.write_text("half")
        raise RuntimeError("killed mid-write")
    assert (tmp_path / "out.txt").read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]  # no .partial left behind
    with atomic_output(tmp_path / "out.txt") as tmp:
        tmp.write_text("new")
    assert (tmp_path / "out.txt").read_text() == "new"
    assert fsyncs == []
