"""The free-running loss's world speed term: joints' speeds where the field's kinetic features
measure them, in the world, against a numpy computation of the same divergence."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from kinectdata.models.losses import (  # noqa: E402
    Body,
    masked_energy_loss,
    masked_jitter_loss,
    masked_world_jitter_loss,
    masked_world_speed_loss,
)

ROOT, FOOT, HEAD = 0, 1, 2
BONES = [(FOOT, ROOT), (HEAD, ROOT)]


def _world_dance(stepping: bool, frames: int = 90) -> np.ndarray:
    """[T, 3, 3] world positions (metres, y up) of a root, a foot and a head: the root sways along
    x; the foot steps along x twice as far (``stepping``: about the root it then moves as much as
    the planted foot does) or stays on the floor; the head rides on the root."""
    t = np.arange(frames) / 30.0
    root = np.stack([0.1 * np.sin(2 * np.pi * 0.5 * t), 0.9 + 0.02 * np.sin(2 * np.pi * t), 0.0 * t], axis=1)
    foot = np.zeros((frames, 3))
    foot[:, 0] = 2 * root[:, 0] if stepping else 0.0
    head = root + np.array([0.0, 0.7, 0.0])
    return np.stack([root, foot, head], axis=1)


def _centred(world: np.ndarray) -> np.ndarray:
    """Root-centred as the build makes them: the others relative to the root, the root kept."""
    c = world - world[:, :1]
    c[:, 0] = world[:, 0]
    return c


def _tensor(p: np.ndarray) -> torch.Tensor:
    return torch.tensor(p.reshape(1, len(p), -1), dtype=torch.float32)


def _body(centred: bool) -> Body:
    return Body(bones=BONES, scale=torch.ones(9), offset=torch.zeros(9), root=ROOT, centred=centred)


def _divergence(made: np.ndarray, real: np.ndarray, chunk: int, excess: bool = False) -> float:
    """numpy: per world component and stretch of ``chunk`` steps, 2 (r/m - log(r/m) - 1) of the mean
    squared steps (``excess``: m/r), floored at 1 % of the real ones' mean, averaged."""
    m, r = made.reshape(len(made), -1), real.reshape(len(real), -1)
    dm, dr = np.diff(m, axis=0) ** 2, np.diff(r, axis=0) ** 2
    bounds = range(0, len(dm), chunk)
    em = np.array([dm[a : a + chunk].mean(axis=0) for a in bounds])
    er = np.array([dr[a : a + chunk].mean(axis=0) for a in bounds])
    floor = 1e-2 * er.mean()
    ratio = (em + floor) / (er + floor) if excess else (er + floor) / (em + floor)
    return float(np.mean(2 * (ratio - np.log(ratio) - 1)))


def test_a_planted_foot_that_cancels_the_roots_sway_pays_only_in_the_world():
    """Root-centred, the still foot moves exactly as much as the stepping one: the speed term on the
    targets cannot tell them apart; the world term can, and equals the divergence numpy computes
    from the world positions."""
    stepping, planted = _world_dance(True), _world_dance(False)
    mask = torch.ones(1, len(stepping), 9, dtype=torch.bool)
    made, real = _tensor(_centred(planted)), _tensor(_centred(stepping))
    world = float(masked_world_speed_loss(made, real, mask, _body(centred=True), chunk=30))
    assert world == pytest.approx(_divergence(planted, stepping, 30), rel=1e-4)
    on_targets = float(masked_energy_loss(made, real, mask, 30))
    assert on_targets == pytest.approx(0.0, abs=1e-6)
    assert world > 1.0
    same = float(masked_world_speed_loss(real, real, mask, _body(centred=True), chunk=30))
    assert same == pytest.approx(0.0, abs=1e-6)


def test_world_positions_are_scored_as_they_are():
    stepping, planted = _world_dance(True), _world_dance(False)
    mask = torch.ones(1, len(stepping), 9, dtype=torch.bool)
    loss = float(masked_world_speed_loss(_tensor(planted), _tensor(stepping), mask, _body(centred=False), chunk=None))
    assert loss == pytest.approx(_divergence(planted, stepping, len(stepping) - 1), rel=1e-4)


def test_frames_where_the_root_is_missing_are_left_out():
    """A root-centred joint without its root has no place in the world: those frames do not count."""
    stepping, planted = _world_dance(True), _world_dance(False)
    mask = torch.ones(1, len(stepping), 9, dtype=torch.bool)
    mask[0, 60:, :3] = False  # the root is lost in the last 30 frames
    made, real = _tensor(_centred(planted)), _tensor(_centred(stepping))
    scrambled = made.clone()
    scrambled[0, 61:, 3:] = torch.randn(29, 6)  # whatever the others do there
    body = _body(centred=True)
    first = float(masked_world_speed_loss(made, real, mask, body, chunk=30))
    assert float(masked_world_speed_loss(scrambled, real, mask, body, chunk=30)) == pytest.approx(first, rel=1e-5)
    assert first == pytest.approx(_divergence(planted[:60], stepping[:60], 30), rel=1e-4)


