"""The travel drawn at generation (kinectdata.targets.travel): the velocity's statistics against the
formulas of two first-order stages, the fit recovering a known process from root tracks (its fast
steps filtered out), silence, gaps in a track, and the stream against the whole song; the floor: the
pull's time constant recovered from sampled dancers, the pull's part of a draw against its closed
form, a start outside the floor, and a record from before floors drawn as it was."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kinectdata.core.errors import ConfigError
from kinectdata.core.jointsets import load_joint_set
from kinectdata.targets.slow_process import two_stage
from kinectdata.targets.specs import TargetSpec, generic_target
from kinectdata.targets.travel import (
    TravelProcess,
    TravelStream,
    draw_travel,
    fit_travel,
    pull_time_constant,
    slow_velocity,
    travel_targets,
)

FPS = 30.0
SPEC = generic_target("positions", load_joint_set("tang2018"))


def _velocity(place: np.ndarray) -> np.ndarray:
    return np.diff(place, axis=0, prepend=np.zeros((1, 2))) * FPS


def test_the_drawn_velocity_has_the_processs_spread_and_time_scale():
    process = TravelProcess(0.35, 0.5)
    velocity = _velocity(draw_travel(process, np.ones(200_000, bool), FPS, np.random.default_rng(1)))[1000:]
    for axis in (0, 1):
        v = velocity[:, axis]
        assert np.sqrt(np.mean(v**2)) == pytest.approx(0.35, rel=0.04)
        for seconds in (0.25, 0.5, 1.0):  # (1 + t / tau) exp(-t / tau)
            lag = round(seconds * FPS)
            seen = float((v[:-lag] * v[lag:]).mean() / (v * v).mean())
            assert seen == pytest.approx((1 + seconds / 0.5) * math.exp(-seconds / 0.5), abs=0.04)
    assert abs(np.corrcoef(velocity[:, 0], velocity[:, 1])[0, 1]) < 0.03  # the axes drawn apart


def test_the_fit_recovers_a_known_process_under_fast_steps():
    # a process slow enough that the low-pass keeps it (a faster one is fitted as its slowed self)
    truth = TravelProcess(0.3, 1.5)
    rng = np.random.default_rng(2)
    tracks = []
    for _ in range(30):  # 2-minute dances whose steps sway the root 5 cm at 1.5 Hz on top of the travel
        place = draw_travel(truth, np.ones(3600, bool), FPS, rng)
        t = np.arange(3600) / FPS
        tracks.append(place + 0.05 * np.stack([np.sin(2 * np.pi * 1.5 * t), np.cos(2 * np.pi * 1.5 * t)], axis=1))
    fitted = fit_travel(tracks, FPS)
    assert fitted.rms_speed == pytest.approx(0.3, rel=0.08)
    assert fitted.time_constant == pytest.approx(1.5, rel=0.12)
    assert fitted.recordings == 30 and fitted.frames == 30 * 3600
    assert "0.30 m/s root mean square along each horizontal axis" in fitted.describe()
    assert TravelProcess.from_dict(fitted.to_dict()) == fitted


def test_a_gap_splits_a_track_and_short_stretches_are_left_out():
    track = np.cumsum(np.random.default_rng(3).normal(0, 0.01, (600, 2)), axis=0)
    track[200:203] = np.nan  # 6.7 s, a gap, 13.2 s
    track[590:] = np.nan
    assert [len(v) for v in slow_velocity(track, FPS)] == [200, 387]
    assert slow_velocity(track[:100], FPS) == []  # 3.3 s: too short to fit
    with pytest.raises(ConfigError, match="no stretch of at least 4 s"):
        fit_travel([track[:100]], FPS)


def test_silence_holds_the_dancer_where_it_is():
    live = np.ones(900, bool)
    live[300:600] = False
    place = draw_travel(TravelProcess(0.4, 0.3), live, FPS, np.random.default_rng(4))
    assert np.ptp(place[300:600], axis=0).max() == 0.0  # not a millimetre in the silence
    assert np.abs(place[600:] - place[599]).max() > 0.05  # and off again with the music


def test_the_root_travels_and_the_stream_is_the_whole_song():
    process = TravelProcess(0.35, 0.5)
    values = np.random.default_rng(5).normal(0, 0.3, (240, SPEC.dim))
    live = np.ones(240, bool)
    live[100:150] = False
    place = draw_travel(process, live, FPS, np.random.default_rng(6))
    moved = travel_targets(values, SPEC, place, FPS)
    root = SPEC.columns(SPEC.root, "position").start
    assert np.array_equal(moved[:, [root, root + 2]], values[:, [root, root + 2]] + place)
    feet = {SPEC.columns(j, "position").start for j in ("left_ankle", "left_heel", "left_toe", "left_knee")}
    arms = [c for j in ("head_right", "left_hand", "right_elbow") for c in range(*_span(j))]
    assert np.array_equal(moved[:, arms], values[:, arms])  # the feet and knees are the foot lock's
    assert any(not np.array_equal(moved[:, f], values[:, f]) for f in feet)
    stream = TravelStream(process, SPEC, FPS, np.random.default_rng(6))
    stepped = np.stack([stream.step(v, bool(k)) for v, k in zip(values, live)])
    assert np.allclose(stepped, moved, atol=1e-9)


def _span(joint: str) -> tuple[int, int]:
    start = SPEC.columns(joint, "position").start
    return start, start + 3


def test_targets_without_a_root_to_travel_are_refused():
    not_centred = TargetSpec.from_dict({**SPEC.to_dict(), "root": None})
    with pytest.raises(ConfigError, match="travel: the target is not centred on its root"):
        travel_targets(np.zeros((3, SPEC.dim)), not_centred, np.zeros((3, 2)), FPS)
    with pytest.raises(ConfigError, match="rms_speed must be a finite number >= 0 m/s"):
        TravelProcess(-1.0, 0.5)


FLOOR = TravelProcess(0.3, 1.5, centre=(0.5, -1.0), radius=8.0, pull=20.0)


def _dancers(process: TravelProcess, count: int, seed: int) -> tuple[list, list, list]:
    """Dancers drawn from ``process``: their starts (x, z), their tracks from the start, their lengths."""
    rng = np.random.default_rng(seed)
    starts, tracks = [], []
    for _ in range(count):
        start = np.asarray(process.centre) + rng.normal(0, 2, 2)
        tracks.append(draw_travel(process, np.ones(int(rng.integers(1500, 6000)), bool), FPS, rng, start))
        starts.append(start)
    return starts, tracks, [len(t) for t in tracks]


def test_the_pull_is_recovered_from_dancers_drawn_with_it():
    # the closed form (an impulse response's running sum) against sampled draws (a recursion)
    starts, tracks, lengths = _dancers(FLOOR, 300, 7)
    centre = np.asarray(FLOOR.centre)
    square = np.mean(np.concatenate([np.sum((t + s - centre) ** 2, axis=1) for t, s in zip(tracks, starts)]))
    offsets = [s - centre for s in starts]
    assert pull_time_constant(FLOOR, offsets, lengths, square, FPS) == pytest.approx(20.0, rel=0.08)
    unbounded = TravelProcess(0.3, 1.5)
    assert pull_time_constant(unbounded, offsets, lengths, 1e6, FPS) is None  # farther than an hour's pull keeps
    assert pull_time_constant(unbounded, offsets, lengths, 1e-6, FPS) == 1.0  # nearer than the strongest


def test_the_fit_keeps_the_floor_where_the_dancers_stood():
    starts, tracks, _ = _dancers(FLOOR, 60, 8)
    fitted = fit_travel(tracks, FPS, starts)
    stood = np.concatenate([t + s for t, s in zip(tracks, starts)])
    assert fitted.centre == pytest.approx(tuple(stood.mean(axis=0)))
    assert fitted.radius == pytest.approx(np.hypot(*(stood - stood.mean(axis=0)).T).max())
    # the fitted pull gives the fitted velocity the dancers' mean square distance from the centre
    redrawn = [
        draw_travel(fitted, np.ones(len(t), bool), FPS, np.random.default_rng(k), s)
        for k, (t, s) in enumerate(zip(tracks * 8, starts * 8))
    ]
    square = np.mean(np.concatenate([np.sum((t + s - fitted.centre) ** 2, axis=1) for t, s in zip(tracks, starts)]))
    again = np.mean(np.concatenate([np.sum((d + s - fitted.centre) ** 2, axis=1) for d, s in zip(redrawn, starts * 8)]))
    assert again == pytest.approx(square, rel=0.15)
    assert "pulled towards the floor's centre" in fitted.describe()
    assert TravelProcess.from_dict(fitted.to_dict()) == fitted
    assert fit_travel(tracks, FPS, [None, *starts[1:]]).centre is None  # an anchor missing: no floor


def test_the_pull_adds_its_closed_form_to_the_same_draws():
    live = np.ones(1200, bool)
    live[400:700] = False
    start = np.array([2.5, 1.0])  # 2.2 m from the centre, inside the floor
    free = draw_travel(FLOOR, live, FPS, np.random.default_rng(9), start=np.asarray(FLOOR.centre))
    pulled = draw_travel(FLOOR, live, FPS, np.random.default_rng(9), start=start)
    a = math.exp(-1 / (FPS * FLOOR.pull))
    steps = np.cumsum(live)  # the pull acts where the music plays, as the velocity does
    offset = start - np.asarray(FLOOR.centre)
    np.testing.assert_allclose(pulled - free, (a ** steps[:, None] - 1) * offset, atol=1e-9)
    assert np.ptp(pulled[400:700], axis=0).max() == 0.0  # held still in the silence
    outside = draw_travel(FLOOR, live, FPS, np.random.default_rng(9), start=np.array([20.0, 0.0]))
    np.testing.assert_array_equal(outside, free)  # a floor of its own: starts at its centre


def test_a_record_from_before_floors_draws_as_it_did():
    old = {"rms_speed": 0.35, "time_constant": 0.5, "recordings": 3, "frames": 900}
    process = TravelProcess.from_dict(old)
    assert process.to_dict() == old and process.pull is None
    live = np.ones(300, bool)
    expected = np.cumsum(0.35 * two_stage(np.random.default_rng(10).standard_normal((300, 2)), live, 0.5, FPS), axis=0)
    placed = draw_travel(process, live, FPS, np.random.default_rng(10), start=np.array([3.0, 3.0]))
    np.testing.assert_array_equal(placed, expected / FPS)
    with pytest.raises(ConfigError, match="a pull needs the floor's centre and radius"):
        TravelProcess(0.35, 0.5, pull=30.0)


def test_the_pulled_stream_is_the_whole_song():
    values = np.random.default_rng(11).normal(0, 0.3, (240, SPEC.dim))
    live = np.ones(240, bool)
    live[100:150] = False
    start = np.array([1.5, 0.0])
    moved = travel_targets(values, SPEC, draw_travel(FLOOR, live, FPS, np.random.default_rng(12), start), FPS)
    stream = TravelStream(FLOOR, SPEC, FPS, np.random.default_rng(12), start)
    stepped = np.stack([stream.step(v, bool(k)) for v, k in zip(values, live)])
    assert np.allclose(stepped, moved, atol=1e-9)
