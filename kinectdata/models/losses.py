"""Training losses shared by the models (torch tensors; differentiable)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any


def masked_mse(prediction, target, mask):
    """Mean squared error over the valid entries (torch tensors; differentiable)."""
    mask = mask.to(prediction.dtype)
    return ((prediction - target) ** 2 * mask).sum() / mask.sum().clamp(min=1.0)


def _changes(prediction, target, mask):
    """The frame-to-frame changes [B, L-1, D] of both sequences and where they are valid."""
    return prediction[:, 1:] - prediction[:, :-1], target[:, 1:] - target[:, :-1], mask[:, 1:] & mask[:, :-1]


def masked_velocity_mse(prediction, target, mask):
    """Mean squared error of the frame-to-frame changes [B, L-1, D] of [B, L, D] sequences, over
    the entries valid in both frames (torch tensors; differentiable). Weighs the motion itself,
    which a pose loss lets a model trade for staying near the mean pose."""
    return masked_mse(*_changes(prediction, target, mask))


def masked_velocity_l1(prediction, target, mask):
    """Mean absolute error of the frame-to-frame changes [B, L-1, D] of [B, L, D] sequences, over
    the entries valid in both frames (torch tensors; differentiable): the L1 form of
    :func:`masked_velocity_mse`, for models trained with L1."""
    made, real, both = _changes(prediction, target, mask)
    both = both.to(prediction.dtype)
    return ((made - real).abs() * both).sum() / both.sum().clamp(min=1.0)


RHYTHM_FFTS = (32, 64, 128)
"""Window lengths (frames) of the rhythm spectra: about 1, 2 and 4 seconds at 30 fps."""
RHYTHM_MAX_HZ = 6.0
"""The rhythm spectra stop here: dance moves are slower; sensor jitter is faster."""


def _component_changes(prediction, target, mask):
    """The frame-to-frame changes of each component of [B, L, D] windows as rows [B * D, L - 1]
    (made, real: zero where the target is invalid) and [B * D] 1.0 where a component is valid
    throughout."""
    import torch

    change = prediction[:, 1:] - prediction[:, :-1]
    real = target[:, 1:] - target[:, :-1]
    B, L, D = real.shape
    both = mask[:, 1:] & mask[:, :-1]
    valid = both.all(dim=1).reshape(B * D).to(prediction.dtype)
    x = change.permute(0, 2, 1).reshape(B * D, L)
    y = torch.where(both, real, torch.zeros_like(real)).permute(0, 2, 1).reshape(B * D, L)
    return x, y, valid


def _spectral_distance(X, Y, valid):
    """Made magnitudes ``X`` against real ``Y`` ([rows, ...], one row per component): the spectral
    convergence ``||Y - X|| / ||Y||`` plus the mean absolute difference of the log magnitudes
    (floored at 1 % of the real mean magnitude), averaged over the rows ``valid`` marks."""
    import torch

    dims = tuple(range(1, X.dim()))
    floor = 1e-2 * Y.mean().detach() + 1e-8
    convergence = torch.linalg.vector_norm(X - Y, dim=dims) / torch.linalg.vector_norm(Y, dim=dims).clamp(min=1e-8)
    log_distance = (torch.log(X + floor) - torch.log(Y + floor)).abs().mean(dim=dims)
    return ((convergence + log_distance) * valid).sum() / valid.sum().clamp(min=1.0)


def masked_rhythm_spectrum_loss(prediction, target, mask, fps: float, ffts=RHYTHM_FFTS, max_hz: float = RHYTHM_MAX_HZ):
    """How differently two motions move, whatever their phase: the multi-resolution spectra of their
    frame-to-frame changes compared (torch tensors; differentiable).

    For each of the D components valid in every frame of a [B, L, D] window, the changes
    [L - 1] are cut into Hann windows of each length in ``ffts`` (a quarter apart), and the
    magnitudes of their spectra from the first bin above 0 Hz up to ``max_hz`` are compared: the
    spectral convergence ``||Y - X|| / ||Y||`` plus the mean absolute difference of the log
    magnitudes (floored at 1 % of the target's mean magnitude), averaged over the lengths (the
    multi-resolution STFT loss of audio generation: Yamamoto et al. 2020, Parallel WaveGAN, on
    motion). A motion that moves as much and as often as the target at every tempo scores near 0
    however its steps fall against the target's; standing still or moving faster or more scores
    high. Windows shorter than a length skip it.

    Args:
        prediction, target: [B, L, D] poses (normalised units).
        mask: [B, L, D] bool validity of the target.
        fps: frames per second (for ``max_hz``).

    Returns:
        A scalar tensor (0 when no component is valid throughout or the window is too short).
    """
    import torch

    x, y, valid = _component_changes(prediction, target, mask)
    L = x.shape[1]
    total, used = prediction.new_zeros(()), 0
    for n in ffts:
        if L < n:
            continue
        window = torch.hann_window(n, device=prediction.device, dtype=prediction.dtype)
        top = max(2, int(max_hz * n / fps) + 1)
        X = torch.stft(x, n, hop_length=n // 4, window=window, center=False, return_complex=True).abs()[:, 1:top]
        Y = torch.stft(y, n, hop_length=n // 4, window=window, center=False, return_complex=True).abs()[:, 1:top]
        total = total + _spectral_distance(X, Y, valid)
        used += 1
    return total / max(used, 1)


PERIODOGRAM_FFT = 1024
"""Points of :func:`masked_periodogram_loss`'s transform: a 300-frame window zero-padded to them."""
PERIODOGRAM_BAND_HZ = (0.1, 2.0)
"""The periods :func:`masked_periodogram_loss` compares: 0.5-10 s, from a half beat of a slow song to
two bars."""


def masked_periodogram_loss(
    prediction, target, mask, fps: float, n_fft: int = PERIODOGRAM_FFT, band_hz=PERIODOGRAM_BAND_HZ
):
    """Where two motions' periods lie, finer than :func:`masked_rhythm_spectrum_loss` tells: per
    component of [B, L, D] windows valid throughout, the magnitude of the whole window's Hann-windowed
    frame-to-frame changes transformed on ``n_fft`` points (zero-padded), from ``band_hz[0]`` to
    ``band_hz[1]``, compared as the rhythm spectra are (spectral convergence plus mean absolute log
    difference, floored at 1 % of the target's mean). Zero-padding does not make two periods in one
    window separable, but it places one period's peak to a fraction of a bin: the rhythm spectra's
    longest window (128 frames, 4.3 s at 30 fps) puts a waltz's bar (2.07 s) and a cha-cha's (1.92 s)
    in one 0.23-Hz bin, where this term sees them 2 points of 0.03 Hz apart: on 10-s sines the wrong
    bar costs 36 x a wrong phase here and 4 x in those spectra. On the folds of tang2018
    (docs/notebook/2026-11-real-dance.md) the cdhc model otherwise played one waltz period for most songs.
    Torch tensors; a scalar (0 when no component is valid throughout)."""
    import torch

    x, y, valid = _component_changes(prediction, target, mask)
    window = torch.hann_window(x.shape[1], periodic=True, device=prediction.device, dtype=prediction.dtype)
    low, high = int(band_hz[0] * n_fft / fps) + 1, int(band_hz[1] * n_fft / fps) + 1
    X = torch.fft.rfft(x * window, n=n_fft).abs()[:, low:high]
    Y = torch.fft.rfft(y * window, n=n_fft).abs()[:, low:high]
    return _spectral_distance(X, Y, valid)