def test_the_free_running_loss_adds_the_world_term_per_two_seconds():
    from kinectdata.models import losses

    stepping, planted = _world_dance(True), _world_dance(False)
    mask = torch.ones(1, len(stepping), 9, dtype=torch.bool)
    made, real, body = _tensor(_centred(planted)), _tensor(_centred(stepping)), _body(centred=True)
    chunk = round(losses.ENERGY_CHUNK_S * 30.0)
    whole = float(losses.masked_rhythm_loss(made, real, mask, 30.0, body, losses.RhythmWeights(posture=2.0)))
    without_body = float(losses.masked_rhythm_loss(made, real, mask, 30.0, None, losses.RhythmWeights(posture=2.0)))
    bones = float(losses.masked_bone_loss(made, real, mask, BONES, body.scale, body.offset))
    world = float(masked_world_speed_loss(made, real, mask, body, chunk))
    assert world > 1.0
    expected = without_body + 10.0 * bones + 1.0 * world  # RhythmWeights' default bone and world speed weights
    assert whole == pytest.approx(expected, rel=1e-5)


def test_the_excess_form_costs_a_bouncing_foot_more_than_a_still_one():
    """Turned round (``excess``), the world term charges a foot that moves where the dancer's stands
    in proportion and a foot that stands where the dancer's moves only in log ratio: the numpy
    divergence with made and real swapped, and the other way round from the plain term."""
    stepping, planted = _world_dance(True), _world_dance(False)
    mask = torch.ones(1, len(stepping), 9, dtype=torch.bool)
    body = _body(centred=True)
    bouncing, still = _tensor(_centred(stepping)), _tensor(_centred(planted))
    too_fast = float(masked_world_speed_loss(bouncing, still, mask, body, chunk=30, excess=True))
    too_slow = float(masked_world_speed_loss(still, bouncing, mask, body, chunk=30, excess=True))
    assert too_fast == pytest.approx(_divergence(stepping, planted, 30, excess=True), rel=1e-4)
    assert too_slow == pytest.approx(_divergence(planted, stepping, 30, excess=True), rel=1e-4)
    assert too_fast > too_slow
    plain_fast = float(masked_world_speed_loss(bouncing, still, mask, body, chunk=30))
    plain_slow = float(masked_world_speed_loss(still, bouncing, mask, body, chunk=30))
    assert plain_slow > plain_fast
    assert float(masked_world_speed_loss(still, still, mask, body, chunk=30, excess=True)) == pytest.approx(0, abs=1e-6)


def _swaying_trunk(with_root: bool, frames: int = 120) -> np.ndarray:
    """[T, 3, 3] world positions of a root swaying along x at 2 Hz and a head above it that sways
    with it, twice as far in the world (``with_root``), or against it, holding still in the world;
    the foot stays on the floor. Root-centred, the head moves as much either way."""
    t = np.arange(frames) / 30.0
    sway = 0.05 * np.sin(2 * np.pi * 2.0 * t)
    root = np.stack([sway, 0.9 + 0 * t, 0 * t], axis=1)
    head = np.stack([2 * sway if with_root else 0 * t, 1.6 + 0 * t, 0 * t], axis=1)
    return np.stack([root, np.zeros((frames, 3)), head], axis=1)


def test_a_trunk_swaying_with_the_root_pays_its_acceleration_only_in_the_world():
    """Root-centred, the head swaying with the root and the one swaying against it accelerate
    alike, so the jitter term on the targets cannot tell them apart; in the world the first head
    accelerates and the second holds still. The world jitter term equals numpy's divergence of the
    world accelerations and jerks, too much costing in proportion (made and real swapped cost
    less)."""
    swaying, steady = _swaying_trunk(True), _swaying_trunk(False)
    mask = torch.ones(1, len(swaying), 9, dtype=torch.bool)
    body = _body(centred=True)
    made, real = _tensor(_centred(swaying)), _tensor(_centred(steady))
    assert float(masked_jitter_loss(made, real, mask, 30)) == pytest.approx(0.0, abs=1e-5)
    world = float(masked_world_jitter_loss(made, real, mask, body, chunk=30))

    def numpy_jitter(m: np.ndarray, r: np.ndarray) -> float:
        m1, r1 = np.diff(m, axis=0), np.diff(r, axis=0)
        acceleration = _divergence(m1, r1, 30, excess=True)
        return acceleration + _divergence(np.diff(m1, axis=0), np.diff(r1, axis=0), 30, excess=True)

    assert world == pytest.approx(numpy_jitter(swaying, steady), rel=1e-4)
    assert world > 1.0
    backwards = float(masked_world_jitter_loss(real, made, mask, body, chunk=30))
    assert backwards == pytest.approx(numpy_jitter(steady, swaying), rel=1e-4)
    assert backwards < world
    assert float(masked_world_jitter_loss(made, made, mask, body, chunk=30)) == pytest.approx(0.0, abs=1e-6)
