"""Fixtures of the model tests."""

from __future__ import annotations

import pytest


@pytest.fixture
def one_thread():
    """Small tensors: one thread is fastest, and two stall badly when the other core is busy."""
    torch = pytest.importorskip("torch")
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)
