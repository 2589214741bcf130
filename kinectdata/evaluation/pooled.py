"""Beat following pooled over several runs, each on its own held-out recordings: the reading of
cross-validation folds (``kinectdata folds``), where each fold's model is scored on the recordings
it did not train on, and the verdicts need all of them together to reach significance.

Each run generates its split's songs free from their first true pose, as ``evaluate`` does; the
generated and the real motions of every run's songs are then read as one set by
:func:`~kinectdata.evaluation.beat_following.beat_following` (dominant periods, metrical levels,
tempo rank correlation, bar repetition, with chance levels from pairings across all the songs).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from kinectdata.core.errors import KinectDataError
from kinectdata.evaluation.beat_following import BeatFollowing, RecordingBeats, beat_following
from kinectdata.evaluation.evaluate import split_songs
from kinectdata.evaluation.metrics.pose_error import motion_energy_per_s
from kinectdata.models.run import load_model


@dataclass(frozen=True)
class PooledFollowing:
    """Beat following of every run's held-out songs read together.

    Attributes:
        generated: the models' motion (each song by the run that did not train on it).
        real: the recorded motion of the same songs.
        runs: per song name, the run that danced it.
        energy_ratios: per song name, the generated motion's energy over the real motion's.
    """

    generated: BeatFollowing
    real: BeatFollowing
    runs: dict[str, str]
    energy_ratios: dict[str, float]


def held_out_following(
    runs: Sequence[tuple[str | Path, str | Path]],
    split: str = "val",
    *,
    draws: int = 200,
    seed: int = 0,
    checksums: bool = True,
    draw_seed: int = 0,
) -> PooledFollowing:
    """Generate each run's ``split`` songs from its dataset and read all of them together.

    Args:
        runs: (run folder, dataset folder) pairs, e.g. one per fold.
        split: the split each run is scored on (a fold's held-out recordings: ``val``).
        draws: chance draws per recording.
        seed: the chance draws' seed.
        checksums: verify each dataset's shards first.
        draw_seed: the seed of the turning and travel drawn in each free run (``evaluate``'s).

    Raises:
        KinectDataError: no run, a run or dataset that cannot be read, a split with no song, or a
            song name held out by two runs.
    """
    if not runs:
        raise KinectDataError("pooled beat following needs at least one (run, dataset) pair")
    generated, real, danced_by, energy = [], [], {}, {}
    for run, dataset in runs:
        net, config = load_model(run)
        net.eval()
        songs = split_songs(net, config, dataset, split, checksums=checksums, draw_seed=draw_seed)
        if not songs.songs:
            raise KinectDataError(f"{dataset}: its {split} split has no song to score")
        motions = songs.generate_many([(s.features, s.first_pose) for s in songs.songs])
        for song, motion in zip(songs.songs, motions):
            if song.name in danced_by:
                raise KinectDataError(f"{song.name} is held out by both {danced_by[song.name]} and {run}")
            danced_by[song.name] = str(run)
            generated.append(RecordingBeats(song.name, motion, None, song.fps, song.beats_s, first_frame=1,
                                            beats_per_bar=song.beats_per_bar))  # fmt: skip
            real.append(RecordingBeats(song.name, song.real_positions, song.real_mask, song.fps, song.beats_s,
                                       beats_per_bar=song.beats_per_bar))  # fmt: skip
            energy[song.name] = motion_energy_per_s(motion, None, song.fps) / motion_energy_per_s(
                song.real_positions, song.real_mask, song.fps
            )
    return PooledFollowing(
        generated=beat_following(generated, draws=draws, seed=seed),
        real=beat_following(real, draws=draws, seed=seed),
        runs=danced_by,
        energy_ratios=energy,
    )