REPETITION_LAGS_S = (0.2, 4.5)
"""The lags (seconds) :func:`masked_repetition_loss` compares: from a quick half beat to two bars of a
slow waltz (2 x 3 x 0.7 s), the range the listening figures read a dominant period from
(:mod:`kinectdata.evaluation.beat_following` looks up to two of the song's bars)."""
REPETITION_DRIFT_S = 2.0
"""Seconds; the centred moving average :func:`masked_repetition_loss` takes out first, as the
listening figures do (:data:`kinectdata.evaluation.rhythm.DRIFT_WINDOW_S`)."""


def vertical_repetition(x, valid, fps: float, lags_s=REPETITION_LAGS_S, drift_s: float = REPETITION_DRIFT_S):
    """How a motion repeats: per window, the autocorrelation of its joints' heights at lags
    ``lags_s`` (seconds), averaged over the joints, as the listening figures compute it for the
    dominant period (each height with its centred ``drift_s`` moving average taken out, each lag the
    Pearson correlation of the pairs ``(h[t], h[t + k])``, no mean taken again).

    Args:
        x: [B, L, J] heights (any unit: the result is unitless); ``valid``: [B, J] 1.0 for a joint
            valid throughout its window.
        fps: frames per second.

    Returns:
        [B, K] the autocorrelation at the K lags (torch; differentiable), and [B] 1.0 for windows
        with a valid joint and room for the longest lag.
    """
    import torch
    import torch.nn.functional as F

    B, L, J = x.shape
    reach = max(1, round(drift_s * fps)) // 2
    rows = x.permute(0, 2, 1).reshape(B * J, 1, L)
    drift = F.avg_pool1d(rows, 2 * reach + 1, stride=1, padding=reach, count_include_pad=False)
    h = (rows - drift).reshape(B * J, L)
    first, last = max(1, math.ceil(lags_s[0] * fps)), min(int(lags_s[1] * fps), L - 2)
    if last < first:
        return x.new_zeros(B, 0), x.new_zeros(B)
    spectrum = torch.fft.rfft(h, n=2 * L)
    cross = torch.fft.irfft(spectrum.real**2 + spectrum.imag**2, n=2 * L)[:, first : last + 1]  # sum h[t] h[t+k]
    energy = torch.cumsum(h**2, dim=1)
    lags = torch.arange(first, last + 1, device=x.device)
    head = energy[:, L - 1 - lags]  # sum over t < L - k of h[t]^2
    tail = energy[:, -1:] - energy[:, lags - 1]  # sum over t >= k of h[t]^2
    scale = 1e-6 * energy[:, -1:].mean() + 1e-12
    r = (cross / torch.sqrt(head * tail + scale**2)).reshape(B, J, -1)
    weights = valid.to(x.dtype)
    curve = (r * weights[..., None]).sum(dim=1) / weights.sum(dim=1, keepdim=True).clamp(min=1.0)
    return curve, (weights.sum(dim=1) > 0).to(x.dtype)


def masked_repetition_loss(prediction, target, mask, body, fps: float):
    """How differently two motions repeat, whatever their phase: the mean squared difference of
    their :func:`vertical_repetition` curves, over windows with a joint valid throughout. The heights
    are the target's own up-axis components (root-centred joints relative to the root, the root in the
    world), as the listening figures read a motion's dominant period from the targets; the
    normalisation, one scale and offset a component, does not change a correlation. The spectra of
    the changes weigh a slow period by its small speed, and a 10-s window's periodogram hardly parts
    a bar from two: the cdhc model repeated at one bar in some songs and at two in others, and the
    rank of its periods with the tempo was lost between songs
    (docs/notebook/2026-12-real-dance-variety.md). [B, L, D] tensors (positions first, ``body.dims``
    per joint, the up axis second); a scalar (0 for a body without bones or fewer than 2 components
    a joint)."""
    if not body.bones or body.dims < 2:
        return prediction.new_zeros(())
    joints = body.joints
    dims = body.dims
    up = slice(1, joints * dims, dims)
    whole = mask[..., up].all(dim=1)  # [B, J]: the height valid throughout the window
    made, counted = vertical_repetition(prediction[..., up], whole, fps)
    real, _ = vertical_repetition(target[..., up], whole, fps)
    if made.shape[1] == 0:
        return prediction.new_zeros(())
    per_window = ((made - real.detach()) ** 2).mean(dim=1)
    return (per_window * counted).sum() / counted.sum().clamp(min=1.0)


ENERGY_CHUNK_S = 2.0
"""The stretch of a window (seconds) over which :func:`masked_rhythm_loss` matches the motion's speed.
Over a whole window, a burst of motion then stillness matched the real speed on average: the cdhc
model on tang2018's validation dances moved 2-18 x the real energy in its first 5 s and 0.04-0.4 x
after (docs/notebook/2026-11-real-dance.md)."""


def masked_energy_loss(
    prediction, target, mask, chunk: int | None = None, excess: bool = False, component_floor: bool = False
):
    """How far a motion's speed is from the target's, in ratio: per component of [B, L, D] windows
    and per stretch of ``chunk`` frame-to-frame changes (None: the whole window; a last shorter
    stretch counts as one), twice the Itakura-Saito divergence ``r/m - log(r/m) - 1`` of the mean
    squared changes ``m`` made from the target's ``r`` (over frame pairs valid in the target), each
    floored at 1 % of the target's mean over the batch (torch tensors; differentiable).

    It depends on the ratio alone (near 1 it is the squared log ratio; twice or half as fast costs
    0.39 or 0.61) and, unlike the squared log ratio, where the music cannot tell when the dancer
    moves it is least at the target's mean speed, not at its geometric mean: on tang2018's
    training windows that mean is 0.56 x the real energy, where the squared log ratio left the
    models (docs/notebook/2026-11-real-dance.md). A stretch where the target holds still asks the motion to hold
    still too. With ``excess`` the divergence is turned round (the made energy's from the target's):
    too much then costs in proportion and too little only in log ratio (:func:`masked_jitter_loss`).

    ``component_floor``: each component floored at 1 % of its own mean over the batch instead of
    the mean over every component. A component far smaller than the rest, in the normalised units
    the network is trained in, lies under the shared floor and costs nothing however it moves: on
    tang2018 the root's sway along the floor (its columns scaled by the floor's width, its travel
    taken out) has a 5th-10th of that floor (docs/notebook/2026-12-real-dance-variety.md, "The feet,
    and the root that the targets' terms do not see")."""
    import torch

    both = (mask[:, 1:] & mask[:, :-1]).to(prediction.dtype)  # [B, L-1, D]
    steps = both.shape[1]
    size = steps if chunk is None or chunk >= steps else max(1, int(chunk))
    bounds = [(s, min(s + size, steps)) for s in range(0, steps, size)]
    pairs = torch.stack([both[:, a:b].sum(dim=1) for a, b in bounds], dim=1)  # [B, chunks, D]

    def energy(x):
        squared = ((x[:, 1:] - x[:, :-1]) ** 2) * both
        return torch.stack([squared[:, a:b].sum(dim=1) for a, b in bounds], dim=1) / pairs.clamp(min=1.0)

    made, real = energy(prediction), energy(target)
    over = (0, 1) if component_floor else (0, 1, 2)
    floor = 1e-2 * (real * (pairs > 0)).sum(dim=over).detach() / (pairs > 0).sum(dim=over).clamp(min=1) + 1e-12
    counted = (pairs > 0).to(prediction.dtype)
    ratio = (made + floor) / (real + floor) if excess else (real + floor) / (made + floor)
    divergence = 2.0 * (ratio - torch.log(ratio) - 1.0)
    return (divergence * counted).sum() / counted.sum().clamp(min=1.0)


