"""Set metrics on motion features: Fréchet distance (FID_k, FID_g) and diversity (Div_k, Div_g).

Both take one feature vector per sequence ([N, D], from :func:`kinetic_features` or
:func:`geometric_features`). As mint (``tools/calculate_scores.py``) and Bailando
(``utils/metrics_new.py``) do, both sets are first standardised with the **reference** set's mean
and standard deviation (ddof 0, plus 1e-10): :func:`standardise_by_reference`.

- FID: ``|mu_g - mu_r|^2 + tr(S_g) + tr(S_r) - 2 tr((S_g S_r)^1/2)``, covariances with ddof 1 (as
  ``np.cov``). The trace of the square root is computed from the eigenvalues of the symmetric
  ``S_r^1/2 S_g S_r^1/2``, which equals the peers' ``scipy.linalg.sqrtm`` value without its
  complex round-off (their FID carries an imaginary part near 1e-6 when a set has fewer sequences
  than features, as every small test set does).
- Diversity: the mean Euclidean distance over the N (N - 1) / 2 pairs of sequences.

:func:`bootstrap_interval` says how much a set metric moves when the sequences are resampled.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from kinectdata.core.errors import KinectDataError

STD_EPSILON = 1e-10
"""Added to the reference standard deviation before dividing (the peers' value)."""


def standardise_by_reference(generated: np.ndarray, reference: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Both feature sets scaled by the reference set's mean and standard deviation.

    Args:
        generated: [N, D] features of the generated sequences.
        reference: [M, D] features of the reference (real) sequences.

    Returns:
        ``(generated, reference)`` as float64 ``(x - mean_r) / (std_r + 1e-10)``, std with ddof 0.
        A feature constant over the reference but not over the generated set is multiplied by
        1e10 here, as by the peers: :func:`constant_reference_features` finds them.
    """
    g, r = _two_sets(generated, reference)
    mean, std = r.mean(axis=0), r.std(axis=0) + STD_EPSILON
    return (g - mean) / std, (r - mean) / std


def constant_reference_features(generated: np.ndarray, reference: np.ndarray) -> list[int]:
    """Feature indices constant over the reference set but varying in the generated set [N, D] / [M, D]."""
    g, r = _features(generated, "generated"), _features(reference, "reference")
    return [int(i) for i in np.flatnonzero((np.ptp(r, axis=0) == 0) & (np.ptp(g, axis=0) > 0))]


FAR_FEATURE = 1e3
"""A standardised generated feature beyond this many reference standard deviations swamps FID."""


def far_from_reference_features(generated_std: np.ndarray, constant: list[int] = ()) -> list[int]:
    """Feature indices of a standardised generated set [N, D] (:func:`standardise_by_reference`)
    with a value more than :data:`FAR_FEATURE` reference standard deviations from the reference
    mean, leaving out ``constant`` (those :func:`constant_reference_features` already names): a
    feature whose reference spread is tiny but not zero then weighs millions of times the others
    in FID."""
    far = np.flatnonzero(np.abs(np.asarray(generated_std, dtype=np.float64)).max(axis=0) > FAR_FEATURE)
    named = set(constant)
    return [int(i) for i in far if int(i) not in named]


def mean_gaps(generated: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Each feature's part of the Fréchet distance's mean term: the squared difference of the two
    sets' means, per feature, of [N, D] and [M, D] features (already standardised, as
    :func:`frechet_distance` takes them). Their sum is the term ``|mu_g - mu_r|^2``; the rest of the
    distance is the covariances'. [D] float64, >= 0."""
    g, r = _two_sets(generated, reference)
    return (g.mean(axis=0) - r.mean(axis=0)) ** 2


def frechet_distance(generated: np.ndarray, reference: np.ndarray) -> float:
    """Fréchet distance between Gaussians fitted to two feature sets (already standardised).

    Args:
        generated: [N, D] features, N >= 2.
        reference: [M, D] features, M >= 2.

    Returns:
        The squared Fréchet distance (unitless for standardised features), >= 0 up to round-off.
    """
    g, r = _two_sets(generated, reference, minimum=2)
    mu_g, mu_r = g.mean(axis=0), r.mean(axis=0)
    # the covariances as A^T A and B^T B of the centred rows: tr(sqrt(root_r cov_g root_r)) is then
    # the sum of the singular values of A B^T, an [N, M] matrix, where sets smaller than the features
    # (evaluate's songs, its bootstrap's draws) need no D x D eigenproblem
    a = (g - mu_g) / np.sqrt(len(g) - 1)
    b = (r - mu_r) / np.sqrt(len(r) - 1)
    if len(g) * len(r) <= g.shape[1] ** 2:
        trace_root = float(np.sum(np.linalg.svd(a @ b.T, compute_uv=False)))
    else:
        root_r = _psd_sqrt(b.T @ b)
        product = np.linalg.eigvalsh(root_r @ (a.T @ a) @ root_r)
        trace_root = float(np.sum(np.sqrt(np.clip(product, 0.0, None))))
    diff = mu_g - mu_r
    return float(diff @ diff + np.sum(a * a) + np.sum(b * b) - 2.0 * trace_root)


def diversity(features: np.ndarray, draw: np.ndarray | None = None) -> float:
    """Mean Euclidean distance over all unordered pairs of rows of [N, D] features, N >= 2.

    Args:
        features: [N, D] feature vectors.
        draw: optional [n] row indices drawn with replacement (a bootstrap resample): the mean is
            then over the pairs of drawn rows that are different sequences, since a sequence paired
            with its own copy would add a distance of 0 that no real set has.
    """
    f = _features(features, "features", 2)
    from scipy.spatial.distance import pdist, squareform

    if draw is None:
        return float(np.mean(pdist(f)))
    rows = np.asarray(draw)
    distances = squareform(pdist(f))[rows[:, None], rows[None, :]]
    different = rows[:, None] != rows[None, :]
    return float(distances[different].mean()) if different.any() else float("nan")


@dataclass(frozen=True)
class Interval:
    """A bootstrap percentile interval of a set metric."""

    low: float
    high: float
    level: float
    resamples: int

    def to_dict(self) -> dict:
        return {"low": self.low, "high": self.high, "level": self.level, "resamples": self.resamples}


def bootstrap_interval(
    statistic: Callable[[np.ndarray, np.ndarray], float],
    generated_count: int,
    reference_count: int,
    resamples: int = 1000,
    level: float = 0.95,
    seed: int = 0,
) -> Interval:
    """Percentile interval of a set metric over sequences drawn with replacement.

    Each resample draws ``generated_count`` generated and ``reference_count`` reference sequence
    indices with replacement, independently, and calls ``statistic(generated_rows,
    reference_rows)`` with the two [n] index arrays. Standardise the features once, on the whole
    reference set, before: a resampled reference in which a rare feature happens to be constant
    would otherwise be divided by 1e-10. Resamples where the statistic is not finite are left out.

    Args:
        statistic: the metric of the drawn rows, e.g. ``lambda g, r: frechet_distance(G[g], R[r])``.
        generated_count: N generated sequences; reference_count: M reference sequences.
        resamples: bootstrap draws.
        level: coverage of the interval, e.g. 0.95.
        seed: random seed.
    """
    if generated_count < 1 or reference_count < 1:
        raise KinectDataError("a bootstrap interval needs at least one sequence in each set")
    rng = np.random.default_rng(seed)
    values = []
    for _ in range(resamples):
        g = rng.integers(0, generated_count, generated_count)
        r = rng.integers(0, reference_count, reference_count)
        with np.errstate(all="ignore"):
            value = statistic(g, r)
        if np.isfinite(value):
            values.append(value)
    if not values:
        raise KinectDataError("no bootstrap resample gave a finite value")
    tail = 100 * (1 - level) / 2
    low, high = np.percentile(values, [tail, 100 - tail])
    return Interval(float(low), float(high), level, len(values))


def _psd_sqrt(matrix: np.ndarray) -> np.ndarray:
    """Symmetric square root of a positive semi-definite matrix (negative round-off eigenvalues as 0)."""
    values, vectors = np.linalg.eigh((matrix + matrix.T) / 2)
    return (vectors * np.sqrt(np.clip(values, 0.0, None))) @ vectors.T


def _two_sets(generated: np.ndarray, reference: np.ndarray, minimum: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Both sets checked by :func:`_features` (at least ``minimum`` sequences each) and of the same
    number of features."""
    g, r = _features(generated, "generated", minimum), _features(reference, "reference", minimum)
    if g.shape[1] != r.shape[1]:
        raise KinectDataError(f"generated features have {g.shape[1]} dimensions, reference {r.shape[1]}")
    return g, r


def _features(x: np.ndarray, what: str, minimum: int = 1) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if a.ndim != 2:
        raise KinectDataError(f"{what} must be [N, D] feature vectors, got shape {a.shape}")
    if a.shape[0] < minimum:
        raise KinectDataError(f"{what}: {a.shape[0]} sequence(s); this metric needs at least {minimum}")
    if not np.all(np.isfinite(a)):
        raise KinectDataError(f"{what}: sequence {int(np.argmin(np.isfinite(a).all(axis=1)))} has non-finite features")
    return a
