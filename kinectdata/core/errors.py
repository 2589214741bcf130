"""The error and warning types kinectdata raises and emits.

Every problem with a user's file is raised as a :class:`KinectDataError` subclass whose message
names the file and, where it applies, the place in it (line, frame, record, column), so that a
command can print it as is and exit non-zero.
"""

from __future__ import annotations

from os import PathLike


class KinectDataError(Exception):
    """Base class of every error kinectdata raises about its inputs or configuration."""


class InputError(KinectDataError):
    """A problem located in one input file.

    The message reads ``PATH, line 12, column 'SpineBase_X': what is wrong``; each location part
    appears only when given. ``line`` is 1-based (as editors count), ``frame`` and ``record`` are
    0-based indices into the file's frames or records.
    """

    def __init__(
        self,
        path: str | PathLike[str] | None,  # None: the problem is not in a file (a bad name)
        message: str,
        *,
        line: int | None = None,
        frame: int | None = None,
        record: int | None = None,
        column: str | int | None = None,
    ) -> None:
        self.path = None if path is None else str(path)
        self.line = line
        self.frame = frame
        self.record = record
        self.column = column
        self.reason = message
        super().__init__(self._format())

    def __reduce__(self):
        # picklable (errors cross process boundaries in parallel builds): rebuild with the fields
        where = {"line": self.line, "frame": self.frame, "record": self.record, "column": self.column}
        return _rebuild, (type(self), self.path, self.reason, where)

    def _format(self) -> str:
        if self.path is None:
            return self.reason
        parts = [self.path]
        if self.line is not None:
            parts.append(f"line {self.line}")
        if self.frame is not None:
            parts.append(f"frame {self.frame}")
        if self.record is not None:
            parts.append(f"record {self.record}")
        if self.column is not None:
            parts.append(f"column {self.column!r}")
        return ", ".join(parts) + ": " + self.reason


def _rebuild(cls: type[InputError], path: str | None, reason: str, where: dict) -> InputError:
    return cls(path, reason, **where)


class FormatError(InputError):
    """A recording file does not follow its format."""


class SchemaError(InputError):
    """A schema, joint-set or other declarative file is invalid."""


class CorpusError(InputError):
    """A local copy of a corpus is not laid out as its recipe expects (a folder or list missing)."""


class AudioError(InputError):
    """An audio file cannot be read or is unusable."""


class AlignmentError(KinectDataError):
    """Motion and audio cannot be aligned as asked (ambiguous offset, too little overlap...)."""


class ConfigError(KinectDataError, ValueError):
    """A setting, argument or combination of them is not valid (not a fault of any file).

    Also a :class:`ValueError`, so code that catches bad values the Python way keeps working.
    """


class KinectDataWarning(UserWarning):
    """Base class of every warning kinectdata emits: ``warnings.filterwarnings("ignore",
    category=KinectDataWarning)`` silences them all, ``"error"`` turns them into exceptions."""
