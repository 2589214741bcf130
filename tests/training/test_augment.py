"""Silence drawn into training windows: the features of silence, and windows whose music stops and
whose dancer holds the pose from there."""

from __future__ import annotations

import math

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from kinectdata.features import PRESETS, compute_features, feature_config  # noqa: E402
from kinectdata.training.augment import (  # noqa: E402
    MIN_MUSIC_FRACTION,
    MIN_SILENT_FRAMES,
    silence_windows,
    silent_frame,
)

FPS = 30.0


@pytest.mark.parametrize("preset", ["yalta2016", "listen_to_dance"])
def test_the_silent_frame_is_what_the_features_of_a_long_silence_hold(preset):
    config = PRESETS[preset]
    silent = silent_frame(config.to_dict(), FPS)
    assert tuple(silent.shape) == tuple(config.output_shape)
    # five seconds of digital silence through the features, frames on the 30 fps clock; a middle one
    cfg = feature_config(config.to_dict())
    starts = np.round(np.arange(150) * cfg.sample_rate / FPS).astype(np.int64)
    frames, padded = compute_features(np.zeros(5 * cfg.sample_rate, np.float32), starts, cfg)
    assert not padded[75]
    np.testing.assert_array_equal(silent.numpy(), frames[75])
    # the documented values: yalta2016's silent frames are the constant 0.1 (the bottom of its 0.1..0.9
    # range); the mel features put the -80 dB floor at 0 of their -80..20 dB range
    expected = 0.1 if preset == "yalta2016" else 0.0
    np.testing.assert_allclose(silent.numpy(), expected, rtol=0, atol=1e-7)


def batch(B: int = 8, L: int = 120, D: int = 4, seed: int = 0) -> dict:
    """A batch shaped as WindowDataset's: audio [B, L, 2, 3] (never the silent value), pose [B, L, D]
    frames 1..L of a motion whose frames 0..L-1 are ``previous``, their masks, and the name along."""
    g = torch.Generator().manual_seed(seed)
    motion = torch.randn(B, L + 1, D, generator=g)
    mask = torch.rand(B, L + 1, D, generator=g) > 0.2
    return {
        "audio": 0.5 + torch.rand(B, L, 2, 3, generator=g),
        "pose": motion[:, 1:].clone(),
        "previous": motion[:, :-1].clone(),
        "mask": mask[:, 1:].clone(),
        "previous_mask": mask[:, :-1].clone(),
        "names": [f"w{b}" for b in range(B)],
    }


SILENT = torch.full((2, 3), 0.1)


def silenced_from(original: dict, out: dict, b: int) -> int | None:
    """The frame from which window b's audio is silent to its end (None: never), found by search."""
    L = original["audio"].shape[1]
    quiet = [bool((out["audio"][b, t] == SILENT).all()) for t in range(L)]
    if not quiet[-1]:
        return None
    s = L - 1
    while s > 0 and quiet[s - 1]:
        s -= 1
    return s


def test_every_window_is_silenced_from_a_frame_in_range_and_holds_its_pose_from_there():
    L = 120
    original = batch(B=64, L=L)
    kept = {k: v.clone() for k, v in original.items() if torch.is_tensor(v)}
    out = silence_windows(original, SILENT, 1.0, torch.Generator().manual_seed(3))
    for k, v in kept.items():  # the given tensors are left as they were
        assert torch.equal(original[k], v)
    assert out["names"] is original["names"]
    lo, hi = math.ceil(0.25 * L), L - 30
    assert (MIN_MUSIC_FRACTION, MIN_SILENT_FRAMES) == (0.25, 30)
    starts = []
    for b in range(64):
        s = silenced_from(original, out, b)
        assert s is not None and lo <= s <= hi
        starts.append(s)
        assert torch.equal(out["audio"][b, :s], original["audio"][b, :s])
        assert torch.equal(out["pose"][b, :s], original["pose"][b, :s])
        assert torch.equal(out["mask"][b, :s], original["mask"][b, :s])
        held, held_mask = original["pose"][b, s - 1], original["mask"][b, s - 1]
        assert torch.equal(out["pose"][b, s:], held.expand(L - s, -1))
        assert torch.equal(out["mask"][b, s:], held_mask.expand(L - s, -1))
        assert torch.equal(out["previous"][b, : s + 1], original["previous"][b, : s + 1])
        assert torch.equal(out["previous"][b, s + 1 :], held.expand(L - s - 1, -1))
        assert torch.equal(out["previous_mask"][b, s + 1 :], held_mask.expand(L - s - 1, -1))
    # teacher forcing still sees the pose of the frame before: previous[t] == pose[t - 1] everywhere
    assert torch.equal(out["previous"][:, 1:], out["pose"][:, :-1])
    assert torch.equal(out["previous_mask"][:, 1:], out["mask"][:, :-1])
    assert min(starts) < lo + 10 and max(starts) > hi - 10 and len(set(starts)) > 20  # drawn over the range


def test_with_a_context_the_silence_starts_where_the_losses_look_after_some_music():
    L, context = 120, 70  # the losses see frames 70..119: music for at least ceil(0.25 * 50) of them
    original = batch(B=64, L=L)
    out = silence_windows(original, SILENT, 1.0, torch.Generator().manual_seed(3), context)
    starts = [silenced_from(original, out, b) for b in range(64)]
    assert all(s is not None and context + 13 <= s <= L - 30 for s in starts), starts
    assert min(starts) == context + 13 and max(starts) == L - 30


def test_share_zero_changes_nothing_and_a_share_silences_about_that_many():
    original = batch(B=16)
    out = silence_windows(original, SILENT, 0.0, torch.Generator().manual_seed(0))
    for k in ("audio", "pose", "previous", "mask", "previous_mask"):
        assert torch.equal(out[k], original[k])
    original = batch(B=400, L=60)
    out = silence_windows(original, SILENT, 0.3, torch.Generator().manual_seed(1))
    silenced = sum(silenced_from(original, out, b) is not None for b in range(400))
    assert 90 <= silenced <= 150  # binomial(400, 0.3): 120 +- 9


def test_windows_too_short_for_music_and_a_silence_are_left_alone():
    original = batch(B=8, L=39)  # ceil(0.25 * 39) = 10 frames of music, then at least 30 of silence: 40
    out = silence_windows(original, SILENT, 1.0, torch.Generator().manual_seed(0))
    for k in ("audio", "pose", "previous", "mask", "previous_mask"):
        assert torch.equal(out[k], original[k])
    original = batch(B=8, L=40)  # exactly long enough: silent from frame 10
    out = silence_windows(original, SILENT, 1.0, torch.Generator().manual_seed(0))
    assert [silenced_from(original, out, b) for b in range(8)] == [10] * 8


def test_the_same_seed_gives_the_same_windows():
    original = batch(B=32)
    one = silence_windows(original, SILENT, 0.5, torch.Generator().manual_seed(11))
    two = silence_windows(original, SILENT, 0.5, torch.Generator().manual_seed(11))
    other = silence_windows(original, SILENT, 0.5, torch.Generator().manual_seed(12))
    for k in ("audio", "pose", "previous", "mask", "previous_mask"):
        assert torch.equal(one[k], two[k])
    assert not torch.equal(one["audio"], other["audio"])
