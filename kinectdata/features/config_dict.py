"""Feature configurations to and from JSON-able dicts (a dataset manifest's ``config.features``):
one place for what every extractor's config does alike."""

from __future__ import annotations

import dataclasses
from typing import Any

from kinectdata.core.errors import ConfigError


def _tuple_fields(cls: type) -> list[str]:
    """The fields declared as tuples, or tuples or None (lists in JSON)."""
    return [f.name for f in dataclasses.fields(cls) if str(f.type).startswith("tuple")]


def config_to_dict(config: Any, *, with_extractor: bool = True) -> dict[str, Any]:
    """Every field of a feature config dataclass, tuples as lists; first ``"extractor"``: the
    class's ``extractor`` name (unless ``with_extractor`` is False)."""
    d = dataclasses.asdict(config)
    for name in _tuple_fields(type(config)):
        d[name] = None if d[name] is None else list(d[name])
    return {"extractor": config.extractor, **d} if with_extractor else d


def config_from_dict(cls: type, d: dict[str, Any], kind: str) -> Any:
    """The ``cls`` config of a :func:`config_to_dict` dict (also after a JSON round trip); missing
    keys take their defaults. ConfigError naming ``kind`` (e.g. "an STFT") when an ``"extractor"``
    key names another extractor, or the class when a key is unknown."""
    if d.get("extractor", cls.extractor) != cls.extractor:
        raise ConfigError(f"not {kind} configuration (extractor {d['extractor']!r})")
    kw = {k: v for k, v in d.items() if k != "extractor"}
    unknown = sorted(set(kw) - {f.name for f in dataclasses.fields(cls)})
    if unknown:
        raise ConfigError(f"unknown {cls.__name__} keys: {unknown}")
    for name in _tuple_fields(cls):
        if name in kw and kw[name] is not None:
            kw[name] = tuple(kw[name])
    return cls(**kw)


def checked_planes(planes: Any, kind: str) -> tuple[int, int]:
    """``planes`` (a config's constant planes: rows, columns) as a tuple of two whole numbers, each at
    least 1; ConfigError naming ``kind`` (e.g. "style input") otherwise."""
    values = tuple(planes)
    if len(values) != 2 or any(isinstance(v, bool) or int(v) != v or v < 1 for v in values):
        raise ConfigError(f"{kind}: planes must be (rows, columns), each at least 1, got {planes!r}")
    return int(values[0]), int(values[1])