LOW_BAND_HZ = 1.5
"""Where :func:`masked_low_band_energy_loss` cuts: the Gaussian smoother's standard deviation is
``1 / (2 pi LOW_BAND_HZ)`` seconds (its gain is 0.61 at this frequency, 0.14 at twice it)."""


def low_passed(x, mask, fps: float, hz: float = LOW_BAND_HZ):
    """[B, L', D] windows [B, L, D] smoothed by a Gaussian of standard deviation ``1 / (2 pi hz)``
    seconds (``fps`` frames a second; cut at three deviations), over the frames whose whole reach
    is valid (``L' = L - 2r``), and their mask [B, L', D]; None when the windows are shorter than
    the kernel. Torch tensors; differentiable."""
    import torch
    import torch.nn.functional as F

    sigma = fps / (2.0 * math.pi * hz)
    reach = max(1, math.ceil(3.0 * sigma))
    B, L, D = x.shape
    if L <= 2 * reach:
        return None
    t = torch.arange(-reach, reach + 1, dtype=x.dtype, device=x.device)
    kernel = torch.exp(-0.5 * (t / sigma) ** 2)
    kernel = (kernel / kernel.sum()).view(1, 1, -1)
    valid = mask.to(x.dtype)

    def conv(v, k):
        return F.conv1d(v.permute(0, 2, 1).reshape(B * D, 1, L), k).reshape(B, D, -1).permute(0, 2, 1)

    whole = conv(valid, torch.ones_like(kernel)) > 2 * reach + 0.5
    return conv(x * valid, kernel), whole


def masked_low_band_energy_loss(
    prediction, target, mask, fps: float, chunk: int | None = None, component_floor: bool = False
):
    """:func:`masked_energy_loss` of the motions' slow part (:func:`low_passed`, below about
    :data:`LOW_BAND_HZ`): how far the speed of the large, slow motion (a sway, a step across the
    floor) is from the target's, per ``chunk`` frames. The cdhc model moved at half the dancers' energy
    with 1.9-2 x their jerk: faster for its size than they are; a gain on its output below 1.5 Hz
    brought the energy but made the feet slide (docs/notebook/2026-12-real-dance-variety.md), so the
    slow motion is asked for in training, where the foot loss sees it. [B, L, D] tensors; a scalar
    (0 for windows shorter than the smoother). ``component_floor``: :func:`masked_energy_loss`'s."""
    made = low_passed(prediction, mask, fps)
    if made is None:
        return prediction.sum() * 0.0
    real, valid = low_passed(target, mask, fps)
    return masked_energy_loss(made[0], real, valid & made[1], chunk, component_floor=component_floor)


def masked_jitter_loss(prediction, target, mask, chunk: int | None = None, component_floor: bool = False):
    """How much more a motion jitters than the target: per component of [B, L, D] windows and per
    stretch of ``chunk`` frames, the mean squared accelerations and jerks (second and third
    frame-to-frame differences) made against the target's, by the Itakura-Saito divergence turned
    round (:func:`masked_energy_loss` with ``excess``): twice the target's costs 0.61, ten times
    13.4, half of it 0.39. The speed term of :func:`masked_rhythm_loss` on the changes forgives the
    other way (ten times the target's acceleration costs 2.8): without this term the cdhc model,
    making its motion from the music alone, jittered on held-out dances at 4-12 x the real dancers'
    mean squared acceleration and 8-36 x their jerk's, most of the excess above the rhythm
    spectra's 6 Hz (docs/notebook/2026-11-real-dance.md). Torch tensors; a scalar.
    ``component_floor``: :func:`masked_energy_loss`'s."""
    made, real, both = _changes(prediction, target, mask)
    loss = masked_energy_loss(made, real, both, chunk, excess=True, component_floor=component_floor)
    return loss + masked_energy_loss(*_changes(made, real, both), chunk, excess=True, component_floor=component_floor)


def masked_posture_loss(prediction, target, mask):
    """How far a motion's postures are from the target's, whatever their timing: per component of
    [B, L, D] windows, the absolute differences of the means and of the standard deviations over
    the frames valid in the target (normalised units), averaged over the components with at least
    two valid frames (torch tensors; differentiable). A motion that drifts out of the body's range,
    or shrinks to one pose, pays; one that takes the target's postures at other moments does not."""
    import torch

    valid = mask.to(prediction.dtype)
    count = valid.sum(dim=1)  # [B, D]

    def moments(x):
        mean = (x * valid).sum(dim=1) / count.clamp(min=1.0)
        var = (((x - mean[:, None]) ** 2) * valid).sum(dim=1) / count.clamp(min=1.0)
        return mean, torch.sqrt(var + 1e-12)

    (made_mean, made_std), (real_mean, real_std) = moments(prediction), moments(target)
    counted = (count >= 2).to(prediction.dtype)
    gap = (made_mean - real_mean).abs() + (made_std - real_std).abs()
    return (gap * counted).sum() / counted.sum().clamp(min=1.0)


def _metres(x, scale, offset, joints: int, dims: int):
    """The first ``joints`` joints' positions [..., joints, dims] in metres, from normalised [..., D]
    vectors ``y = (x - offset) * scale``."""
    width = joints * dims
    return (x[..., :width] / scale[:width] + offset[:width]).unflatten(-1, (joints, dims))


def _world(x, scale, offset, joints: int, dims: int, root: int | None, centred: bool):
    """The first ``joints`` joints' positions [..., joints, dims] in metres in the world: as
    :func:`_metres`, with the root's position added back to the others' when ``centred``."""
    import torch

    p = _metres(x, scale, offset, joints, dims)
    if not centred:
        return p
    others = torch.ones(joints, 1, dtype=p.dtype, device=p.device)
    others[root] = 0.0
    return p + others * p[..., root : root + 1, :]


def _joints_valid(mask, joints: int, dims: int):
    """[B, L, J] where every component of each of the first ``joints`` joints is valid in a [B, L, D]
    mask (positions first, ``dims`` components per joint)."""
    return mask[..., : joints * dims].unflatten(-1, (joints, dims)).all(dim=-1)


def _bone_lengths(prediction, target, mask, bones, scale, offset, dims: int):
    """Each bone's length in every frame of the prediction and of the target [B, L, bones] (metres,
    the normalisation ``y = (x - offset) * scale`` undone) and where both its joints are valid in
    the target [B, L, bones]."""
    import torch

    joints = max(max(pair) for pair in bones) + 1
    child = torch.tensor([c for c, _ in bones], device=prediction.device)
    parent = torch.tensor([p for _, p in bones], device=prediction.device)

    def lengths(x):
        p = _metres(x, scale, offset, joints, dims)
        return torch.linalg.vector_norm(p[..., child, :] - p[..., parent, :], dim=-1)

    valid = _joints_valid(mask, joints, dims)  # [B, L, J]
    return lengths(prediction), lengths(target), valid[..., child] & valid[..., parent]


