"""Where live audio comes from: an input device (PortAudio through sounddevice, as ``capture``
records), or an audio file played at real-time pace (to the speakers too, if asked).

A source yields :class:`AudioBlock` s: mono float32 samples at the run's rate, each stamped with
the clock time its last sample was heard, which is where a frame's latency is counted from.
"""

from __future__ import annotations

import queue
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kinectdata.align.audio import AudioReader
from kinectdata.core.errors import KinectDataError

FALL_BEHIND_S = 0.05
"""A file source read this far behind its real-time pace counts an overrun: an input device's buffer
(PortAudio's default high latency is of that order) would have overflowed."""
DEVICE_SILENCE_S = 2.0
"""An input device that delivers nothing for this long has gone away: the session ends."""


@dataclass(frozen=True)
class AudioBlock:
    """Consecutive samples of the live audio.

    Attributes:
        samples: [n] float32 mono at the session's rate.
        heard_s: clock time (seconds) at which the block's last sample was heard.
        overrun: samples were lost before this block (the device's buffer overflowed), or the
            session fell behind a file's real-time pace by more than :data:`FALL_BEHIND_S`.
    """

    samples: np.ndarray
    heard_s: float
    overrun: bool = False


class FileSource:
    """An audio file played at real-time pace on ``clock``: block i is yielded when its last
    sample would have been heard, ``start + (samples so far) / rate``.

    Args:
        path: any file libsndfile (or the MP3 decoder) reads.
        sample_rate: Hz of the blocks (the run's).
        block: samples per block (160 at 16 kHz: 10 ms).
        clock: :mod:`~kinectdata.live.clock`.
        play: also play the file on the default output device (sounddevice), from the start.
    """

    def __init__(self, path: str | Path, sample_rate: int, block: int, clock, *, play: bool = False):
        self.path, self.rate, self.block, self.clock, self.play = Path(path), sample_rate, block, clock, play
        self.reader = AudioReader(path, sample_rate)
        self.name = f"the file {self.path.name}"

    def blocks(self) -> Iterator[AudioBlock]:
        samples = np.concatenate([np.zeros(0, np.float32), *self.reader.blocks()])
        if self.play:
            _play(samples, self.rate)
        start = self.clock.now()
        behind = False
        for first in range(0, samples.size, self.block):
            chunk = samples[first : first + self.block]
            due = start + (first + chunk.size) / self.rate
            late = self.clock.now() - due > max(self.block / self.rate, FALL_BEHIND_S)  # behind the music
            self.clock.sleep_until(due)
            yield AudioBlock(chunk, due, overrun=late and not behind)
            behind = late

    def close(self) -> None:
        if self.play:
            import sounddevice

            sounddevice.stop()


class DeviceSource:
    """An input device through PortAudio (sounddevice): blocks as the device delivers them,
    stamped on ``clock`` when they arrive.

    Args:
        device: a sounddevice device name or index; None: the default input.
        sample_rate: Hz (the run's; PortAudio converts when the device runs at another rate).
        block: samples per block.
        clock: :mod:`~kinectdata.live.clock` (the monotonic clock).
    """

    def __init__(self, device: str | int | None, sample_rate: int, block: int, clock):
        self.device, self.rate, self.block, self.clock = device, sample_rate, block, clock
        self.name = "the default input device" if device is None else f"the input device {device!r}"
        self.stream = None

    def blocks(self) -> Iterator[AudioBlock]:
        sd = _sounddevice()
        arrived: queue.Queue = queue.Queue()

        def callback(indata, frames, time_info, status) -> None:
            arrived.put((indata[:, 0].copy(), self.clock.now(), bool(status.input_overflow)))

        try:
            self.stream = sd.InputStream(
                device=self.device,
                channels=1,
                samplerate=self.rate,
                blocksize=self.block,
                dtype="float32",
                callback=callback,
            )
            self.stream.start()
        except (sd.PortAudioError, ValueError) as exc:
            raise KinectDataError(f"{self.name} cannot be opened at {self.rate} Hz ({exc})") from None
        while True:
            try:
                samples, heard, overflow = arrived.get(timeout=DEVICE_SILENCE_S)
            except queue.Empty:
                raise KinectDataError(
                    f"{self.name} delivered no audio for {DEVICE_SILENCE_S:g} s: was it unplugged?"
                ) from None
            yield AudioBlock(samples, heard, overflow)

    def close(self) -> None:
        if self.stream is not None:
            self.stream.stop()
            self.stream.close()
            self.stream = None


def open_source(given: str | None, sample_rate: int, block: int, clock, *, play: bool = False):
    """The source ``--input`` names: an existing audio file (played at real-time pace), else an
    input device by name or index; None: the default input device."""
    if given is not None and Path(given).is_file():
        return FileSource(given, sample_rate, block, clock, play=play)
    if play:
        raise KinectDataError("--play plays an input file; a device's sound is already in the room")
    device: str | int | None = int(given) if given is not None and given.isdigit() else given
    return DeviceSource(device, sample_rate, block, clock)


def _play(samples: np.ndarray, rate: int) -> None:
    sd = _sounddevice()
    try:
        sd.play(samples, rate)
    except (sd.PortAudioError, ValueError) as exc:
        raise KinectDataError(f"the sound cannot be played on the default output device ({exc})") from None


def _sounddevice():
    try:
        import sounddevice
    except ImportError:
        raise KinectDataError("live audio needs sounddevice: pip install 'kinectdata[live]'") from None
    except OSError as exc:  # the module is there but not the PortAudio library it loads
        raise KinectDataError(
            f"live audio needs the PortAudio library ({exc}): apt-get install libportaudio2"
        ) from None
    return sounddevice
