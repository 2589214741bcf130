"""The free-running loss's root band terms: the root's speed along the floor at the bar's rate, the
beat's and the half beat's, and its vertical speed there and at the quarter beat's, against scipy's
periodogram of the same velocity; and the phase of its rise and fall against the dancer's, against
numpy's transform of the same velocity."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import periodogram

torch = pytest.importorskip("torch")

from kinectdata.models.losses import (  # noqa: E402
    ROOT_BANDS_HZ,
    ROOT_RISE_BANDS_HZ,
    Body,
    masked_root_band_loss,
    masked_root_phase_loss,
    masked_root_rise_loss,
)

FPS = 30.0
ROOT, FOOT = 0, 1


def _centred_windows(sway_hz: list[float], amplitude: float = 0.1, frames: int = 300) -> np.ndarray:
    """[B, T, 6] root-centred windows (metres): the root sways along x (and half as far along z) at
    each rate of ``sway_hz``, bobbing up and down at 3 Hz; the foot stays 0.9 m below it."""
    t = np.arange(frames) / FPS
    out = []
    for hz in sway_hz:
        x = amplitude * np.sin(2 * np.pi * hz * t)
        z = 0.5 * amplitude * np.cos(2 * np.pi * hz * t)
        root = np.stack([x, 0.9 + 0.05 * np.sin(2 * np.pi * 3 * t), z], axis=1)
        foot = np.tile([0.0, -0.9, 0.0], (frames, 1))
        out.append(np.concatenate([root, foot], axis=1))
    return np.stack(out)


def _body(scale: float = 0.5) -> Body:
    return Body(bones=[(FOOT, ROOT)], scale=torch.full((6,), scale), offset=torch.zeros(6), root=ROOT, centred=True)


def _normalised(metres: np.ndarray, scale: float = 0.5):
    return torch.from_numpy((metres * scale).astype(np.float64))


def _reference(made: np.ndarray, real: np.ndarray, axes=(0, 2), bands=ROOT_BANDS_HZ) -> float:
    """The divergence by scipy's Hann periodogram of the root's velocity along ``axes``, band by band."""
    powers = []
    for x in (made, real):
        velocity = np.diff(x[:, :, list(axes)], axis=1) * FPS
        freqs, p = periodogram(velocity, fs=FPS, window="hann", detrend=False, scaling="spectrum", axis=1)
        # scipy's one-sided power over (sum of the window)^2, back to the transform's |X|^2 (the
        # floor's last 1e-12 is absolute)
        window_sum = np.hanning(velocity.shape[1] + 1)[:-1].sum()
        p = p.sum(axis=2) * window_sum**2 / 2
        powers.append(np.stack([p[:, (freqs >= lo) & (freqs < hi)].sum(axis=1) for lo, hi in bands], axis=1))
    m, r = powers
    floor = 1e-2 * r.mean(axis=0) + 1e-12
    q = (r + floor) / (m + floor)
    terms = 2 * (q - np.log(q) - 1)
    return float(terms.mean())


def test_root_band_loss_equals_scipys_periodogram_band_by_band():
    real_m = _centred_windows([0.7, 0.6, 1.2])
    made_m = _centred_windows([1.5, 0.7, 2.5], amplitude=0.07)
    mask = torch.ones(3, 300, 6, dtype=torch.bool)
    got = float(masked_root_band_loss(_normalised(made_m), _normalised(real_m), mask, _body(), FPS))
    assert got == pytest.approx(_reference(made_m, real_m), rel=1e-6)
    assert got > 0.5


def test_swaying_at_the_beat_costs_where_the_dancers_sway_at_the_bar():
    """The same speed at the bar's rate costs nothing; at the beat's (twice the rate) it costs, and
    so does half the speed at the bar's rate. Only the root's floor motion counts: its bob (y) and
    the units the targets are normalised in do not."""
    real = _centred_windows([0.7])
    mask = torch.ones(1, 300, 6, dtype=torch.bool)
    loss = lambda made, scale=0.5: float(  # noqa: E731
        masked_root_band_loss(_normalised(made, scale), _normalised(real, scale), mask, _body(scale), FPS)
    )
    assert loss(real) == pytest.approx(0.0, abs=1e-9)
    assert loss(_centred_windows([1.4])) > 1.0
    assert loss(_centred_windows([0.7], amplitude=0.05)) > 0.5
    bobbing = real.copy()
    bobbing[:, :, 1] += 0.1 * np.sin(2 * np.pi * 1.5 * np.arange(300) / FPS)
    assert loss(bobbing) == pytest.approx(0.0, abs=1e-9)
    assert loss(_centred_windows([1.4]), scale=0.05) == pytest.approx(loss(_centred_windows([1.4])), rel=1e-6)


def test_windows_whose_root_is_not_known_throughout_are_left_out():
    real = _centred_windows([0.7, 0.7])
    made = _centred_windows([0.7, 2.0])
    mask = torch.ones(2, 300, 6, dtype=torch.bool)
    mask[1, 100, 0] = False  # the second window's root x is missing in one frame
    got = float(masked_root_band_loss(_normalised(made), _normalised(real), mask, _body(), FPS))
    assert got == pytest.approx(0.0, abs=1e-9)
    mask[:, 100, 0] = False
    assert float(masked_root_band_loss(_normalised(made), _normalised(real), mask, _body(), FPS)) == 0.0


def test_the_root_band_loss_moves_the_root_towards_the_dancers_rate():
    """A gradient step on the loss slows a root swaying at the beat where the dancer sways at the bar."""
    real = _normalised(_centred_windows([0.7]))
    made = _normalised(_centred_windows([0.7, 1.5])[1:]).requires_grad_(True)
    mask = torch.ones(1, 300, 6, dtype=torch.bool)
    loss = masked_root_band_loss(made, real, mask, _body(), FPS)
    loss.backward()
    assert made.grad is not None and float(made.grad[..., 3:].abs().sum()) == 0.0  # the foot's columns untouched
    stepped = (made - 1e-6 * made.grad / made.grad.abs().max()).detach()
    assert float(masked_root_band_loss(stepped, real, mask, _body(), FPS)) < float(loss.detach())


def test_a_body_without_a_root_or_too_short_a_window_costs_nothing():
    real = _normalised(_centred_windows([0.7], frames=3))
    mask = torch.ones(1, 3, 6, dtype=torch.bool)
    rootless = Body(bones=[(FOOT, ROOT)], scale=torch.full((6,), 0.5), offset=torch.zeros(6))
    assert float(masked_root_band_loss(real, real * 2, mask, rootless, FPS)) == 0.0
    assert float(masked_root_band_loss(real, real * 2, mask, _body(), FPS)) == 0.0


def _rising(rise_hz: list[float], amplitude: float = 0.04, frames: int = 300) -> np.ndarray:
    """[B, T, 6] root-centred windows (metres): the root rises and falls at each rate of ``rise_hz``
    around 0.9 m while it sways along x at 0.7 Hz; the foot stays 0.9 m below it."""
    out = _centred_windows([0.7] * len(rise_hz), frames=frames)
    t = np.arange(frames) / FPS
    for window, hz in zip(out, rise_hz):
        window[:, 1] = 0.9 + amplitude * np.sin(2 * np.pi * hz * t)
    return out


RISE_BANDS = ((0.5, 1.0), (1.0, 2.0), (2.0, 4.0), (4.0, 8.0))  # written out: the quarter beat's band too


def test_root_rise_loss_equals_scipys_periodogram_of_the_vertical_velocity():
    assert ROOT_RISE_BANDS_HZ == RISE_BANDS
    real_m = _rising([0.6, 1.4, 5.0])
    made_m = _rising([1.4, 1.4, 2.5], amplitude=0.02)
    mask = torch.ones(3, 300, 6, dtype=torch.bool)
    got = float(masked_root_rise_loss(_normalised(made_m), _normalised(real_m), mask, _body(), FPS))
    assert got == pytest.approx(_reference(made_m, real_m, axes=(1,), bands=RISE_BANDS), rel=1e-6)
    assert got > 0.5


def test_the_quarter_beats_rise_and_fall_counts_and_the_floor_bands_stop_at_4_hz():
    """The dancer's root moves at 0.7, 1.5 and 3 Hz along the floor and up and down, and at 6 Hz up
    and down too. A shake at 5.5 Hz added along y costs in the rise term (its 4-8 Hz band holds it);
    the same shake along x costs next to nothing in the root band term (its bands end at 4 Hz)."""
    assert ROOT_BANDS_HZ == ((0.5, 1.0), (1.0, 2.0), (2.0, 4.0))
    t = np.arange(300) / FPS
    moving = sum(0.03 * np.sin(2 * np.pi * hz * t) for hz in (0.7, 1.5, 3.0))
    real = _rising([1.4])
    real[0, :, 0] = moving
    real[0, :, 1] = 0.9 + moving + 0.005 * np.sin(2 * np.pi * 6.0 * t)
    shake = 0.03 * np.sin(2 * np.pi * 5.5 * t)
    up, along = real.copy(), real.copy()
    up[0, :, 1] += shake
    along[0, :, 0] += shake
    mask = torch.ones(1, 300, 6, dtype=torch.bool)
    rise = float(masked_root_rise_loss(_normalised(up), _normalised(real), mask, _body(), FPS))
    floor = float(masked_root_band_loss(_normalised(along), _normalised(real), mask, _body(), FPS))
    assert rise > 1.0
    assert floor < 1e-3
    assert float(masked_root_rise_loss(_normalised(real), _normalised(real), mask, _body(), FPS)) == pytest.approx(
        0.0, abs=1e-9
    )


def test_a_root_that_stops_rising_and_falling_costs_whatever_it_does_along_the_floor():
    """The rise and fall the root band term cannot see: a root that stays at one height costs, one
    rising and falling as the dancer does costs nothing, however differently it sways along the floor."""
    real = _rising([1.4])
    mask = torch.ones(1, 300, 6, dtype=torch.bool)
    loss = lambda made: float(  # noqa: E731
        masked_root_rise_loss(_normalised(made), _normalised(real), mask, _body(), FPS)
    )
    level = real.copy()
    level[:, :, 1] = 0.9
    swaying_fast = real.copy()
    swaying_fast[:, :, 0] *= 3.0
    assert loss(real) == pytest.approx(0.0, abs=1e-9)
    assert loss(swaying_fast) == pytest.approx(0.0, abs=1e-9)
    assert loss(level) > 5.0
    assert loss(_rising([0.7])) > 1.0
    assert float(masked_root_band_loss(_normalised(level), _normalised(real), mask, _body(), FPS)) == pytest.approx(
        0.0, abs=1e-9
    )


def test_the_root_rise_loss_brings_back_the_rise_and_fall():
    """A gradient step on the loss raises the vertical motion of a root that barely moves up and down."""
    made = _normalised(_rising([1.4], amplitude=0.01))
    stepped = _step_lowers(masked_root_rise_loss, made, _normalised(_rising([1.4])))
    assert float(stepped[0, :, 1].std()) > float(made[0, :, 1].std())


def _step_lowers(loss_of, made, real):
    """A gradient step on ``loss_of`` touches only the root's y and lowers the loss; the stepped window."""
    made = made.clone().requires_grad_(True)
    mask = torch.ones(*real.shape, dtype=torch.bool)
    loss = loss_of(made, real, mask, _body(), FPS)
    loss.backward()
    assert made.grad is not None and float(made.grad[..., [0, 2, 3, 4, 5]].abs().sum()) == 0.0  # only the root's y
    stepped = (made - 1e-4 * made.grad / made.grad.abs().max()).detach()
    assert float(loss_of(stepped, real, mask, _body(), FPS)) < float(loss.detach())
    return stepped