def masked_bone_loss(prediction, target, mask, bones, scale, offset, dims: int = 3):
    """How much a motion's bones stretch: per bone, the mean absolute difference between its length
    in each frame of the prediction and its mean length over the target window, as a fraction of
    that length (lengths in metres after undoing the normalisation ``y = (x - offset) * scale``;
    dimensionless, like the bone-length CV it lowers), over the bones valid in the target
    throughout (torch tensors; differentiable).

    Args:
        prediction, target, mask: [B, L, D]; positions first, ``dims`` components per joint.
        bones: (joint, parent) index pairs into the positioned joints
            (:meth:`~kinectdata.targets.specs.TargetSpec.position_bones`).
        scale, offset: [D] the normalisation.
    """
    if not bones:
        return prediction.new_zeros(())
    made_length, real_length, valid = _bone_lengths(prediction, target, mask, bones, scale, offset, dims)
    both = valid.all(dim=1)  # [B, bones]: valid throughout the window
    typical = real_length.mean(dim=1, keepdim=True)
    stretch = ((made_length - typical).abs() / typical.clamp(min=1e-3)).mean(dim=1)  # [B, bones]
    counted = both.to(prediction.dtype)
    return (stretch * counted).sum() / counted.sum().clamp(min=1.0)


def _moments_gap(made, real):
    """[B, K] the absolute differences of the means plus those of the (population) standard
    deviations over the frames of [B, L, K] made and real values: what the span and bend terms
    compare, whatever the timing."""
    return (made.mean(dim=1) - real.mean(dim=1)).abs() + (
        made.std(dim=1, correction=0) - real.std(dim=1, correction=0)
    ).abs()


def chains_of(bones) -> list[tuple[int, int, int]]:
    """Every two-bone chain, (joint, parent, grandparent) index triples, from (joint, parent)
    ``bones``: (ankle, knee, hip), (wrist, elbow, shoulder)... The joint bent is the middle one."""
    parent = dict(bones)
    return [(child, mid, parent[mid]) for child, mid in bones if mid in parent]


def spans_of(bones) -> list[tuple[int, int]]:
    """Each joint with its grandparent, (joint, grandparent) index pairs, from (joint, parent)
    ``bones``: the ends of every two-bone chain (:func:`chains_of`: ankle and hip across the knee,
    wrist and shoulder across the elbow), whose distance says how far the joint between them is bent."""
    return [(child, grand) for child, _, grand in chains_of(bones)]


def masked_bend_loss(prediction, target, mask, bones, scale, offset, dims: int = 3):
    """How differently a motion bends its joints, in angle: per two-bone chain (:func:`chains_of`:
    the knee between hip and ankle, the elbow between shoulder and wrist...), the angle at the middle
    joint in every frame (radians, pi when straight), and the absolute differences between the
    prediction's and the target's mean and standard deviation of it over the window, over the chains
    valid in the target throughout (torch tensors; differentiable: the angle is ``atan2`` of the
    cross and dot products, whose gradient stays finite near straight).

    The span term (:func:`masked_span_loss`) compares the chain's length end to end as a fraction of
    it, and near straight a large bend shortens it little: on tang2018's fold 2 a cdhc run bent its
    knees at 133 degrees in the median frame of its training windows against the dancers' 157, its
    hip-to-ankle span 2 % short (0.756 m against 0.771) and the span term at 0.04
    (docs/notebook/2026-12-real-dance-variety.md, "The root at the bar's rate, and the bent knee
    back").

    Args:
        prediction, target, mask: [B, L, D]; positions first, ``dims`` (2 or 3) components per joint.
        bones: (joint, parent) index pairs into the positioned joints.
        scale, offset: [D] the normalisation ``y = (x - offset) * scale``.

    Returns:
        A scalar tensor in radians (0 without a two-bone chain valid throughout a window).
    """
    import torch

    chains = chains_of(bones)
    if not chains or dims not in (2, 3):
        return prediction.new_zeros(())
    joints = max(max(chain) for chain in chains) + 1
    child, mid, grand = (torch.tensor(list(ix), device=prediction.device) for ix in zip(*chains))

    def angles(x):
        p = _metres(x, scale, offset, joints, dims)
        u, v = p[..., child, :] - p[..., mid, :], p[..., grand, :] - p[..., mid, :]
        dot = (u * v).sum(dim=-1)
        if dims == 3:
            cross = torch.linalg.vector_norm(torch.linalg.cross(u, v, dim=-1), dim=-1)
        else:
            cross = (u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]).abs()
        return torch.atan2(cross, dot)  # [B, L, chains]

    valid = _joints_valid(mask, joints, dims)  # [B, L, J]
    both = (valid[..., child] & valid[..., mid] & valid[..., grand]).all(dim=1)  # [B, chains]
    real = torch.where(both[:, None], angles(target), torch.zeros((), dtype=prediction.dtype))
    counted = both.to(prediction.dtype)
    return (_moments_gap(angles(prediction), real) * counted).sum() / counted.sum().clamp(min=1.0)


def masked_span_loss(prediction, target, mask, bones, scale, offset, dims: int = 3):
    """How differently a motion bends its joints: per two-bone chain (:func:`spans_of`: hip to
    ankle, shoulder to wrist...), the absolute differences between the prediction's and the
    target's mean and standard deviation of the chain's span over the window, as a fraction of the
    target's mean span (metres after undoing the normalisation ``y = (x - offset) * scale``;
    dimensionless), over the chains valid in the target throughout (torch tensors; differentiable).

    The posture term (:func:`masked_posture_loss`) compares each coordinate apart and the bone term
    (:func:`masked_bone_loss`) each bone's length: neither measures the angle between two bones. A
    fold run on tang2018 danced with its right knee bent under 110 degrees in half of its frames,
    where the dancers' knees bend that far in 3 % (docs/notebook/2026-12-real-dance-variety.md).

    Args:
        prediction, target, mask: [B, L, D]; positions first, ``dims`` components per joint.
        bones: (joint, parent) index pairs into the positioned joints.
        scale, offset: [D] the normalisation.
    """
    spans = spans_of(bones)
    if not spans:
        return prediction.new_zeros(())
    made, real, valid = _bone_lengths(prediction, target, mask, spans, scale, offset, dims)
    both = valid.all(dim=1)  # [B, spans]: valid throughout the window
    typical = real.mean(dim=1)
    counted = both.to(prediction.dtype)
    return (_moments_gap(made, real) / typical.clamp(min=1e-3) * counted).sum() / counted.sum().clamp(min=1.0)


def world_positions(prediction, target, mask, body):
    """The positioned joints of [B, L, D] windows in metres in the world, flattened to
    [B, L, J * dims] (the root's travel added back to root-centred joints), for the prediction and
    the target, and where the joint (and, centred, the root) is valid in the target [B, L, J * dims];
    None for a body without bones, or a centred one without a root. Torch tensors; differentiable."""
    if not body.bones or (body.centred and body.root is None):
        return None
    joints = body.joints
    dims = body.dims
    valid = _joints_valid(mask, joints, dims)  # [B, L, J]
    if body.centred:
        valid = valid & valid[..., body.root : body.root + 1]
    world_mask = valid[..., None].expand(*valid.shape, dims).flatten(-2)

    def world(x):
        return _world(x, body.scale, body.offset, joints, dims, body.root, body.centred).flatten(-2)

    return world(prediction), world(target), world_mask


