"""The free-running loss's foot term against EDGE's foot contact score as the evaluation computes it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from kinectdata.evaluation.field_scores import Y_UP_TO_Z_UP  # noqa: E402
from kinectdata.evaluation.metrics.foot_contact import foot_contact_score  # noqa: E402
from kinectdata.models.losses import masked_foot_loss  # noqa: E402

FEET = (7, 10, 8, 11)  # SMPL-24 left ankle, left foot, right ankle, right foot


def _dance(seed: int, slide: float, frames: int = 120) -> np.ndarray:
    """[T, 24, 3] y-up positions (metres): a body that sways and bobs with its root, feet on the
    floor that slide by ``slide``."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames) / 30.0
    body = rng.normal(0.0, 0.3, (24, 3))
    root = np.stack([0.2 * np.sin(2 * np.pi * 0.7 * t), 0.05 * np.sin(2 * np.pi * 1.9 * t), 0.1 * t], axis=1)
    p = body[None] + root[:, None]
    p[:, 0] = root
    for k, j in enumerate(FEET):
        p[:, j] = body[j]
        p[:, j, 0] += slide * np.sin(2 * np.pi * (1.1 + 0.3 * k) * t + k)
        p[:, j, 2] += slide * np.cos(2 * np.pi * (0.9 + 0.2 * k) * t)
    return p


def _feet_weights() -> torch.Tensor:
    w = torch.zeros(4, 24)
    for k, j in enumerate(FEET):
        w[k, j] = 1.0
    return w


def _loss(made: np.ndarray, real: np.ndarray, centred: bool = False) -> float:
    x = torch.tensor(made.reshape(1, len(made), -1), dtype=torch.float32)
    y = torch.tensor(real.reshape(1, len(real), -1), dtype=torch.float32)
    ones = torch.ones(72)
    mask = torch.ones_like(y, dtype=torch.bool)
    return float(masked_foot_loss(x, y, mask, _feet_weights(), ones, torch.zeros(72), root=0, centred=centred))


def test_the_foot_term_is_the_squared_log_excess_of_edges_score():
    made, real = _dance(0, 0.05), _dance(1, 0.01)
    edge_made = foot_contact_score(made @ Y_UP_TO_Z_UP.T, 30.0, up_axis=2)
    edge_real = foot_contact_score(real @ Y_UP_TO_Z_UP.T, 30.0, up_axis=2)
    assert edge_made > 2 * edge_real
    floor = 1e-2 * edge_real
    expected = np.log((edge_made + floor) / (edge_real + floor)) ** 2
    assert _loss(made, real) == pytest.approx(expected, rel=1e-3)


def test_feet_planted_more_than_the_dancers_cost_nothing():
    assert _loss(_dance(0, 0.01), _dance(1, 0.05)) == 0.0
    assert _loss(_dance(0, 0.03), _dance(0, 0.03)) == pytest.approx(0.0, abs=1e-9)


def test_root_centred_positions_get_the_root_back():
    made, real = _dance(0, 0.05), _dance(1, 0.01)

    def centred(p):
        c = p - p[:, :1]
        c[:, 0] = p[:, 0]
        return c

    assert _loss(centred(made), centred(real), centred=True) == pytest.approx(_loss(made, real), rel=1e-4)


def test_training_finds_the_feet_through_the_joint_sets_smpl24_mapping():
    """tang2018's feet: the SMPL-24 foot is the midpoint of heel and toe (its shipped mapping)."""
    from kinectdata.core.jointsets import load_joint_set
    from kinectdata.targets.specs import TargetSpec
    from kinectdata.training.train import _feet

    names = load_joint_set("tang2018").names
    spec = TargetSpec.from_dict(
        {
            "name": "all",
            "description": "every joint",
            "joint_set": "tang2018",
            "positions": list(names),
            "orientations": [],
            "root": "pelvis",
        }
    )
    feet = _feet(spec)
    import kinectdata

    shipped = Path(kinectdata.__file__).parent / "schemas/jointsets/to_smpl24/tang2018.json"
    mapping = json.loads(shipped.read_text())["joints"]
    for row, joint in zip(feet, ("left_ankle", "left_foot", "right_ankle", "right_foot")):
        expected = dict(mapping[joint]["from"])
        got = {spec.positions[i]: float(w) for i, w in enumerate(row) if w}
        assert got == pytest.approx(expected)
    without_heel = TargetSpec.from_dict({**spec.to_dict(), "positions": [n for n in names if n != "left_heel"]})
    assert _feet(without_heel) is None  # the left foot needs its heel: no foot term
