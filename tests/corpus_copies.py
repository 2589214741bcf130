"""Small local copies made in the shape of real dance corpora, for the recipe tests and the docs.

No corpus data: the motion is the bundled synthetic dancer (``sample_data``), rearranged the way
each corpus lays out its files (facts from the corpora's own documentation, named in
``kinectdata/dataset/recipes``), with the bundled synthetic music.
"""

from __future__ import annotations

import pickle
import shutil
from pathlib import Path

import numpy as np
import soundfile

from kinectdata.formats import read_motion
from kinectdata.formats.bvh_writer import write_bvh

REPO = Path(__file__).resolve().parents[1]
SAMPLES = REPO / "sample_data"

COCO_FROM_KINECT = {
    "nose": ("Head", (0.0, -0.02, 0.08)),
    "left_eye": ("Head", (0.03, 0.01, 0.07)),
    "right_eye": ("Head", (-0.03, 0.01, 0.07)),
    "left_ear": ("Head", (0.07, 0.0, 0.0)),
    "right_ear": ("Head", (-0.07, 0.0, 0.0)),
    "left_shoulder": ("ShoulderLeft", (0, 0, 0)),
    "right_shoulder": ("ShoulderRight", (0, 0, 0)),
    "left_elbow": ("ElbowLeft", (0, 0, 0)),
    "right_elbow": ("ElbowRight", (0, 0, 0)),
    "left_wrist": ("WristLeft", (0, 0, 0)),
    "right_wrist": ("WristRight", (0, 0, 0)),
    "left_hip": ("HipLeft", (0, 0, 0)),
    "right_hip": ("HipRight", (0, 0, 0)),
    "left_knee": ("KneeLeft", (0, 0, 0)),
    "right_knee": ("KneeRight", (0, 0, 0)),
    "left_ankle": ("AnkleLeft", (0, 0, 0)),
    "right_ankle": ("AnkleRight", (0, 0, 0)),
}
"""COCO-17, in COCO's order, from the synthetic Kinect v2 dancer: (joint, offset in metres)."""

AISTPP_SEQUENCES = {
    "gBR_sBM_cAll_d04_mBR0_ch01": ("synth_001", 0.0, "train"),
    "gBR_sBM_cAll_d04_mBR1_ch02": ("synth_002", 0.0, "train"),
    "gPO_sBM_cAll_d10_mPO1_ch02": ("synth_003", 0.0, "val"),
    "gJB_sFM_cAll_d09_mJB2_ch03": ("synth_001", 8.0, "test"),
    "gLH_sBM_cAll_d16_mLH0_ch01": ("synth_002", 8.0, "ignored"),
    "gMH_sBM_cAll_d22_mMH3_ch04": ("synth_003", 8.0, None),
}
"""Sequence name -> (the sample it is made from, where in it (s), its crossmodal split; ``ignored``
is in ignore_list.txt). The music is the sample's from that time on."""


def coco_keypoints_m(sample: str, start: float = 0.0, seconds: float | None = None) -> np.ndarray:
    """[T, 17, 3] COCO keypoints in metres, y up, from a bundled sample's frames from ``start`` s on
    (NaN where untracked), taken as frames 1/60 s apart."""
    motion = read_motion(SAMPLES / f"{sample}.csv")
    positions = np.where(motion.position_mask[..., None], motion.positions, np.nan)
    positions = positions[motion.times >= motion.times[0] + start]
    if seconds is not None:
        positions = positions[: int(seconds * 60)]
    index = motion.joint_set.index
    return np.stack([positions[:, index(j)] + offset for j, offset in COCO_FROM_KINECT.values()], axis=1)


def make_aistpp_copy(where: Path, seconds: float | None = 6.0) -> Path:
    """An AIST++-shaped copy under ``where``: ``aist_plusplus_final/`` (keypoints3d/*.pkl in cm with
    ``keypoints3d`` and ``keypoints3d_optim``, splits/crossmodal_*.txt, ignore_list.txt) and
    ``aist_plusplus_final/music/`` (m<genre><n>.flac). Returns the annotations folder."""
    annotations = where / "aist_plusplus_final"
    (annotations / "keypoints3d").mkdir(parents=True)
    (annotations / "splits").mkdir()
    (annotations / "music").mkdir()
    splits: dict[str, list[str]] = {"train": [], "val": [], "test": []}
    for name, (sample, start, split) in AISTPP_SEQUENCES.items():
        keypoints = coco_keypoints_m(sample, start, seconds) * 100.0
        with open(annotations / "keypoints3d" / f"{name}.pkl", "wb") as f:
            pickle.dump(
                {"keypoints3d": keypoints, "keypoints3d_optim": keypoints + 0.5}, f, protocol=pickle.HIGHEST_PROTOCOL
            )
        audio, rate = soundfile.read(SAMPLES / f"{sample}.flac")
        soundfile.write(annotations / "music" / f"{name.split('_')[4]}.flac", audio[int(start * rate) :], rate)
        if split in splits:
            splits[split].append(name)
    for split, names in splits.items():
        (annotations / "splits" / f"crossmodal_{split}.txt").write_text("\n".join(names) + "\n")
    ignored = [n for n, (*_, split) in AISTPP_SEQUENCES.items() if split == "ignored"]
    (annotations / "ignore_list.txt").write_text("\n".join(ignored) + "\n")
    return annotations