def test_the_rise_term_leaves_out_what_the_floor_term_does():
    """Windows whose root height is missing in a frame, a rootless body and a window too short for a
    transform cost nothing in the rise term either."""
    real = _rising([1.4, 1.4])
    made = _rising([1.4, 0.7])
    mask = torch.ones(2, 300, 6, dtype=torch.bool)
    mask[1, 50, 1] = False  # the second window's root y is missing in one frame
    assert float(masked_root_rise_loss(_normalised(made), _normalised(real), mask, _body(), FPS)) == pytest.approx(
        0.0, abs=1e-9
    )
    rootless = Body(bones=[(FOOT, ROOT)], scale=torch.full((6,), 0.5), offset=torch.zeros(6))
    assert float(masked_root_rise_loss(_normalised(made), _normalised(real), mask, rootless, FPS)) == 0.0
    short = torch.ones(2, 3, 6, dtype=torch.bool)
    assert float(masked_root_rise_loss(_normalised(made[:, :3]), _normalised(real[:, :3]), short, _body(), FPS)) == 0.0


def _phase_reference(made: np.ndarray, real: np.ndarray, bands=RISE_BANDS) -> float:
    """The phase term by numpy: each band's correlation of the transforms of the root's vertical
    velocity (a periodic Hann window), weighed by the real power's share in the band."""
    transforms = []
    for x in (made, real):
        velocity = np.diff(x[:, :, 1], axis=1) * FPS  # [B, T-1]
        window = np.hanning(velocity.shape[1] + 1)[:-1]
        transforms.append(np.fft.rfft(velocity * window, axis=1))
    freqs = np.fft.rfftfreq(made.shape[1] - 1, d=1.0 / FPS)
    g, t = transforms
    inside = [(freqs >= lo) & (freqs < hi) for lo, hi in bands]
    m = np.stack([(np.abs(g[:, b]) ** 2).sum(axis=1) for b in inside], axis=1)
    r = np.stack([(np.abs(t[:, b]) ** 2).sum(axis=1) for b in inside], axis=1)
    cross = np.stack([(g[:, b] * np.conj(t[:, b])).real.sum(axis=1) for b in inside], axis=1)
    floor = np.minimum(1e-2 * r.mean(axis=0) + 1e-12, r)
    gap = 1 - cross / np.sqrt(np.maximum(m, floor) * r + 1e-12)
    return float(((gap * r / r.sum(axis=1, keepdims=True)).sum(axis=1)).mean())


