"""What every sensor of a capture gives the take (:class:`SensorTake`) and what it must offer
(:class:`Sensor`): :mod:`.openni` (OpenNI2 devices) and :mod:`.k4a` (Azure Kinect and Orbbec
Femto through pyk4a)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Protocol


@dataclass
class SensorTake:
    """What a sensor recorded into a take, as ``take.json`` keeps it.

    Attributes:
        device: what identifies the device (OpenNI2: ``uri``, ``vendor``, ``name``; Azure Kinect:
            ``serial``, ``index``).
        key: the key of the recording's entry in ``take.json`` (``oni``, ``mkv``).
        entry: the recording's entry; ``zero_clock_s`` is the clock time of the file's time 0.
        skeleton: the live skeleton's entry (``file``, ``user``, ``frames``) or None.
        problems: doubts about the recording, one line each.
    """

    device: dict[str, Any]
    key: str
    entry: dict[str, Any]
    skeleton: dict[str, Any] | None
    problems: list[str]

    @property
    def zero_clock_s(self) -> float:
        return float(self.entry["zero_clock_s"])


class Sensor(Protocol):
    """A device to record a take from: its settings, the files it writes, and how.

    Attributes:
        kind: ``take.json``'s ``sensor`` (``openni2``, ``k4a``).
        files: the take's files it may write (refused when the folder holds them already).
        what: names the device in messages.
    """

    kind: ClassVar[str]
    files: ClassVar[tuple[str, ...]]

    @property
    def what(self) -> str: ...

    def record(self, take: Path, duration_s: float, problems: list[str]) -> SensorTake:
        """Record ``duration_s`` seconds into the folder ``take``; append doubts to ``problems``.
        Raises KinectDataError (naming the device) when it cannot; leaves no partial file."""
        ...

    def describe(self, doc: dict[str, Any], take: str) -> list[str]:
        """The lines ``kinectdata capture`` prints about the files it wrote."""
        ...
