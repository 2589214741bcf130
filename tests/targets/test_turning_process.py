"""The turning drawn at generation (kinectdata.targets.turning): its statistics against the formulas of
two first-order stages, the fit recovering a known process, the geometry (a rigid turn about the
standing foot, measured back by evaluation's least-squares turning rate), silence, and the stream
against the whole song."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kinectdata.core.errors import ConfigError
from kinectdata.core.jointsets import load_joint_set
from kinectdata.evaluation.metrics.turning import turning_rates
from kinectdata.targets.specs import generic_target
from kinectdata.targets.turning import (
    TurningProcess,
    TurningStream,
    draw_turning_speed,
    fit_turning,
    turn_targets,
    turnable,
)

FPS = 30.0
SPEC = generic_target("positions", load_joint_set("tang2018"))
FEET = ("left_ankle", "right_ankle")


def _pose(spec=SPEC, seed=0, frames=1) -> np.ndarray:
    """Root-centred targets [frames, D]: joints 0.1-0.8 m from the root, the left ankle 10 cm below the
    right one, the root's travel 0."""
    rng = np.random.default_rng(seed)
    values = np.zeros((frames, spec.dim))
    for j in spec.positions:
        if j != spec.root:
            values[:, spec.columns(j)] = rng.uniform(-0.4, 0.4, 3)
    values[:, spec.columns("left_ankle").start + 1] = -0.9
    values[:, spec.columns("right_ankle").start + 1] = -0.8
    return values


def _autocorrelation(x: np.ndarray, lag: int) -> float:
    return float((x[:-lag] * x[lag:]).mean() / (x * x).mean())


def test_the_drawn_speed_has_the_processs_spread_and_time_scale():
    process = TurningProcess(1.3, 0.4, FEET)
    speed = draw_turning_speed(process, np.ones(300_000, bool), FPS, np.random.default_rng(1))[1000:]
    assert np.sqrt(np.mean(speed**2)) == pytest.approx(1.3, rel=0.03)
    for seconds in (0.2, 0.4, 1.0):  # two stages of time constant tau: (1 + t / tau) exp(-t / tau)
        expected = (1 + seconds / 0.4) * math.exp(-seconds / 0.4)
        assert _autocorrelation(speed, round(seconds * FPS)) == pytest.approx(expected, abs=0.03)
    assert np.mean(speed) == pytest.approx(0.0, abs=0.05)


def test_the_fit_recovers_a_known_process_from_its_draws():
    truth = TurningProcess(0.9, 0.6, FEET)
    rng = np.random.default_rng(2)
    rates = [draw_turning_speed(truth, np.ones(20_000, bool), FPS, rng)[500:] for _ in range(5)]
    rates[0][100:120] = np.nan  # frames without a known turn are left out
    fitted = fit_turning(rates, FPS, SPEC)
    assert fitted.rms_speed == pytest.approx(0.9, rel=0.05)
    assert fitted.time_constant == pytest.approx(0.6, rel=0.1)
    assert fitted.pivot == FEET and fitted.recordings == 5 and fitted.frames == 5 * 19_500 - 20
    with pytest.raises(ConfigError, match="no turning speed"):
        fit_turning([np.full(10, np.nan)], FPS, SPEC)


def test_silence_holds_the_turning_still_and_music_starts_it_from_rest():
    live = np.r_[np.zeros(60, bool), np.ones(200, bool), np.zeros(40, bool)]
    speed = draw_turning_speed(TurningProcess(1.3, 0.4, FEET), live, FPS, np.random.default_rng(3))
    assert (speed[~live] == 0).all() and (speed[live] != 0).all()
    assert abs(speed[60]) < abs(speed[60:]).max() / 10  # low-passed: the music's first frame turns slowly
    still = _pose(frames=len(live))
    turned = turn_targets(still, SPEC, np.where(live, 5.0, 0.0), FPS, TurningProcess(1.3, 0.4, FEET))
    assert np.array_equal(turned[:60], still[:60])  # no speed: the frames are the network's