def masked_world_speed_loss(
    prediction, target, mask, body, chunk: int | None = None, excess: bool = False, component_floor: bool = False
):
    """How far each joint's speed in the world is from the target's, in ratio: the
    :func:`masked_energy_loss` of the joints' positions in metres along each world axis
    (:func:`world_positions`: the root's travel added back to root-centred joints), per stretch of
    ``chunk`` frame-to-frame changes (None: the whole window), over the frames where the joint
    (and the root) are valid.

    The speed term of :func:`masked_rhythm_loss` on the targets themselves cannot see this: a
    root-centred foot that cancels the root's sway keeps its target-space speed while it stands
    still on the floor, and the torso then sways with the root. The field's kinetic features
    (FID_k, :mod:`kinectdata.evaluation.metrics.kinetic`) measure speeds in the world, and there
    the cdhc model on tang2018's validation dances moved its feet at 0.03-0.06 x the real speed
    along the floor and its shoulders and head at 2.3-3 x (docs/notebook/2026-11-real-dance.md).

    Args:
        prediction, target, mask: [B, L, D]; positions first, ``body.dims`` components per joint.
        body: the :class:`Body` (its bones give the positioned joints; ``root`` is needed when
            ``centred``).
        chunk: frame-to-frame changes per stretch.
        excess: the divergence turned round (:func:`masked_energy_loss`'s ``excess``): a joint
            moving faster in the world than the target's costs in proportion, slower only in log
            ratio (``RhythmWeights.world_excess``).
        component_floor: :func:`masked_energy_loss`'s.

    Returns:
        A scalar tensor (0 for a body without bones, or a centred one without a root).
    """
    world = world_positions(prediction, target, mask, body)
    if world is None:
        return prediction.new_zeros(())
    return masked_energy_loss(*world, chunk, excess=excess, component_floor=component_floor)


def masked_world_jitter_loss(prediction, target, mask, body, chunk: int | None = None, component_floor: bool = False):
    """How much more each joint accelerates in the world than the target's: :func:`masked_jitter_loss`
    (the mean squared accelerations and jerks per stretch of ``chunk`` frames, too much costing in
    proportion) of the joints' positions in metres along each world axis (:func:`world_positions`).

    The jitter term on the targets works about the root, where a root-centred trunk holds still
    while the root carries it: there the cdhc model's trunk accelerated along the floor at 2-2.5 x
    the dancers' on tang2018's validation dances (pelvis 2.1-2.7 m/s^2 against 1.1), and its rumbas
    were named cha-chas by their motion (docs/notebook/2026-12-real-dance-variety.md).

    Args:
        prediction, target, mask: [B, L, D]; positions first, ``body.dims`` components per joint.
        body: the :class:`Body`.
        chunk: frames per stretch (None: the whole window).
        component_floor: :func:`masked_energy_loss`'s.

    Returns:
        A scalar tensor (0 for a body without bones, or a centred one without a root).
    """
    world = world_positions(prediction, target, mask, body)
    if world is None:
        return prediction.new_zeros(())
    return masked_jitter_loss(*world, chunk, component_floor=component_floor)


ROOT_BANDS_HZ = ((0.5, 1.0), (1.0, 2.0), (2.0, 4.0))
"""The bands (Hz) :func:`masked_root_band_loss` compares the root's speed along the floor in: the bar's
rate of the slow dances (a waltz's bar at 0.5 Hz, a cha-cha's at 0.5-0.6; two of their beats at
1-1.5), the beat's, and the half beat's."""


def masked_root_band_loss(prediction, target, mask, body, fps: float, bands=ROOT_BANDS_HZ):
    """How differently fast the root moves along the floor in each band of ``bands`` than the
    target's, whatever the phase: per [B, L, D] window whose root is valid throughout, the root's
    velocity along the floor's axes (every axis but y, the up axis) in metres per second
    (:func:`world_positions`), Hann-windowed over the whole window, and the power of its transform
    summed over the bins of each band (proportional to the mean squared speed in that band), made
    against real by :func:`masked_energy_loss`'s divergence ``2 (r/m - log(r/m) - 1)`` (too slow
    costing in proportion, too fast in log ratio; each band's power floored at 1 % of the target's
    mean over the batch).

    The speed terms see how fast the root moves per 2 s, not at which rate it moves: on tang2018's
    fold 2 the cdhc model's root moved along the floor at 0.22 m/s between 1 and 2 Hz (the beat)
    and at 0.08 between 0.5 and 1 Hz, the dancers' at 0.09 and 0.23 (the bar's rate), and the trunk
    riding on it accelerated twice as hard as theirs (docs/notebook/2026-12-real-dance-variety.md,
    "The root's sway at the beat, brought to the dancers'").

    Args:
        prediction, target, mask: [B, L, D]; positions first, ``body.dims`` components per joint.
        body: the :class:`Body` (its ``root`` is the joint measured).
        fps: frames per second.
        bands: (low, high) Hz pairs, each from ``low`` up to, not including, ``high``; a band holding
            no bin of the window's transform is skipped.

    Returns:
        A scalar tensor (0 for a body without a root or bones, windows with no valid root throughout,
        or no band with a bin).
    """
    return _root_term(prediction, target, mask, body, _root_band_divergence, fps, bands, vertical=False)


ROOT_RISE_BANDS_HZ = ((0.5, 1.0), (1.0, 2.0), (2.0, 4.0), (4.0, 8.0))
"""The bands (Hz) :func:`masked_root_rise_loss` compares the root's vertical speed in: those of
:data:`ROOT_BANDS_HZ` and the quarter beat's, where a waltz's rise and fall is still sharp."""


def masked_root_rise_loss(prediction, target, mask, body, fps: float, bands=ROOT_RISE_BANDS_HZ):
    """:func:`masked_root_band_loss` of the root's vertical velocity (the y axis, metres per second):
    how differently fast the root rises and falls in each band than the target's, whatever the phase.

    The root band term asks only the root's speed along the floor for the dancers' rates, and it
    took the rise and fall with it: on tang2018's fold 2 the cdhc model's scored waltzes then moved
    the pelvis up and down with 0.66 times the real waltzers' vertical kinetic energy (1.11 times
    without the term); on fold 1, with the span term at 30 and the beat held as well (c1), with 0.42
    (the held lead: 0.84), and fold 1's Latin dances were named waltzes
    (docs/notebook/2026-12-real-dance-variety.md, "The rise and fall kept, and the joints bent to
    the dancers' angle").

    Arguments and result as :func:`masked_root_band_loss`'s, the root's height in place of its place
    on the floor (0 also for windows whose root height is not valid throughout or that are shorter
    than 3 frames).
    """
    return _root_term(prediction, target, mask, body, _root_band_divergence, fps, bands, vertical=True)


def masked_root_phase_loss(prediction, target, mask, body, fps: float, bands=ROOT_RISE_BANDS_HZ):
    """How far out of phase with the target the root rises and falls, band by band: per [B, L, D]
    window whose root height is valid throughout, the root's vertical velocity (m/s, Hann-windowed
    over the window) made and real are band-passed to each band of ``bands`` (their transforms kept at
    the band's bins), and each band costs one minus their correlation, ``1 - Re<m, r> / (|m| |r|)``:
    0 in phase, 1 unrelated, 2 in antiphase, whatever the size (under the made power, a floor of 1 %
    of the band's real power averaged over the batch's whole windows, at most the window's own). The
    bands are weighed by the target's share of its power in them, so the band the dancer rises and
    falls in most keeps time most. Windows whose real power over the bands is under 1 % of the mean
    over the batch's whole windows are not counted (no rise to keep in time).

    :func:`masked_root_rise_loss` asks each band for the dancer's power whatever the phase, and power
    can be bought with motion that keeps no time: on tang2018's fold 2 the rise term at 5 brought the
    scored waltzes' rise and fall back and took the beat (9 of 12 songs at a metrical level against
    11; docs/notebook/2026-12-real-dance-variety.md). This term asks the rise and fall to come when
    the dancer's did, to the same music: in time with the heard beat as far as the dancer was.
    Being blind to size, it leaves the amount of rise to the rise term.

    Arguments as :func:`masked_root_band_loss`'s; a scalar tensor, 0 for a body without a root or
    bones, windows with no root height valid throughout or shorter than 3 frames, or no band counted.
    """
    return _root_term(prediction, target, mask, body, _root_phase_gap, fps, bands)