BVH_FILES = {
    "train/salsa_01": "synth_001",
    "train/salsa_02": "synth_002",
    "test/salsa_03": "synth_003",
    "warmup": None,
}
"""A BVH folder: the path below it (no suffix) -> the sample whose music lies beside (None: no music)."""


def make_bvh_folder(where: Path, seconds: float = 6.0) -> Path:
    """A folder of BVH files (centimetres) from the bundled dancer, each with its music beside it
    but one (``warmup.bvh``); train/ and test/ subfolders. Returns the folder."""
    folder = where / "bvh_corpus"
    motion = read_motion(SAMPLES / "synth_001.csv")
    frames = int(seconds * 30)
    for below, sample in BVH_FILES.items():
        path = folder / f"{below}.bvh"
        path.parent.mkdir(parents=True, exist_ok=True)
        take = read_motion(SAMPLES / f"{sample or 'synth_001'}.csv") if sample else motion
        write_bvh(take.select(slice(0, frames)), path)
        if sample:
            shutil.copyfile(SAMPLES / f"{sample}.flac", path.with_suffix(".flac"))
    return folder


def made_up_rest_joints() -> np.ndarray:
    """[55, 3] rest joints in metres in SMPL-X's order (y up, facing +z, left at +x): a made-up body of
    a person's proportions, not SMPL-X's (whose model kinectdata cannot ship)."""
    body = [
        (0, 0.95, 0),
        (0.08, 0.87, 0),
        (-0.08, 0.87, 0),
        (0, 1.05, -0.01),
        (0.09, 0.50, 0.01),
        (-0.09, 0.50, 0.01),
        (0, 1.18, 0),
        (0.09, 0.08, -0.02),
        (-0.09, 0.08, -0.02),
        (0, 1.23, 0.01),
        (0.10, 0.02, 0.11),
        (-0.10, 0.02, 0.11),
        (0, 1.45, -0.01),
        (0.07, 1.38, 0),
        (-0.07, 1.38, 0),
        (0, 1.60, 0.03),
        (0.18, 1.40, -0.01),
        (-0.18, 1.40, -0.01),
        (0.44, 1.40, -0.02),
        (-0.44, 1.40, -0.02),
        (0.68, 1.40, -0.01),
        (-0.68, 1.40, -0.01),
        (0, 1.55, 0.06),
        (0.03, 1.65, 0.08),
        (-0.03, 1.65, 0.08),
    ]
    fingers = []
    for side in (1.0, -1.0):
        for z in (0.03, 0.0, -0.04, -0.02):  # index, middle, pinky, ring
            fingers += [(side * x, 1.40, z) for x in (0.78, 0.81, 0.83)]
        fingers += [(side * 0.72, 1.39, 0.04), (side * 0.74, 1.39, 0.06), (side * 0.76, 1.39, 0.08)]  # thumb
    return np.array(body + fingers, dtype=np.float32)


def finedance_motion(seconds: float, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A FineDance-shaped [T, 315] motion at 30 fps (smooth swings of every joint, a turning root
    walking a circle), with the translation [T, 3] and local rotation matrices [T, 52, 3, 3] it holds."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * 30)) / 30.0
    axes = rng.normal(size=(52, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    amplitude = rng.uniform(0.1, 0.5, size=52)
    phase = rng.uniform(0, 2 * np.pi, size=52)
    angles = amplitude * np.sin(2 * np.pi * 1.0 * t[:, None] + phase)  # [T, 52]
    rotvec = angles[..., None] * axes
    rotvec[:, 0] = np.array([0.0, 1.0, 0.0]) * (0.8 * t)[:, None]  # the root turns about y
    local = Rotation.from_rotvec(rotvec.reshape(-1, 3)).as_matrix().reshape(len(t), 52, 3, 3)
    translation = np.stack([0.5 * np.sin(0.8 * t), 0.02 * np.sin(4 * np.pi * t), 0.5 * np.cos(0.8 * t)], axis=1)
    six = local[:, :, :2, :].reshape(len(t), 52 * 6)
    return np.concatenate([translation, six], axis=1).astype(np.float32), translation, local


FINEDANCE_PIECES = {"001": "synth_001", "002": "synth_002", "063": "synth_003", "116": "synth_001", "005": None}
"""Piece -> the sample whose music is its music_wav (None: no music). 063 is a cross_genre test
piece; 116 is ignored by both splits; 001, 002 and 005 are training pieces."""


def make_finedance_copy(where: Path, seconds: float = 6.0) -> Path:
    """A FineDance-shaped copy: ``FineDance/`` (its code repository, holding the rest joints
    ``smplx_neu_J_1.npy``, made up here) with ``data/finedance/`` (motion/*.npy, music_wav/*.wav).
    Returns the data folder."""
    repo = where / "FineDance"
    data = repo / "data" / "finedance"
    (data / "motion").mkdir(parents=True)
    (data / "music_wav").mkdir()
    np.save(repo / "smplx_neu_J_1.npy", made_up_rest_joints())
    for k, (piece, sample) in enumerate(FINEDANCE_PIECES.items()):
        np.save(data / "motion" / f"{piece}.npy", finedance_motion(seconds, seed=k)[0])
        if sample:
            audio, rate = soundfile.read(SAMPLES / f"{sample}.flac")
            soundfile.write(data / "music_wav" / f"{piece}.wav", audio, rate)
    return data
