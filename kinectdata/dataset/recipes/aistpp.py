"""AIST++ (Li et al. 2021, "AI Choreographer"): its 3-D keypoints with the AIST Dance DB music.

What the recipe relies on (the AIST++ API, github.com/google/aistplusplus_api: README.md's folder
layout, aist_plusplus/loader.py; the dataset's site, google.github.io/aistplusplus_dataset):

- The annotations folder holds ``keypoints3d/<sequence>.pkl`` (a pickled dict of ``keypoints3d``
  and ``keypoints3d_optim``, each [T, 17, 3] COCO keypoints, centimetres, y up, 60 fps),
  ``splits/<set>_{train,val,test}.txt`` (one sequence name per line; ``crossmodal`` is the split
  the music-to-dance papers use) and ``ignore_list.txt`` (sequences whose reconstruction failed).
- A sequence name reads ``g<genre>_s<situation>_c<camera>_d<dancer>_m<music>_ch<choreography>``, e.g.
  ``gBR_sBM_cAll_d04_mBR0_ch01``; its music is the AIST Dance DB's ``<music>`` file (``mBR0.wav``), a
  separate download. The videos were recorded to the music from its start, so motion and music
  share time zero (offset 0 s), as mint and Bailando read them.

The pickles are read with kinectdata's restricted unpickler (numpy arrays and plain containers
only); the keypoints through the shipped array schema ``aistpp_keypoints3d`` (or ``..._optim``),
joint set ``coco17_tree`` (COCO-17 plus the pelvis and thorax midpoints). AIST++'s SMPL motions
(``motions/``) need the SMPL body model, which kinectdata cannot ship, and are not read.
"""

from __future__ import annotations

import os
from pathlib import Path

from kinectdata.core.errors import CorpusError
from kinectdata.dataset.inputs import RecordingEntry
from kinectdata.dataset.recipes.manifest import CorpusManifest, audio_beside, collected, relative

KEYPOINTS = ("keypoints3d", "keypoints3d_optim")
MUSIC_FOLDERS = ("music", "all_musics", "wav", "../music", "../all_musics", "../wav")
"""Where the music is looked for, relative to the annotations folder, when no folder is given."""
FPS = 60.0


def prepare_aistpp(
    path: str | Path,
    *,
    music: str | Path | None = None,
    keypoints: str = "keypoints3d",
    split_set: str = "crossmodal",
    include_unsplit: bool = False,
) -> CorpusManifest:
    """A recordings manifest for a local copy of AIST++.

    Args:
        path: the annotations folder (``keypoints3d/``, ``splits/``, ``ignore_list.txt``).
        music: the folder of the AIST Dance DB music (``mBR0.wav``...); default the first of
            :data:`MUSIC_FOLDERS` that exists.
        keypoints: ``keypoints3d`` or ``keypoints3d_optim`` (AIST++'s bundle-adjusted keypoints).
        split_set: the published split to use (``splits/<split_set>_train.txt``...).
        include_unsplit: keep the sequences in none of the split's lists, with no split (the build
            draws them); by default they are left out, as the papers leave them out.

    Returns:
        A :class:`CorpusManifest`: each sequence read as ``format: arrays`` with the schema
        ``aistpp_<keypoints>``, its music, its published split and offset 0 s; the sequences left out
        with the reason (in the ignore list, in no split, its music missing).

    Raises:
        CorpusError: the folder has no ``keypoints3d/``, no music folder is found, a split list is
            missing, or no sequence has its music.
    """
    path = Path(path)
    if keypoints not in KEYPOINTS:
        raise CorpusError(None, f"keypoints {keypoints!r}: AIST++ has {' or '.join(KEYPOINTS)}")
    sequences = sorted((path / "keypoints3d").glob("*.pkl"))
    if not sequences:
        raise CorpusError(path, "no keypoints3d/*.pkl: give AIST++'s annotations folder (keypoints3d/, splits/)")
    music_dir = _music_folder(path, music)
    splits = _published_splits(path, split_set)
    ignored = _ignore_list(path)
    root = Path(os.path.commonpath([path.resolve(), music_dir.resolve()]))
    entries, skipped = [], []
    for pkl in sequences:
        name = pkl.stem
        if name in ignored:
            skipped.append((name, "in ignore_list.txt (its reconstruction failed)"))
            continue
        split = splits.get(name)
        if split is None and splits and not include_unsplit:
            skipped.append((name, f"in none of the {split_set} split's lists"))
            continue
        music_id = _music_id(name)
        if music_id is None:
            skipped.append((name, "not an AIST++ sequence name (g.._s.._c.._d.._m.._ch..)"))
            continue
        audio = audio_beside(music_dir, music_id)
        if audio is None:
            skipped.append((name, f"no music {music_id} in {music_dir}"))
            continue
        entries.append(
            RecordingEntry(
                name=name,
                recording=relative(pkl, root),
                audio=relative(audio, root),
                split=split,
                offset=0.0,
                format="arrays",
                schema=f"aistpp_{keypoints}",
            )
        )
    description = (
        f"AIST++ {keypoints} (COCO-17 keypoints, cm, y up, {FPS:g} fps) with the AIST Dance DB music; "
        f"splits: {split_set}; offset 0 s (the videos start with their music)"
    )
    return collected("aistpp", path, root, entries, skipped, description)


def _music_folder(path: Path, music: str | Path | None) -> Path:
    if music is not None:
        folder = Path(music)
        if not folder.is_dir():
            raise CorpusError(folder, "no such music folder")
        return folder
    for candidate in MUSIC_FOLDERS:
        folder = (path / candidate).resolve()
        if folder.is_dir():
            return folder
    raise CorpusError(
        path,
        f"no music folder ({', '.join(MUSIC_FOLDERS)} beside keypoints3d/): give the AIST Dance DB music's "
        "folder (--music DIR, holding mBR0.wav ...)",
    )


def _published_splits(path: Path, split_set: str) -> dict[str, str]:
    """Sequence name -> train/val/test from ``splits/<split_set>_<split>.txt``; {} with no splits folder."""
    folder = path / "splits"
    if not folder.is_dir():
        return {}
    splits: dict[str, str] = {}
    for split in ("train", "val", "test"):
        listing = folder / f"{split_set}_{split}.txt"
        if not listing.is_file():
            known = sorted({p.stem.rsplit("_", 1)[0] for p in folder.glob("*_*.txt")})
            raise CorpusError(listing, f"no such split list (split sets here: {', '.join(known) or 'none'})")
        for line in listing.read_text(encoding="utf-8").split():
            splits[line.strip()] = split
    return splits


def _ignore_list(path: Path) -> set[str]:
    listing = path / "ignore_list.txt"
    return set(listing.read_text(encoding="utf-8").split()) if listing.is_file() else set()


def _music_id(name: str) -> str | None:
    """The music of an AIST++ sequence name (its fifth field, ``m`` + genre + number), or None."""
    parts = name.split("_")
    if len(parts) == 6 and parts[4].startswith("m") and len(parts[4]) >= 3:
        return parts[4]
    return None