def _phase_loss(made: np.ndarray, real: np.ndarray) -> float:
    mask = torch.ones(*real.shape, dtype=torch.bool)
    return float(masked_root_phase_loss(_normalised(made), _normalised(real), mask, _body(), FPS))


def _rising_at(hz: float, shift_s: float, amplitude: float = 0.04) -> np.ndarray:
    """A window of :func:`_rising` whose rise and fall comes ``shift_s`` seconds late."""
    out = _rising([hz])
    t = np.arange(out.shape[1]) / FPS
    out[0, :, 1] = 0.9 + amplitude * np.sin(2 * np.pi * hz * (t - shift_s))
    return out


def test_root_phase_loss_equals_numpys_band_correlation():
    real = np.concatenate([_rising([0.6]), _rising([1.4]), _rising([5.0])])
    made = np.concatenate([_rising_at(0.6, 0.3), _rising_at(1.4, 0.1, 0.01), _rising([2.5])])
    real[1, :, 1] += 0.01 * np.sin(2 * np.pi * 3.0 * np.arange(300) / FPS)  # a second band in one window
    got = _phase_loss(made, real)
    assert got == pytest.approx(_phase_reference(made, real), rel=1e-6)
    assert 0.2 < got < 2.0


def test_the_phase_term_asks_when_the_root_rises_not_how_much():
    """The dancer rises and falls at 1.4 Hz. In time at half the size costs next to nothing (the rise
    term's business); a quarter period late costs about 1, half a period late about 2."""
    real = _rising([1.4])
    period = 1 / 1.4
    assert _phase_loss(real, real) == pytest.approx(0.0, abs=1e-6)
    assert _phase_loss(_rising_at(1.4, 0.0, 0.02), real) < 0.05
    assert _phase_loss(_rising_at(1.4, period / 4), real) == pytest.approx(1.0, abs=0.05)
    assert _phase_loss(_rising_at(1.4, period / 2), real) == pytest.approx(2.0, abs=0.05)
    swaying_fast = real.copy()
    swaying_fast[:, :, 0] *= 3.0
    assert _phase_loss(swaying_fast, real) == pytest.approx(0.0, abs=1e-6)  # only the height's timing counts


