"""Small local copies made in the shape of real dance corpora, for the recipe tests and the docs.

No corpus data: the motion is the bundled synthetic dancer (``sample_data``) or a made-up body,
rearranged the way each corpus lays out its files (facts from the corpora's own documentation, named
in ``kinectdata/dataset/recipes``), with the bundled synthetic music.
"""

from __future__ import annotations

import functools
import io
import json
import math
import pickle
import shutil
from dataclasses import dataclass
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


# -- Dance with Melody (tang2018) ---------------------------------------------------------------------

TANG2018_BODY_CM = np.array(
    [
        (0.0, 62.0, -8.0),  # 0 the back of the head
        (0.0, 61.0, 10.0),  # 1 its front
        (0.0, 15.0, -1.0),  # 2 spine
        (-18.0, 45.0, 0.0),  # 3-6 right shoulder, elbow, wrist, hand
        (-42.0, 38.0, 6.0),
        (-47.0, 44.0, 29.0),
        (-47.0, 45.0, 37.0),
        (-10.0, 0.0, 0.0),  # 7-11 right hip, knee, ankle, heel, toe
        (-11.0, -47.0, 4.0),
        (-11.0, -83.0, -2.0),
        (-11.0, -89.0, -9.0),
        (-11.0, -91.0, 14.0),
        (18.0, 45.0, 0.0),  # 12-15 left shoulder, elbow, wrist, hand
        (41.0, 50.0, -1.0),
        (43.0, 68.0, 9.0),
        (43.0, 76.0, 12.0),
        (10.0, 0.0, 0.0),  # 16-20 left hip, knee, ankle, heel, toe
        (11.0, -47.0, 4.0),
        (11.0, -83.0, -2.0),
        (11.0, -89.0, -9.0),
        (11.0, -91.0, 14.0),
        (46.0, 66.0, 13.0),  # 21 beside the left wrist
        (-49.0, 43.0, 33.0),  # 22 beside the right hand
    ]
)
"""A made-up ballroom dancer's 23 points about the pelvis, in centimetres, y up, facing +z (its left
at +x), in the corpus's order (tang2018 joint set): a person's proportions, no corpus values."""


