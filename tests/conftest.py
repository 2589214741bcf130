"""Shared test fixtures: paths to the bundled real files and small generated recordings."""

from __future__ import annotations

from pathlib import Path

import pytest

DATA = Path(__file__).parent / "data"
REPO = Path(__file__).parent.parent


@pytest.fixture
def fixture_csv() -> Path:
    """A real Kinect v2 recording in the KinectReader dialect (MIT, see tests/data/kinect_v2_csv)."""
    return DATA / "kinect_v2_csv" / "Ges01_wavehand.csv"
