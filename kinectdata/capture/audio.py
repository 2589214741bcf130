"""Audio from an input device to a WAV file, stamped on the monotonic clock (sounddevice).

The stream's callback hands each block to a writer thread (no disk I/O in the audio thread) and,
for the first block, notes when its first sample entered the converter on ``time.monotonic()``:
the callback's "now" minus how long ago, by the stream's own clock, that sample was captured.
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import soundfile as sf

from kinectdata.core.errors import KinectDataError


def _sounddevice():
    try:
        import sounddevice
    except ImportError:
        raise KinectDataError("audio capture needs sounddevice: pip install 'kinectdata[capture]'") from None
    except OSError as exc:  # the module is there but not the PortAudio library it loads
        raise KinectDataError(f"audio capture needs PortAudio ({exc}): apt-get install libportaudio2") from None
    return sounddevice


def input_devices() -> list[dict[str, Any]]:
    """The audio input devices: index, name, input channels, default sample rate."""
    sd = _sounddevice()
    return [
        {"index": i, "name": d["name"], "channels": d["max_input_channels"], "sample_rate": d["default_samplerate"]}
        for i, d in enumerate(sd.query_devices())
        if d["max_input_channels"] > 0
    ]


class AudioCapture:
    """Records ``device`` (an index or name) to ``path`` between :meth:`start` and :meth:`stop`.

    Attributes (after :meth:`stop`): ``first_sample_clock_s`` (monotonic seconds of sample 0),
    ``frames`` (samples per channel written), ``overflows`` (blocks the device dropped).
    ``stream_factory`` makes the input stream (default ``sounddevice.InputStream``).
    """

    def __init__(
        self,
        path: str | Path,
        device: int | str | None,
        sample_rate: int = 48000,
        channels: int = 1,
        stream_factory: Callable[..., Any] | None = None,
    ):
        self.path, self.device, self.sample_rate, self.channels = Path(path), device, sample_rate, channels
        self.first_sample_clock_s: float | None = None
        self.frames = 0
        self.overflows = 0
        self._queue: queue.Queue = queue.Queue()
        self._factory = stream_factory or _sounddevice().InputStream
        self._writer: threading.Thread | None = None
        self._stream = None
        self._error: Exception | None = None

    def _callback(self, indata: np.ndarray, frames: int, time_info, status) -> None:
        if self.first_sample_clock_s is None:
            now = time.monotonic()
            adc, current = getattr(time_info, "inputBufferAdcTime", 0.0), getattr(time_info, "currentTime", 0.0)
            ago = current - adc if adc and current and current >= adc else frames / self.sample_rate
            self.first_sample_clock_s = now - ago
        if status and getattr(status, "input_overflow", False):
            self.overflows += 1
        self._queue.put(indata.copy())

    def _write(self, f: sf.SoundFile) -> None:
        try:
            while (block := self._queue.get()) is not None:
                f.write(block)
                self.frames += block.shape[0]
        except Exception as exc:  # reported by stop()
            self._error = exc

    def start(self, wait_s: float = 5.0) -> None:
        """Open the device and start recording; returns once the first block has arrived."""
        self._file = sf.SoundFile(self.path, "w", self.sample_rate, self.channels, subtype="PCM_24", format="WAV")
        self._writer = threading.Thread(target=self._write, args=(self._file,), daemon=True)
        self._writer.start()
        try:
            self._stream = self._factory(
                device=self.device,
                samplerate=self.sample_rate,
                channels=self.channels,
                dtype="float32",
                callback=self._callback,
            )
            self._stream.start()
        except Exception as exc:
            self._finish()
            raise KinectDataError(f"audio device {self.device!r}: cannot record ({exc})") from exc
        deadline = time.monotonic() + wait_s
        while self.first_sample_clock_s is None and time.monotonic() < deadline:
            time.sleep(0.005)
        if self.first_sample_clock_s is None:
            self.stop()
            raise KinectDataError(f"audio device {self.device!r}: no sound arrived in {wait_s:g} s")

    def _finish(self) -> None:
        if self._writer is None:
            return
        self._queue.put(None)
        self._writer.join()
        self._writer = None
        self._file.close()

    def stop(self) -> None:
        """Stop the device and finish the file."""
        if self._stream is not None:
            self._stream.stop()
            self._stream.close()
            self._stream = None
        self._finish()
        if self._error is not None:
            raise KinectDataError(f"{self.path}: writing the audio failed ({self._error})")
