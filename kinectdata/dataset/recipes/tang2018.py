"""Dance with Melody (Tang, Jia, Mao, ACM MM 2018): ballroom dances with their songs.

What the recipe relies on (github.com/mhy12345/Music-to-Dance-Motion-Synthesis at commit 82ae014:
Readme.md, utils/draw.py, and the data, measured as docs/corpora.md tells):

- One folder per dance, ``DANCE_<style>_<n>/``, holding ``audio.mp3`` (the whole song),
  ``config.json`` (where the dance lies in the song) and ``skeletons.json`` (read by the
  ``tang2018`` reader, which places each frame on the song's clock). The style letter is the
  corpus's: C cha-cha, R rumba, T tango, W waltz (Readme.md names the four dances).
- A dance whose files are not all there (the public mirror lacks some blobs) is left out with
  the file that is missing; one whose ``config.json`` cannot be read, with what is wrong in it.
  A folder whose song is there but not its dance can give a labelled song (``songs``,
  ``labelled_songs=True``): its music, with the folder's style, teaches a build's music style
  classifier. Not by default: on the three folds the copy's 5 Latin ones cost the hearing a
  held-out song and 4 of 72 stretched ones (docs/notebook/2026-12-real-dance-variety.md).
- Motion and song share one clock: audio_time = motion_time + start_position / 25, the offset
  written for each dance.
- Metre: a waltz is in 3 (three beats to the bar), cha-cha, rumba and tango in 4; written as each
  dance's ``beats_per_bar``, which ``evaluate`` builds the metrical levels from and the
  ``listen_to_dance_rhythm_bars`` features count the bar by.

The corpus publishes no split. ``split="kinectdata"`` (the default) takes kinectdata's acceptance
split (:data:`KINECTDATA_SPLIT`: issue 25), which keeps each style in the test set;
``split=None`` leaves every dance to the build's draw.

The corpus has no licence: nothing of it is shipped; the recipe reads a local copy.
"""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

from kinectdata.core.errors import CorpusError, FormatError
from kinectdata.dataset.inputs import LabelledSong, RecordingEntry
from kinectdata.dataset.recipes.manifest import CorpusManifest, collected, relative
from kinectdata.formats.tang2018 import CONFIG, SONG_FPS, read_config

STYLES = {"C": ("cha-cha", 4), "R": ("rumba", 4), "T": ("tango", 4), "W": ("waltz", 3)}
"""The folder's style letter -> (the dance, beats per bar)."""
FILES = ("skeletons.json", CONFIG, "audio.mp3")
KINECTDATA_SPLIT = {
    "test": ("C_2", "C_4", "R_2", "R_3", "T_5", "W_1", "W_3"),
    "val": ("C_6", "R_4", "W_4"),
}
"""kinectdata's acceptance split (issue 25): these dances test and validate, every other complete
dance trains. Never train, tune or pick a checkpoint on the test dances."""
SPLITS = ("kinectdata", "none", None)
_FOLDER = re.compile(r"DANCE_([A-Z])_(\d+)")


def prepare_tang2018(
    path: str | Path, *, split: str | None = "kinectdata", labelled_songs: bool = False
) -> CorpusManifest:
    """A recordings manifest for a local copy of the Dance with Melody corpus.

    Args:
        path: the folder holding the ``DANCE_<style>_<n>/`` folders (the repository's root).
        split: ``"kinectdata"`` for :data:`KINECTDATA_SPLIT`, or ``"none"`` (None) to leave the split
            to the build.
        labelled_songs: list each folder with a song but no dance as a labelled song of its style.

    Returns:
        A :class:`CorpusManifest`: each complete dance as ``format: tang2018`` with its song, offset
        (its start in the song), style and beats per bar, named ``<style letter>_<n>`` (``W_1``);
        the incomplete ones left out with the file that is missing, and those whose ``config.json``
        cannot be read with what is wrong in it; with ``labelled_songs``, each folder with a song but
        no dance as a labelled song of its style.

    Raises:
        CorpusError: not a folder, no ``DANCE_*`` folder in it, or no dance complete.
    """
    path = Path(path)
    if split not in SPLITS:
        raise CorpusError(None, f"split {split!r}: the tang2018 recipe takes 'kinectdata' or 'none'")
    split = None if split == "none" else split
    if not path.is_dir():
        raise CorpusError(path, "not a folder")
    folders = [p for p in path.iterdir() if p.is_dir() and _FOLDER.fullmatch(p.name)]
    if not folders:
        raise CorpusError(path, "no DANCE_<style>_<n> folders: give the corpus's root folder")
    folders.sort(key=lambda p: (_FOLDER.fullmatch(p.name)[1], int(_FOLDER.fullmatch(p.name)[2])))
    assigned = {name: s for s, names in KINECTDATA_SPLIT.items() for name in names} if split else {}
    entries, skipped, songs = [], [], []
    for folder in folders:
        letter, number = _FOLDER.fullmatch(folder.name).groups()
        name = f"{letter}_{number}"
        missing = [f for f in FILES if not (folder / f).is_file() or (folder / f).stat().st_size == 0]
        if missing:
            song_only = "audio.mp3" not in missing and letter in STYLES
            if song_only and labelled_songs:
                songs.append(LabelledSong(name, relative(folder / "audio.mp3", path), STYLES[letter][0]))
            kept = ""
            if song_only:
                kept = "; its song is kept to hear the style by" if labelled_songs else "; its song alone is there"
            skipped.append((name, f"{folder.name}/{missing[0]} is missing or empty{kept}"))
            continue
        if letter not in STYLES:
            skipped.append((name, f"style letter {letter!r} is none of the corpus's ({', '.join(STYLES)})"))
            continue
        try:
            start, _ = read_config(folder / CONFIG)
        except FormatError as exc:
            skipped.append((name, exc.reason if exc.path is None else f"{folder.name}/{CONFIG}: {exc.reason}"))
            continue
        style, beats_per_bar = STYLES[letter]
        entries.append(
            RecordingEntry(
                name=name,
                recording=relative(folder / "skeletons.json", path),
                audio=relative(folder / "audio.mp3", path),
                split=assigned.get(name, "train") if split else None,
                offset=start / SONG_FPS,
                format="tang2018",
                style=style,
                beats_per_bar=beats_per_bar,
            )
        )
    description = (
        "Dance with Melody (Tang, Jia, Mao 2018): ballroom dances (cha-cha, rumba, tango, waltz) with their songs; "
        "23 points + center, cm, y up, each dance at its own rate (25 x frames / its span in song frames); "
        f"offset = start_position / 25 s; split: {split or 'drawn by the build'}"
    )
    found = collected("tang2018", path, path.resolve(), entries, skipped, description)
    # the pelvis's height drifts by tens of centimetres in most dances (a reconstruction artefact):
    # learn the body's shape about its root
    return replace(found, build_options=("--root-centre",), songs=tuple(songs))
