"""A folder of BVH files with their music beside them (the Motorica dance set, studio exports).

Each ``<name>.bvh`` (in the folder or below it) pairs with the audio file of the same name in the
same folder (``.wav``, ``.flac``, ``.ogg``, ``.mp3``); a BVH with none is left out and reported. A
file below a folder named ``train``, ``val`` (or ``valid``, ``validation``) or ``test`` takes that
split; the others are drawn by the build. BVH does not state its unit: ``unit`` (centimetres by
default, as Motorica's and CMU's files are) is written into every entry, and ``kinectdata info``
says when a body looks 100 times too large or small. Corpora cut their motion to their music, so
the offset is 0 s unless ``offset="auto"`` asks the build to find it.
"""

from __future__ import annotations

from pathlib import Path

from kinectdata.core.errors import CorpusError
from kinectdata.dataset.inputs import RecordingEntry
from kinectdata.dataset.recipes.manifest import CorpusManifest, audio_beside, collected, recording_name, relative

SPLIT_FOLDERS = {"train": "train", "val": "val", "valid": "val", "validation": "val", "test": "test"}
BVH_UNITS = ("cm", "m", "mm", "in")


def prepare_bvh_folder(path: str | Path, *, unit: str = "cm", offset: float | str = 0.0) -> CorpusManifest:
    """A recordings manifest for the BVH files under ``path`` that have their music beside them.

    Args:
        path: the folder, searched recursively for ``*.bvh``.
        unit: the unit of the files' offsets and positions: ``cm``, ``m``, ``mm`` or ``in``.
        offset: seconds, audio_time = motion_time + offset, for every file; or ``"auto"``.

    Returns:
        A :class:`CorpusManifest` named by each file's path below ``path`` (``/`` becomes ``+``).

    Raises:
        CorpusError: not a folder, no BVH in it, or no BVH with its audio.
    """
    path = Path(path)
    if unit not in BVH_UNITS:
        raise CorpusError(None, f"unit {unit!r}: BVH units are {', '.join(BVH_UNITS)}")
    if not path.is_dir():
        raise CorpusError(path, "not a folder")
    files = sorted(path.rglob("*.bvh"), key=lambda p: p.relative_to(path).as_posix())
    if not files:
        raise CorpusError(path, "no .bvh files in this folder or below it")
    entries, skipped, names = [], [], set()
    for bvh in files:
        below = bvh.relative_to(path).with_suffix("")
        name = recording_name("+".join(below.parts))
        audio = audio_beside(bvh.parent, bvh.stem)
        if audio is None:
            skipped.append((name, f"no audio {bvh.stem}.wav/.flac/.ogg/.mp3 beside it"))
            continue
        while name in names:
            name += "_"
        names.add(name)
        split = next((SPLIT_FOLDERS[p.lower()] for p in below.parts[:-1] if p.lower() in SPLIT_FOLDERS), None)
        entries.append(
            RecordingEntry(
                name=name,
                recording=relative(bvh, path),
                audio=relative(audio, path),
                split=split,
                offset=offset,
                format="bvh",
                unit=unit,
            )
        )
    description = f"BVH files with their music beside them; unit {unit}; offset {offset}"
    return collected("bvh-folder", path, path.resolve(), entries, skipped, description)
