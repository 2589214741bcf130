"""FineDance (Li et al., ICCV 2023): SMPL-H motion of 14.6 hours of dance with its music.

What the recipe relies on (FineDance, github.com/li-ronghui/FineDance: README.md's data layout and
split description; dataset/FineDance_dataset.py ``get_train_test_list``, the published lists;
data/code/pre_motion.py):

- The data folder holds ``motion/<NNN>.npy`` (read by :mod:`kinectdata.formats.finedance`: root
  translation and SMPL-H rotations, 30 fps, metres, y up), ``music_wav/<NNN>.wav`` (the same
  names) and ``label_json/``. Pieces are numbered 001 to 211; a release may hold a part of them.
- Motion and music start together (offset 0 s); FineDance cuts both to the shorter.
- Two splits: ``cross_genre`` (FineDance@Genre: 20 test pieces across genres, no validation set)
  and ``cross_dancer`` (FineDance@Dancer: test and validation pieces by dancer). Each leaves out
  pieces the authors ignore; a piece in both a test list and the ignore list is left out.
- Positions need the SMPL-X rest joints ``smplx_neu_J_1.npy`` from FineDance's code repository
  (not its data download): found in the data folder or up to two folders above it (FineDance's
  code reads its data from ``data/finedance/``), or given.
"""

from __future__ import annotations

import os
from pathlib import Path

from kinectdata.core.errors import CorpusError
from kinectdata.dataset.inputs import RecordingEntry
from kinectdata.dataset.recipes.manifest import CorpusManifest, audio_beside, collected, relative

REST_JOINTS_FILE = "smplx_neu_J_1.npy"
SPLITS = {
    "cross_genre": {
        "test": "063 132 143 036 098 198 130 012 211 193 179 065 137 161 092 120 037 109 204 144",
        "val": "",
        "ignore": "116 117 118 119 120 121 122 123 202 130",
    },
    "cross_dancer": {
        "test": "001 002 003 004 005 006 007 008 009 010 011 012 013 124 126 128 130 132",
        "val": "115 117 119 121 122 135 137 139 141 143 145 147",
        "ignore": "116 118 120 123 202 159 130",
    },
}
"""FineDance's published lists (dataset/FineDance_dataset.py); every other piece is training."""


def prepare_finedance(
    path: str | Path, *, rest_joints: str | Path | None = None, split: str = "cross_genre"
) -> CorpusManifest:
    """A recordings manifest for a local copy of FineDance.

    Args:
        path: the data folder (``motion/``, ``music_wav/``).
        rest_joints: FineDance's ``smplx_neu_J_1.npy``; default found in ``path`` or up to two
            folders above it (the code repository, when the data lies in its ``data/finedance/``).
        split: ``cross_genre`` (FineDance@Genre) or ``cross_dancer`` (FineDance@Dancer).

    Returns:
        A :class:`CorpusManifest`: each piece as ``format: finedance`` with the rest joints, its
        music, its split and offset 0 s; the ignored pieces and those without music left out.

    Raises:
        CorpusError: no ``motion/*.npy``, no ``music_wav/``, no rest joints, or an unknown split.
    """
    path = Path(path)
    if split not in SPLITS:
        raise CorpusError(None, f"split {split!r}: FineDance publishes {' and '.join(SPLITS)}")
    pieces = sorted((path / "motion").glob("*.npy"))
    if not pieces:
        raise CorpusError(path, "no motion/*.npy: give FineDance's data folder (motion/, music_wav/)")
    music = path / "music_wav"
    if not music.is_dir():
        raise CorpusError(music, "no such folder: FineDance's music is music_wav/<NNN>.wav beside motion/")
    rest = _rest_joints(path, rest_joints)
    root = Path(os.path.commonpath([path.resolve(), rest.resolve()]))
    lists = {name: set(ids.split()) for name, ids in SPLITS[split].items()}
    entries, skipped = [], []
    for npy in pieces:
        name = npy.stem
        if name in lists["ignore"]:
            skipped.append((name, f"ignored by FineDance's {split} split"))
            continue
        audio = audio_beside(music, name)
        if audio is None:
            skipped.append((name, f"no music music_wav/{name}.wav"))
            continue
        entries.append(
            RecordingEntry(
                name=name,
                recording=relative(npy, root),
                audio=relative(audio, root),
                split="test" if name in lists["test"] else "val" if name in lists["val"] else "train",
                offset=0.0,
                format="finedance",
                rest_joints=relative(rest, root),
            )
        )
    description = (
        f"FineDance SMPL-H motion (30 fps, metres, y up) posed on {REST_JOINTS_FILE}; split {split}; offset 0 s"
    )
    return collected("finedance", path, root, entries, skipped, description)


def _rest_joints(path: Path, given: str | Path | None) -> Path:
    if given is not None:
        rest = Path(given)
        if not rest.is_file():
            raise CorpusError(rest, "no such rest-joints file")
        return rest
    for folder in (path, path.parent, path.parent.parent):
        if (folder / REST_JOINTS_FILE).is_file():
            return folder / REST_JOINTS_FILE
    raise CorpusError(
        path,
        f"no {REST_JOINTS_FILE} here or up to two folders above: FineDance's motion is rotations, posed on the SMPL-X "
        "rest joints from its code repository (github.com/li-ronghui/FineDance): give --rest-joints FILE",
    )
