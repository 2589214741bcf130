"""Metrics on arrays: plain numpy functions, shapes and units in their docstrings.

- :mod:`.pose_error`: SMAPE and motion energy of generated against real poses (Yalta et al.);
- :mod:`.kinetic`, :mod:`.geometric`: the field's per-sequence motion features (AIST++ API);
- :mod:`.distribution`: FID and diversity over sets of those features, bootstrap intervals;
- :mod:`.beat_alignment`: the Beat Align Score as the peers compute it, both directions;
- :mod:`.foot_contact`: EDGE's physical foot contact score;
- :mod:`.quality`: bone-length consistency and jitter (jerk);
- :mod:`.turning`: how fast the body turns about the vertical, and its share of the motion's energy.

Definitions, sources and the fixtures that prove them: docs/metrics.md.
"""

from kinectdata.core.body_quality import bone_length_variation, mean_jerk
from kinectdata.evaluation.metrics.beat_alignment import (
    music_beat_frames,
    peer_beat_align_score,
    peer_motion_beats,
)
from kinectdata.evaluation.metrics.distribution import (
    bootstrap_interval,
    constant_reference_features,
    diversity,
    frechet_distance,
    mean_gaps,
    standardise_by_reference,
)
from kinectdata.evaluation.metrics.foot_contact import foot_contact_score, physical_foot_contact
from kinectdata.evaluation.metrics.geometric import describe_feature, geometric_features
from kinectdata.evaluation.metrics.kinetic import describe_kinetic_feature, kinetic_features
from kinectdata.evaluation.metrics.pose_error import motion_energy, motion_energy_per_s, smape
from kinectdata.evaluation.metrics.turning import Turning, turning, turning_rates

__all__ = [
    "bone_length_variation",
    "bootstrap_interval",
    "constant_reference_features",
    "diversity",
    "foot_contact_score",
    "frechet_distance",
    "mean_gaps",
    "describe_feature",
    "geometric_features",
    "kinetic_features",
    "describe_kinetic_feature",
    "mean_jerk",
    "motion_energy",
    "motion_energy_per_s",
    "music_beat_frames",
    "peer_beat_align_score",
    "peer_motion_beats",
    "physical_foot_contact",
    "smape",
    "standardise_by_reference",
    "Turning",
    "turning",
    "turning_rates",
]