def _root_term(prediction, target, mask, body, term, *args, **kwargs):
    """``term(made, real, valid, body, *args, **kwargs)`` (:func:`_root_band_divergence`,
    :func:`_root_phase_gap`) of [B, L, D] windows, their world positions made here
    (:func:`world_positions`); 0 for a body without a root or bones."""
    world = world_positions(prediction, target, mask, body) if body.root is not None else None
    if world is None:
        return prediction.new_zeros(())
    return term(*world, body, *args, **kwargs)


def _root_band_spectra(made, real, valid, body, fps: float, bands, vertical: bool):
    """The root's velocity transforms, band by band, of world positions already made
    (:func:`world_positions`: [B, L, J * dims] made and real, and where they are valid) for a body with
    a root: ``vertical`` False, along the floor's axes; True, along y. Per band holding a bin of the
    window's transform, the made and real Hann-windowed transforms of the velocity (m/s) at its bins,
    [B, bins, axes] complex, and ``whole``, [B] bool, the windows whose root is valid throughout; None
    when no window is, the windows are shorter than 3 frames or no band holds a bin."""
    import torch

    dims = body.dims
    columns = [body.root * dims + axis for axis in range(dims) if (axis == 1) == vertical]
    whole = valid[..., columns].all(dim=2).all(dim=1)  # [B]
    steps = made.shape[1] - 1
    if steps < 2 or not bool(whole.any()):
        return None
    window = torch.hann_window(steps, device=made.device, dtype=made.dtype)[None, :, None]
    keep = whole[:, None, None].to(made.dtype)

    def transform(x):
        velocity = (x[:, 1:, columns] - x[:, :-1, columns]) * fps * keep  # [B, L-1, axes]
        return torch.fft.rfft(velocity * window, dim=1)  # [B, bins, axes]

    freqs = torch.fft.rfftfreq(steps, d=1.0 / fps).to(made.device)
    made_t, real_t = transform(made), transform(torch.where(valid, real, torch.zeros_like(real)))
    chosen = [(freqs >= low) & (freqs < high) for low, high in bands]
    chosen = [c for c in chosen if bool(c.any())]
    if not chosen:
        return None
    return [(made_t[:, c], real_t[:, c]) for c in chosen], whole


def _band_powers(per_band):
    """[B, bands] made and real powers (summed |transform|^2 over each band's bins and the axes) of
    :func:`_root_band_spectra`'s per-band transforms."""
    import torch

    made = torch.stack([(g.abs() ** 2).sum(dim=(1, 2)) for g, _ in per_band], dim=1)
    real = torch.stack([(t.abs() ** 2).sum(dim=(1, 2)) for _, t in per_band], dim=1)
    return made, real


def _band_floor(real_power, counted):
    """1 % of each band's real power, [B, bands], averaged over the ``counted`` windows: the floor
    under a band's power."""
    return 1e-2 * (real_power * counted).sum(dim=0).detach() / counted.sum(dim=0).clamp(min=1.0) + 1e-12


def _root_band_divergence(made, real, valid, body, fps: float, bands=ROOT_BANDS_HZ, vertical: bool = False):
    """:func:`masked_root_band_loss` (``vertical`` False: the floor's axes) or
    :func:`masked_root_rise_loss` (True: the y axis) of world positions already made
    (:func:`world_positions`: [B, L, J * dims] made and real, and where they are valid), for a body
    with a root."""
    spectra = _root_band_spectra(made, real, valid, body, fps, bands, vertical)
    return made.new_zeros(()) if spectra is None else _band_divergence(*spectra)


def _band_divergence(per_band, whole):
    """The divergence of :func:`masked_root_band_loss` from :func:`_root_band_spectra`'s result."""
    import torch

    m, r = _band_powers(per_band)  # [B, bands]
    counted = whole.to(r.dtype)[:, None].expand_as(r)
    floor = _band_floor(r, counted)
    ratio = (r + floor) / (m + floor)
    divergence = 2.0 * (ratio - torch.log(ratio) - 1.0)
    return (divergence * counted).sum() / counted.sum().clamp(min=1.0)


def _root_phase_gap(made, real, valid, body, fps: float, bands=ROOT_RISE_BANDS_HZ):
    """:func:`masked_root_phase_loss` of world positions already made (:func:`world_positions`), for a
    body with a root."""
    spectra = _root_band_spectra(made, real, valid, body, fps, bands, vertical=True)
    return made.new_zeros(()) if spectra is None else _phase_gap(*spectra)


def _phase_gap(per_band, whole):
    """The gap of :func:`masked_root_phase_loss` from :func:`_root_band_spectra`'s result."""
    import torch

    m, r = _band_powers(per_band)  # [B, bands]
    cross = torch.stack([(g * t.conj()).real.sum(dim=(1, 2)) for g, t in per_band], dim=1)
    # The floor under the made power keeps the gradient bounded where the model does not rise at all;
    # capped at the band's own real power, so that a copy of the dancer costs 0 in a quiet band too.
    floor = torch.minimum(_band_floor(r, whole.to(r.dtype)[:, None].expand_as(r)), r.detach())
    gap = 1.0 - cross / torch.sqrt(torch.maximum(m, floor) * r + 1e-12)
    total = r.sum(dim=1)  # [B]
    share = r / total[:, None].clamp(min=1e-12)
    typical = total[whole].mean().detach()
    counted = (whole & (total > 1e-2 * typical)).to(r.dtype)  # a dancer who barely rises keeps no phase
    return ((gap * share).sum(dim=1) * counted).sum() / counted.sum().clamp(min=1.0)


def _feet_valid(mask, feet, root: int, dims: int):
    """[B, L] where every joint ``feet`` [4, P] weighs and the root are valid in a [B, L, D] mask."""
    used = (feet > 0).any(dim=0).clone()
    used[root] = True
    return _joints_valid(mask, feet.shape[1], dims)[..., used].all(dim=-1)


def _foot_points(p, feet):
    """The four foot points [B, L, 4, dims] (left ankle, left foot, right ankle, right foot) of
    positions [B, L, P, dims], as ``feet`` [4, P] weighs the joints."""
    import torch

    return torch.einsum("kp,blpc->blkc", feet.to(p.dtype), p)