def test_a_turn_is_rigid_about_the_standing_foot_and_measured_back_at_its_speed():
    frames = 120
    values = _pose(frames=frames)
    values[:, SPEC.columns("pelvis")] = np.linspace(0, 0.3, frames)[:, None] * [1, 0, 0]  # the root travels
    speed = np.sin(np.arange(frames) / 15.0) * 2.0
    turned = turn_targets(values, SPEC, speed, FPS, TurningProcess(1.3, 0.4, FEET))
    root = turned[:, SPEC.columns("pelvis")]
    world = {j: turned[:, SPEC.columns(j)] + (0 if j == "pelvis" else root) for j in SPEC.positions}
    # the lower (left) ankle stays put in the world, up to the root's own travel carried by the turn
    unturned_foot = values[:, SPEC.columns("pelvis")] + values[:, SPEC.columns("left_ankle")]
    step = np.diff(world["left_ankle"][:, [0, 2]], axis=0)
    heading = np.cumsum(speed) / FPS
    c, s = np.cos(heading[:-1]), np.sin(heading[:-1])  # the step is turned by the heading it left
    travel = np.diff(unturned_foot[:, [0, 2]], axis=0)
    carried = np.stack([c * travel[:, 0] - s * travel[:, 1], s * travel[:, 0] + c * travel[:, 1]], axis=1)
    np.testing.assert_allclose(step, carried, atol=1e-4)
    # every distance between joints is kept, heights are untouched
    a, b = world["head_right"], world["right_ankle"]
    np.testing.assert_allclose(np.linalg.norm(a - b, axis=1), np.linalg.norm(a - b, axis=1)[0], atol=1e-9)
    np.testing.assert_allclose(turned[:, 1::3], values[:, 1::3])
    # evaluation's least-squares turning rate of the joints about the root reads the drawn speed back
    offsets = np.stack([turned[:, SPEC.columns(j)] for j in SPEC.positions if j != "pelvis"], axis=1)
    rate = turning_rates(offsets, FPS)
    np.testing.assert_allclose(rate, (heading[2:] - heading[:-2]) * FPS / 2, atol=1e-9)


def test_without_feet_the_turn_is_about_the_root():
    values = _pose(frames=50)
    speed = np.full(50, 1.0)
    turned = turn_targets(values, SPEC, speed, FPS, TurningProcess(1.0, 0.4, ("pelvis",)))
    np.testing.assert_allclose(turned[:, SPEC.columns("pelvis")], 0.0, atol=1e-12)


def test_the_stream_turns_frame_by_frame_as_the_whole_song_is_turned():
    process = TurningProcess(1.3, 0.35, FEET)
    frames = 150
    values = _pose(frames=frames, seed=4) + np.random.default_rng(5).normal(0, 0.05, (frames, SPEC.dim))
    live = np.r_[np.ones(70, bool), np.zeros(20, bool), np.ones(60, bool)]
    whole = turn_targets(values, SPEC, draw_turning_speed(process, live, FPS, np.random.default_rng(6)), FPS, process)
    stream = TurningStream(process, SPEC, FPS, np.random.default_rng(6))
    stepped = np.stack([stream.step(v, bool(on)) for v, on in zip(values, live)])
    np.testing.assert_allclose(stepped, whole, atol=1e-10)


def test_the_record_round_trips_and_bad_processes_or_targets_are_refused():
    process = TurningProcess(1.2, 0.4, FEET, 33, 59_000, 0.96)
    assert TurningProcess.from_dict(process.to_dict()) == process
    assert "about the standing foot, fitted on 33 training recordings" in process.describe()
    for bad in ({"rms_speed": -1.0}, {"time_constant": 0.0}, {"pivot": ("a", "b", "c")}):
        with pytest.raises(ConfigError, match="turning"):
            TurningProcess(**{"rms_speed": 1.0, "time_constant": 0.4, "pivot": FEET, **bad})
    with pytest.raises(ConfigError, match="not a turning process record"):
        TurningProcess.from_dict({"rms_speed": 1.0})
    assert "centred on its root" in turnable(SPEC, root_centred=False)
    assert turnable(SPEC, root_centred=True) == ""
    other = generic_target("positions", load_joint_set("kinect_v2"))  # other joints: no left_ankle
    with pytest.raises(ConfigError, match="pivot 'left_ankle' is not among the target's joints"):
        turn_targets(np.zeros((1, other.dim)), other, np.zeros(1), FPS, process)
