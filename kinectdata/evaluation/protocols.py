"""The field's evaluation protocols: which preprocessing, rates and directions each peer's table uses.

A protocol is data: the frame rate the features and beats are computed at, whether each sequence
is moved so that its first root position is the origin (Bailando), how many frames are kept, the
Beat Align Score's direction and sigma, and PFC's rate. Metrics and features are in
:mod:`kinectdata.evaluation.metrics`; docs/metrics.md says where each protocol comes from.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

from kinectdata.core.errors import ConfigError
from kinectdata.evaluation.metrics.beat_alignment import SIGMA_S, SMOOTHING_S
from kinectdata.evaluation.metrics.foot_contact import PFC_FPS


@dataclass(frozen=True)
class Protocol:
    """How a peer computes its table.

    Attributes:
        name: the preset's name (``aist``, ``bailando``, ``edge``).
        reproduces: the peer code whose numbers this protocol gives.
        fps: frames per second of the features and motion beats (AIST++ motion: 60).
        zero_start: subtract each sequence's first-frame root position from every frame (Bailando).
        max_frames: frames kept from the start of each sequence for the features (None: all).
        bas_direction: ``music_to_motion`` (Bailando's code) or ``motion_to_music`` (AIST++ paper).
        bas_sigma_s: the Beat Align Score's Gaussian sigma, seconds.
        motion_beat_smoothing_s: sigma of the speed curve's smoothing, seconds.
        pfc_fps: frame rate of the PFC computation (EDGE: 30; the motion is resampled to it).
        peer_acceleration: the kinetic features keep the peers' acceleration slip.
        peer_velocity: the geometric features keep the peers' 1/120 s velocity scale.
    """

    name: str
    reproduces: str
    fps: float = 60.0
    zero_start: bool = False
    max_frames: int | None = None
    bas_direction: str = "music_to_motion"
    bas_sigma_s: float = SIGMA_S
    motion_beat_smoothing_s: float = SMOOTHING_S
    pfc_fps: float = PFC_FPS
    peer_acceleration: bool = True
    peer_velocity: bool = True

    def to_dict(self) -> dict:
        record = asdict(self)
        record["feature_normalisation"] = "both sets standardised by the reference set's mean and std (ddof 0) + 1e-10"
        record["fid_covariance"] = "np.cov, ddof 1"
        return record


PROTOCOLS: dict[str, Protocol] = {
    "aist": Protocol(
        name="aist",
        reproduces=(
            "AI Choreographer / AIST++ (Li et al. 2021): features of the AIST++ API on raw positions, FID as mint's "
            "tools/calculate_scores.py; Beat Align Score averaged over motion beats, as the paper defines it"
        ),
        bas_direction="motion_to_music",
    ),
    "bailando": Protocol(
        name="bailando",
        reproduces=(
            "Bailando (Li et al. 2022): utils/metrics_new.py (first root position at the origin, first 1200 frames, "
            "FID and Div on reference-standardised features) and utils/beat_align_score.py (averaged over music beats)"
        ),
        zero_start=True,
        max_frames=1200,
    ),
    "edge": Protocol(
        name="edge",
        reproduces=(
            "EDGE (Tseng et al. 2023): PFC as eval/eval_pfc.py (30 fps, z up); EDGE reports the other columns with "
            "Bailando's code, so they follow the bailando protocol"
        ),
        zero_start=True,
        max_frames=1200,
    ),
}


def get_protocol(name: str) -> Protocol:
    """A named protocol preset; ConfigError listing the presets for an unknown name."""
    try:
        return PROTOCOLS[name]
    except KeyError:
        raise ConfigError(f"unknown protocol {name!r}: choose one of {', '.join(PROTOCOLS)}") from None