def masked_foot_loss(
    prediction, target, mask, feet, scale, offset, root: int, centred: bool = False, up_axis: int = 1, dims: int = 3
):
    """How much more the feet slide than the target's: per [B, L, D] window, EDGE's physical foot
    contact score (:mod:`kinectdata.evaluation.metrics.foot_contact`: per frame, the horizontal
    step of the slower joint of each foot, left x right, x the root's acceleration as a share of
    its largest in the window, its upward part clamped at >= 0; the mean over frames) of the
    prediction and of the target; the squared log of their ratio where the prediction's is the
    larger, 0 where it is not (a motion may plant its feet more than the dancer did), each floored
    at 1 % of the target's mean over the batch (torch tensors; differentiable).

    Args:
        prediction, target, mask: [B, L, D]; positions first, ``dims`` components per joint.
        feet: [4, P] weights over the P positioned joints of the left ankle, left foot, right
            ankle and right foot (as the joint set's SMPL-24 mapping makes them).
        scale, offset: [D] the normalisation ``y = (x - offset) * scale`` (metres after undoing).
        root: the root's index among the positioned joints (whose acceleration the score reads).
        centred: the positions are root-centred (:func:`~kinectdata.targets.specs.extract_targets`):
            the root's position is added back to the others'.
        up_axis: the vertical axis (1: y up, the toolkit's frame).
    """
    import torch

    joints = feet.shape[1]

    flat = [a for a in range(dims) if a != up_axis]
    valid = _feet_valid(mask, feet, root, dims)  # [B, L]
    frames = (valid[:, 2:] & valid[:, 1:-1] & valid[:, :-2]).to(prediction.dtype)  # [B, L-2]

    def score(x):
        p = _world(x, scale, offset, joints, dims, root, centred)
        acceleration = p[:, 2:, root] - 2 * p[:, 1:-1, root] + p[:, :-2, root]  # [B, L-2, dims]
        upward = acceleration[..., up_axis].clamp(min=0.0)
        level = torch.stack([upward if a == up_axis else acceleration[..., a] for a in range(dims)], dim=-1)
        magnitude = torch.sqrt((level**2).sum(dim=-1) + 1e-12) * frames
        share = magnitude / magnitude.amax(dim=1, keepdim=True).clamp(min=1e-9)
        foot = _foot_points(p, feet)[..., flat]  # [B, L, 4, 2]
        step = torch.sqrt(((foot[:, 2:] - foot[:, 1:-1]) ** 2).sum(dim=-1) + 1e-12)  # [B, L-2, 4]
        both = torch.minimum(step[..., 0], step[..., 1]) * torch.minimum(step[..., 2], step[..., 3])
        return (both * share * frames).sum(dim=1) / frames.sum(dim=1).clamp(min=1.0)  # [B]

    made, real = score(prediction), score(target)
    counted = (frames.sum(dim=1) > 0).to(prediction.dtype)
    floor = 1e-2 * (real * counted).sum().detach() / counted.sum().clamp(min=1.0) + 1e-12
    excess = torch.relu(torch.log(made + floor) - torch.log(real.detach() + floor))
    return (excess**2 * counted).sum() / counted.sum().clamp(min=1.0)


def masked_step_loss(prediction, target, mask, body):
    """How differently fast the feet move about the root than the target's over a window: per
    [B, L, D] window and per component of the four foot joints' positions about the root (left
    ankle, left foot, right ankle, right foot as ``body.feet`` weighs them, in metres along each
    axis, the root's position taken away), :func:`masked_energy_loss`'s divergence of the mean
    squared frame-to-frame changes over the whole window (too slow costing in proportion, too fast
    in log ratio), over the frames where the feet and the root are valid (torch tensors;
    differentiable).

    The world speed term compares each joint's speed with the root's travel in it: a body carried
    along the floor moves its feet there without stepping. On tang2018's fold 3 both models' hips
    moved along the floor at 1.05-1.3 x the dancers' and their feet about the hips at 0.6-0.7 x (0.4
    on folds 1 and 2): the dancer glided, and the four foot features were about half of FID_k on the
    aist protocol (docs/notebook/2026-12-real-dance-variety.md, "The dancer glides"). The whole
    window, not a stretch of 2 s: when the music does not say in which bar the dancer steps, the
    mean speed over ten seconds is what it does say. At weight 20 both models' feet came to
    0.8 x about the hips but no faster along the floor (the hips swayed over planted feet) and
    FID_k rose: tried, not adopted (docs/training.md).

    Args:
        prediction, target, mask: [B, L, D]; positions first, ``body.dims`` components per joint.
        body: the :class:`Body` (``feet`` and ``root`` needed).

    Returns:
        A scalar tensor (0 for a body without feet or root).
    """
    if body.feet is None or body.root is None:
        return prediction.new_zeros(())
    joints = body.feet.shape[1]
    valid = _feet_valid(mask, body.feet, body.root, body.dims)  # [B, L]

    def about_root(x):
        p = _world(x, body.scale, body.offset, joints, body.dims, body.root, body.centred)
        return _foot_points(p - p[..., body.root : body.root + 1, :], body.feet).flatten(-2)  # [B, L, 4 * dims]

    made, real = about_root(prediction), about_root(target)
    return masked_energy_loss(made, real, valid[..., None].expand_as(real))


def masked_bone_jitter_loss(
    prediction,
    target,
    mask,
    bones,
    scale,
    offset,
    dims: int = 3,
    chunk: int | None = None,
    component_floor: bool = False,
):
    """How much faster a motion's bones stretch and shrink than the target's: per bone and per stretch
    of ``chunk`` frames, the mean squared frame-to-frame change of its length (metres, after undoing
    the normalisation ``y = (x - offset) * scale``) made against the target's, by the Itakura-Saito
    divergence turned round (:func:`masked_energy_loss` with ``excess``: twice the target's costs 0.61,
    ten times 13.4), over the frame pairs where both of the bone's joints are valid in the target.

    :func:`masked_bone_loss` asks each bone to keep its length on average; a bone can keep it and
    still jump a centimetre between frames, which the real dancers' do not: on two cross-validation
    folds of tang2018 the cdhc model's spine changed its length by more than 6 mm between frames 131
    times where the real dancers' did 22 times (14 with this term), and the peers' geometric
    features, which count a chest moving along the spine faster than 1.8 humerus lengths a second,
    then vary where the real dancers' never do (FID_g multiplied by 1e10, docs/notebook/2026-11-real-dance.md).
    Torch tensors [B, L, D]; a scalar.

    Args:
        prediction, target, mask: [B, L, D]; positions first, ``dims`` components per joint.
        bones: (joint, parent) index pairs into the positioned joints.
        scale, offset: [D] the normalisation.
        chunk: frames per stretch (None: the whole window).
        component_floor: :func:`masked_energy_loss`'s (each bone floored by its own length changes).
    """
    if not bones:
        return prediction.new_zeros(())
    made_length, real_length, valid = _bone_lengths(prediction, target, mask, bones, scale, offset, dims)
    return masked_energy_loss(made_length, real_length, valid, chunk, excess=True, component_floor=component_floor)


@dataclass(frozen=True)
class Body:
    """What :func:`masked_rhythm_loss` needs to measure a motion's body in metres.

    Attributes:
        bones: (joint, parent) index pairs into the positioned joints, for :func:`masked_bone_loss`.
        scale, offset: [D] torch tensors, the normalisation ``y = (x - offset) * scale``.
        dims: components per position.
        feet: [4, P] torch tensor for :func:`masked_foot_loss`, or None (no foot term).
        root: the root's index among the positioned joints (needed with ``feet``).
        centred: the positions are root-centred.
    """

    bones: list[tuple[int, int]]
    scale: Any
    offset: Any
    dims: int = 3
    feet: Any = None
    root: int | None = None
    centred: bool = False

    @property
    def joints(self) -> int:
        """How many positioned joints the terms read: through the last joint a bone or the root names."""
        joints = max(max(pair) for pair in self.bones) + 1
        return joints if self.root is None else max(joints, self.root + 1)

    def to(self, device) -> Body:
        """The same body with its tensors on ``device``."""
        feet = None if self.feet is None else self.feet.to(device)
        return replace(self, scale=self.scale.to(device), offset=self.offset.to(device), feet=feet)