def test_the_band_the_dancer_rises_in_most_keeps_time_most():
    """The dancer rises at 1.4 Hz and barely at 3 Hz: the 3 Hz part out of phase costs little, the
    1.4 Hz part out of phase costs much."""
    t = np.arange(300) / FPS
    real = _rising([1.4])
    real[0, :, 1] += 0.004 * np.sin(2 * np.pi * 3.0 * t)
    small_late = real.copy()
    small_late[0, :, 1] = 0.9 + 0.04 * np.sin(2 * np.pi * 1.4 * t) - 0.004 * np.sin(2 * np.pi * 3.0 * t)
    big_late = real.copy()
    big_late[0, :, 1] = 0.9 - 0.04 * np.sin(2 * np.pi * 1.4 * t) + 0.004 * np.sin(2 * np.pi * 3.0 * t)
    assert _phase_loss(small_late, real) < 0.2
    assert _phase_loss(big_late, real) > 1.5


def test_the_phase_term_brings_the_rise_into_time_and_leaves_out_what_it_cannot_see():
    real = _normalised(_rising([1.4]))
    made = _normalised(_rising_at(1.4, 0.2))
    _step_lowers(masked_root_phase_loss, made, real)
    mask = torch.ones(1, 300, 6, dtype=torch.bool)
    level = _rising([1.4])
    level[:, :, 1] = 0.9
    flat = torch.ones(1, 300, 6, dtype=torch.bool)
    # a model that does not rise at all: a finite gradient (the floor), the cost of unrelated motion
    still = _normalised(level).requires_grad_(True)
    cost = masked_root_phase_loss(still, real, flat, _body(), FPS)
    cost.backward()
    assert float(cost.detach()) == pytest.approx(1.0, abs=1e-6)
    assert float(still.grad.abs().max()) < 100.0  # without the floor, about 3e7
    # a dancer who does not rise, a missing height, a rootless body, a short window: nothing
    assert _phase_loss(_rising([1.4]), level) == 0.0
    missing = torch.ones(1, 300, 6, dtype=torch.bool)
    missing[0, 10, 1] = False
    assert float(masked_root_phase_loss(made, real, missing, _body(), FPS)) == 0.0
    rootless = Body(bones=[(FOOT, ROOT)], scale=torch.full((6,), 0.5), offset=torch.zeros(6))
    assert float(masked_root_phase_loss(made, real, mask, rootless, FPS)) == 0.0
    short = torch.ones(1, 2, 6, dtype=torch.bool)  # one step of velocity: no transform
    assert float(masked_root_phase_loss(made[:, :2], real[:, :2], short, _body(), FPS)) == 0.0


def test_a_copy_costs_nothing_and_a_dancer_who_barely_rises_is_not_counted():
    """Beside a loud window, a quiet one: its copy costs 0 (the floor never exceeds a band's own
    power), and a quiet window danced in antiphase is left out (under 1 % of the batch's power), so
    the batch costs what the loud window costs alone."""
    t = np.arange(300) / FPS
    quiet = _rising([1.4], amplitude=0.0025)
    quiet[0, :, 1] += 0.0051 * np.sin(2 * np.pi * 0.6 * t)
    loud_real, loud_late = _rising([1.4]), _rising_at(1.4, 0.18)
    real = np.concatenate([loud_real, quiet])
    assert _phase_loss(real, real) == pytest.approx(0.0, abs=1e-6)
    whisper = _rising([1.4], amplitude=0.0002)
    antiphase = _rising_at(1.4, 0.5 / 1.4, amplitude=0.0002)
    alone = _phase_loss(loud_late, loud_real)
    assert alone > 0.5
    batch = _phase_loss(np.concatenate([loud_late, antiphase]), np.concatenate([loud_real, whisper]))
    assert batch == pytest.approx(alone, rel=1e-9)