def tang2018_dance(frames: int, seed: int = 0) -> dict:
    """A ``skeletons.json`` document of ``frames`` frames of the made-up dancer: turning about y, the
    legs stepping in turn, the pelvis (``center``, cm) bobbing and drifting round the room; each point
    given relative to ``center`` as the corpus gives it."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames) / 25.0
    beat = rng.uniform(1.6, 2.2)  # steps per second
    step = 12.0 * np.sin(2 * np.pi * beat / 2 * t + rng.uniform(0, 2 * np.pi))
    body = np.broadcast_to(TANG2018_BODY_CM, (frames, 23, 3)).copy()
    for leg, sign in (((8, 9, 10, 11), 1.0), ((17, 18, 19, 20), -1.0)):
        body[:, leg, 2] += sign * step[:, None] * np.array([0.5, 1.0, 1.0, 1.0])
    body[:, (5, 6, 14, 15, 21, 22), 1] += 3.0 * np.sin(2 * np.pi * 0.5 * t)[:, None]
    body += rng.normal(0.0, 0.3, body.shape)
    turn = rng.uniform(-0.8, 0.8) * t + rng.uniform(0, 2 * np.pi)  # radians about y
    c, s = np.cos(turn)[:, None], np.sin(turn)[:, None]
    points = np.stack([c * body[..., 0] + s * body[..., 2], body[..., 1], -s * body[..., 0] + c * body[..., 2]], -1)
    radius = rng.uniform(50.0, 150.0)
    center = np.stack(
        [
            radius * np.sin(0.3 * t) + rng.uniform(-100, 100),
            95.0 + 3.0 * np.sin(2 * np.pi * beat * t) + 10.0 * t / max(t[-1], 1.0),  # the height drifts
            radius * np.cos(0.3 * t) + rng.uniform(-100, 100),
        ],
        axis=1,
    )
    return {"length": frames, "center": center.tolist(), "skeletons": points.tolist()}


@dataclass(frozen=True)
class MadeDance:
    """A dance folder of the made copy: where the dance starts in its song (song frames at 25 per
    second), how many song frames more than motion frames it spans (its rate is 25 T / (T + extra)),
    the music it is cut from, and the files the mirror lacks (absent) or holds empty."""

    start: int
    extra: int
    music: str = "synth_001"
    absent: tuple[str, ...] = ()
    empty: tuple[str, ...] = ()

    @property
    def complete(self) -> bool:
        return not self.absent and not self.empty


TANG2018_DANCES = {
    "C_1": MadeDance(30, 2, absent=("skeletons.json",)),
    "C_2": MadeDance(40, 3, "synth_001"),
    "C_4": MadeDance(12, 1, "synth_002"),
    "C_6": MadeDance(5, 2, "synth_003"),
    "C_7": MadeDance(60, 4, "synth_001"),
    "C_9": MadeDance(7, 2, absent=("audio.mp3",)),
    "R_2": MadeDance(8, 1, "synth_002"),
    "R_3": MadeDance(20, 3, "synth_003"),
    "R_4": MadeDance(50, 4, "synth_001"),
    "R_5": MadeDance(17, 2, "synth_002"),
    "R_6": MadeDance(0, 1, absent=("skeletons.json",)),
    "T_1": MadeDance(0, 2, absent=("skeletons.json", "audio.mp3")),
    "T_5": MadeDance(0, 5, "synth_003"),
    "W_1": MadeDance(0, 1, "synth_001"),
    "W_2": MadeDance(25, 2, absent=("audio.mp3",)),
    "W_3": MadeDance(52, 2, "synth_002"),
    "W_4": MadeDance(33, 3, "synth_003"),
    "W_5": MadeDance(0, 1, "synth_001"),
    "W_6": MadeDance(3, 2, "synth_002"),
    "W_9": MadeDance(10, 1, empty=("audio.mp3",)),
    "W_13": MadeDance(4, 2, empty=("skeletons.json",)),
}
"""The made copy's dances (``DANCE_<name>``): 14 complete, of each style letter, in the acceptance
split's test (C_2, C_4, R_2, R_3, T_5, W_1, W_3), validation (C_6, R_4, W_4) and training sets; the
others lack a file, as the public mirror lacks some blobs, or hold one empty."""


def write_tang2018_dance(folder: Path, dance: MadeDance, frames: int, seed: int) -> None:
    """One ``DANCE_<style>_<n>/`` folder: config.json, skeletons.json, audio.mp3 (the sample's music
    from its start, long enough to hold the dance's span and a second more, in whole steps of
    :data:`AUDIO_STEP_S`), less what is absent."""
    folder.mkdir(parents=True, exist_ok=True)
    end = dance.start + frames + dance.extra
    files = {
        "config.json": lambda p: p.write_text(json.dumps({"start_position": dance.start, "end_position": end})),
        "skeletons.json": lambda p: p.write_text(json.dumps(tang2018_dance(frames, seed))),
        "audio.mp3": lambda p: _write_mp3(p, dance.music, AUDIO_STEP_S * math.ceil((end / 25.0 + 1.0) / AUDIO_STEP_S)),
    }
    for name, write in files.items():
        if name in dance.empty:
            (folder / name).write_bytes(b"")
        elif name not in dance.absent:
            write(folder / name)


AUDIO_STEP_S = 4.0
"""The copies' songs are cut to multiples of 4 s, so that dances of one sample share an encoding."""


def _write_mp3(path: Path, sample: str, seconds: float) -> None:
    path.write_bytes(_mp3_bytes(sample, seconds))


@functools.cache
def _mp3_bytes(sample: str, seconds: float) -> bytes:
    """The sample's music cut to ``seconds``, as MP3 (encoded once per test process: LAME takes
    about 0.4 s a song, and the copies repeat their songs)."""
    audio, rate = soundfile.read(SAMPLES / f"{sample}.flac")
    encoded = io.BytesIO()
    soundfile.write(encoded, audio[: int(seconds * rate)], rate, format="MP3", subtype="MPEG_LAYER_III")
    return encoded.getvalue()


def make_tang2018_copy(where: Path, seconds: float = 4.0, dances: dict[str, MadeDance] | None = None) -> Path:
    """A Dance with Melody-shaped copy: ``Music-to-Dance-Motion-Synthesis/`` (its repository's root)
    with a Readme.md, utils/ and ``DANCE_<style>_<n>/`` folders (:data:`TANG2018_DANCES`), each
    dance ``seconds`` long at 25 frames a second of motion. Returns the root."""
    root = where / "Music-to-Dance-Motion-Synthesis"
    (root / "utils").mkdir(parents=True)
    (root / "Readme.md").write_text("# Dataset\n\nA small copy made in the corpus's shape for kinectdata's tests.\n")
    (root / "utils" / "draw.py").write_text("# the corpus draws its skeletons here\n")
    frames = int(round(seconds * 25))
    for k, (name, dance) in enumerate((dances or TANG2018_DANCES).items()):
        write_tang2018_dance(root / f"DANCE_{name}", dance, frames, seed=k)
    return root