@dataclass(frozen=True)
class RhythmWeights:
    """The weights of :func:`masked_rhythm_loss`'s optional terms (``TrainConfig``'s fields of the
    same names with ``_weight``: :meth:`~kinectdata.training.config.TrainConfig.rhythm_weights`); a
    term of weight 0 is not computed. Named, not positional: nine floats in a row are easy to pass
    in the wrong order.

    Three terms on the body were always part of the loss and have weights other than 0 by default:
    ``bone`` (10: a stretch of a tenth of a bone's length, about the real dancers' bone-length CV on
    tang2018, then weighs 1, the order of the spectral term; at 1 the bones were 1.5 times as
    variable as the real ones on the validation dances, docs/notebook/2026-11-real-dance.md),
    ``world_speed`` (1, that of the speed term on the targets: with it the cdhc model's feet step
    and its torso sways less, docs/notebook/2026-11-real-dance.md) and ``foot`` (10: feet sliding
    twice as much as the real dancer's then cost 4.8, the order of the other terms')."""

    posture: float = 3.0
    jitter: float = 0.0
    periodogram: float = 0.0
    bone_jitter: float = 0.0
    low_energy: float = 0.0
    span: float = 0.0
    bend: float = 0.0
    repetition: float = 0.0
    world_excess: float = 0.0
    world_jitter: float = 0.0
    root_band: float = 0.0
    root_rise: float = 0.0
    root_phase: float = 0.0
    step: float = 0.0
    bone: float = 10.0
    world_speed: float = 1.0
    foot: float = 10.0


def rhythm_weight_settings() -> tuple[str, ...]:
    """The training settings that weigh :func:`masked_rhythm_loss`'s terms: each field of
    :class:`RhythmWeights` with ``_weight`` (``posture_weight``...), in the fields' order. The one
    list the training settings, the published loop's zeros and the checks on them are made from."""
    from dataclasses import fields

    return tuple(f"{f.name}_weight" for f in fields(RhythmWeights))


def masked_rhythm_loss(
    prediction,
    target,
    mask,
    fps: float,
    body=None,
    weights: RhythmWeights | None = None,
    component_floor: bool = False,
):
    """The free-running loss of training (``TrainConfig.free_weight``): the spectra of the motion's
    changes (:func:`masked_rhythm_spectrum_loss`: how often and how much at each tempo, whatever the
    phase), its speed and the size of its speed's changes in every :data:`ENERGY_CHUNK_S` seconds
    (:func:`masked_energy_loss` of the motion and of its frame-to-frame changes: the second keeps a
    motion made from the music alone from jittering), its postures' means and spreads
    (:func:`masked_posture_loss`) and, given a :class:`Body`, how much its bones stretch against the
    target's (``weights.bone``), its joints' speeds in the world
    (:func:`masked_world_speed_loss`, per :data:`ENERGY_CHUNK_S`, ``weights.world_speed``)
    and, when the body has feet, how much more they slide (``weights.foot``).

    ``weights`` (:class:`RhythmWeights`, its defaults when None) weigh the posture term and the
    optional ones: how much more the motion jitters (:func:`masked_jitter_loss`), where its periods
    lie (:func:`masked_periodogram_loss`), the speed of its slow part
    (:func:`masked_low_band_energy_loss`) and, given a body, how much faster its bones change their
    lengths (:func:`masked_bone_jitter_loss` per :data:`ENERGY_CHUNK_S`), how differently it bends
    its joints (:func:`masked_span_loss` end to end, :func:`masked_bend_loss` in angle), how differently it repeats
    (:func:`masked_repetition_loss`), how much faster its joints move in the world than the
    target's (:func:`masked_world_speed_loss` with ``excess``), how much more they accelerate
    there (:func:`masked_world_jitter_loss`) and how differently fast the root moves along the floor
    at the bar's rate, the beat's and the half beat's (:func:`masked_root_band_loss`) and how
    differently fast it rises and falls there and at the quarter beat's (:func:`masked_root_rise_loss`)
    and how far out of phase with the target (:func:`masked_root_phase_loss`), and how differently
    fast its feet move about the root (:func:`masked_step_loss`).
    ``component_floor``: every speed, jitter and bone term floors each component by its own mean
    (:func:`masked_energy_loss`'s). [B, L, D] tensors; a scalar."""
    cf = component_floor
    w = RhythmWeights() if weights is None else weights
    chunk = max(1, round(ENERGY_CHUNK_S * fps))
    loss = masked_rhythm_spectrum_loss(prediction, target, mask, fps) + masked_energy_loss(
        prediction, target, mask, chunk, component_floor=cf
    )
    loss = loss + masked_energy_loss(*_changes(prediction, target, mask), chunk, component_floor=cf)
    loss = loss + w.posture * masked_posture_loss(prediction, target, mask)
    if w.jitter > 0:
        loss = loss + w.jitter * masked_jitter_loss(prediction, target, mask, chunk, component_floor=cf)
    if w.periodogram > 0:
        loss = loss + w.periodogram * masked_periodogram_loss(prediction, target, mask, fps)
    if w.low_energy > 0:
        loss = loss + w.low_energy * masked_low_band_energy_loss(
            prediction, target, mask, fps, chunk, component_floor=cf
        )
    if body is not None:
        if w.bone > 0:
            loss = loss + w.bone * masked_bone_loss(
                prediction, target, mask, body.bones, body.scale, body.offset, body.dims
            )
        world = world_positions(prediction, target, mask, body)
        if world is not None:
            if w.world_speed > 0:
                loss = loss + w.world_speed * masked_energy_loss(*world, chunk, component_floor=cf)
            if w.world_excess > 0:
                loss = loss + w.world_excess * masked_energy_loss(*world, chunk, excess=True, component_floor=cf)
            if w.world_jitter > 0:
                loss = loss + w.world_jitter * masked_jitter_loss(*world, chunk, component_floor=cf)
            if w.root_band > 0 and body.root is not None:
                loss = loss + w.root_band * _root_band_divergence(*world, body, fps)
            if (w.root_rise > 0 or w.root_phase > 0) and body.root is not None:
                # one transform of the root's height for both terms
                rise = _root_band_spectra(*world, body, fps, ROOT_RISE_BANDS_HZ, vertical=True)
                if rise is not None and w.root_rise > 0:
                    loss = loss + w.root_rise * _band_divergence(*rise)
                if rise is not None and w.root_phase > 0:
                    loss = loss + w.root_phase * _phase_gap(*rise)
        if w.span > 0:
            loss = loss + w.span * masked_span_loss(
                prediction, target, mask, body.bones, body.scale, body.offset, body.dims
            )
        if w.bend > 0:
            loss = loss + w.bend * masked_bend_loss(
                prediction, target, mask, body.bones, body.scale, body.offset, body.dims
            )
        if w.bone_jitter > 0:
            loss = loss + w.bone_jitter * masked_bone_jitter_loss(
                prediction, target, mask, body.bones, body.scale, body.offset, body.dims, chunk, component_floor=cf
            )
        if w.repetition > 0:
            loss = loss + w.repetition * masked_repetition_loss(prediction, target, mask, body, fps)
        if w.step > 0:
            loss = loss + w.step * masked_step_loss(prediction, target, mask, body)
        if body.feet is not None and w.foot > 0:
            loss = loss + w.foot * masked_foot_loss(
                prediction, target, mask, body.feet, body.scale, body.offset, body.root, body.centred, dims=body.dims
            )
    return loss
