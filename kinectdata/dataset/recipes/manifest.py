"""What a corpus recipe returns: the recordings it found, the folder they are under, what it left out."""

from __future__ import annotations

import os
import re
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

from kinectdata.core.atomic import atomic_output
from kinectdata.core.errors import CorpusError
from kinectdata.dataset.collection import AUDIO_EXTENSIONS
from kinectdata.dataset.inputs import LabelledSong, RecordingEntry


@dataclass(frozen=True)
class CorpusManifest:
    """A corpus's recordings as a recordings manifest, with paths relative to ``root``.

    Attributes:
        corpus: the recipe's name (``aistpp``, ``finedance``, ``bvh-folder``).
        root: the absolute folder every recording and audio path is relative to.
        recordings: one entry per recording, with its split where the corpus publishes one.
        skipped: (name, why) for each file of the corpus left out (a published ignore list, no
            music, in no split).
        description: the corpus's facts the recipe relied on, written into the manifest.
        target: the target a dataset of the corpus is built with (``--target``): a generic one,
            since no shipped target spec is made for a corpus's own joints.
        build_options: other ``build-dataset`` options the corpus needs (e.g. ``--root-centre``
            where the body's place in the room drifts).
        songs: the corpus's songs whose style is known but whose dance is missing, paths relative to
            ``root``: they teach a build's music style classifier (written as ``songs``).
    """

    corpus: str
    root: Path
    recordings: tuple[RecordingEntry, ...]
    skipped: tuple[tuple[str, str], ...] = ()
    description: str = ""
    target: str = "positions"
    build_options: tuple[str, ...] = ()
    songs: tuple[LabelledSong, ...] = ()

    def split_counts(self) -> dict[str, int]:
        """Recordings per split (``unsplit`` for those the build will draw)."""
        counts = Counter(e.split or "unsplit" for e in self.recordings)
        return {k: counts[k] for k in ("train", "val", "test", "unsplit") if counts[k]}

    def to_dict(self, manifest_folder: str | Path) -> dict:
        """The manifest document, its ``root`` relative to ``manifest_folder`` when it lies inside it."""
        folder = Path(manifest_folder).resolve()
        root = self.root.resolve()
        root_text = os.path.relpath(root, folder) if root.is_relative_to(folder) else str(root)
        doc = {"corpus": self.corpus, "root": root_text}
        if self.description:
            doc["description"] = self.description
        doc["recordings"] = [e.to_dict() for e in self.recordings]
        if self.songs:
            doc["songs"] = [s.to_dict() for s in self.songs]
        return doc

    def write(self, path: str | Path) -> Path:
        """Write the manifest as YAML (``.yaml``/``.yml``) or JSON, atomically; its path."""
        import json

        import yaml

        path = Path(path)
        doc = self.to_dict(path.parent)
        with atomic_output(path) as tmp:
            if path.suffix.lower() in (".yaml", ".yml"):
                tmp.write_text(yaml.safe_dump(doc, sort_keys=False, allow_unicode=True, width=120), encoding="utf-8")
            else:
                tmp.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
        return path

    def root_outside(self, manifest_path: str | Path) -> bool:
        """Whether ``root`` lies outside the folder of a manifest written at ``manifest_path``: then
        building from it takes ``--allow-outside-paths``."""
        return not self.root.resolve().is_relative_to(Path(manifest_path).parent.resolve())


def collected(
    corpus: str,
    path: Path,
    root: Path,
    entries: list[RecordingEntry],
    skipped: list[tuple[str, str]],
    description: str,
) -> CorpusManifest:
    """The manifest of what a recipe found under ``path``; CorpusError when it listed nothing."""
    if not entries:
        why = skipped[0][1] if skipped else "none found"
        raise CorpusError(path, f"no recording could be listed ({len(skipped)} left out; the first: {why})")
    return CorpusManifest(corpus, root, tuple(entries), tuple(skipped), description)


def audio_beside(folder: Path, stem: str) -> Path | None:
    """``folder/<stem>.<ext>`` for the first audio extension kinectdata reads that exists, else None."""
    return next((folder / f"{stem}{ext}" for ext in AUDIO_EXTENSIONS if (folder / f"{stem}{ext}").is_file()), None)


_NOT_NAME = re.compile(r"[^A-Za-z0-9_.+-]")


def recording_name(text: str) -> str:
    """A dataset name for a recording: characters other than letters, digits and ``_ . + -`` become ``_``."""
    return _NOT_NAME.sub("_", text)


def relative(path: Path, root: Path) -> str:
    """``path`` relative to ``root``, with forward slashes (manifests travel between systems). Taken
    as the folders name it, symbolic links not followed: a corpus whose dances are links to another
    disk lists them under its root (the build then reads them with ``--allow-outside-paths``)."""
    return Path(os.path.relpath(os.path.abspath(path), os.path.abspath(root))).as_posix()
