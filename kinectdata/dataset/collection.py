"""Finding recording sessions in a folder: a skeleton file and its audio, sharing a name.

A session is ``<name>.<skeleton extension>`` (``.csv``, ``.skeleton``, ``.htr``, ``.json``), or an
OpenPose output folder ``<name>_openpose/`` (or ``<name>/``) holding ``*_keypoints.json`` files,
with ``<name>.<audio extension>`` (``.wav``, ``.flac``, ``.ogg``, ``.mp3``) beside it and, for
synthetic sessions, ``<name>.truth.json`` with the ground truth.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from kinectdata.core.errors import KinectDataError

SKELETON_EXTENSIONS = (".csv", ".skeleton", ".htr", ".json")
AUDIO_EXTENSIONS = (".wav", ".flac", ".ogg", ".mp3")
OPENPOSE_FOLDER_SUFFIX = "_openpose"


@dataclass(frozen=True)
class Session:
    """One recording session: a skeleton file, its audio and optional ground truth."""

    name: str
    skeleton: Path
    audio: Path
    truth: Path | None = None

    def load_truth(self) -> dict[str, Any] | None:
        return None if self.truth is None else json.loads(self.truth.read_text())


def find_sessions(folder: str | Path) -> list[Session]:
    """The sessions in a folder, sorted by name; skeleton files without audio are skipped."""
    folder = Path(folder)
    if not folder.is_dir():
        raise KinectDataError(f"{folder}: not a folder")
    sessions = []
    for skeleton in sorted(folder.iterdir()):
        if skeleton.is_dir():
            if next(skeleton.glob("*_keypoints.json"), None) is None:
                continue
            name = skeleton.name.removesuffix(OPENPOSE_FOLDER_SUFFIX)
        elif skeleton.suffix.lower() not in SKELETON_EXTENSIONS or skeleton.name.endswith(".truth.json"):
            continue
        else:
            name = skeleton.stem
        audio = next((folder / f"{name}{ext}" for ext in AUDIO_EXTENSIONS if (folder / f"{name}{ext}").is_file()), None)
        if audio is None:
            continue
        truth = folder / f"{name}.truth.json"
        sessions.append(Session(name, skeleton, audio, truth if truth.is_file() else None))
    return sessions
