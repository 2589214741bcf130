"""The models by name: each one a :class:`~kinectdata.models.kind.ModelKind` that declares what
training, evaluation, generation, export and the sweep need of it, so those stay one loop each.

Bundled (:mod:`.bundled`): ``yalta`` (Yalta et al. 2016) and ``cdhc`` (Lee et al. 2018).
:func:`register_model` adds another, :func:`unregister_model` removes it. Which model a dataset
trains comes from the pipeline that builds it (:data:`kinectdata.dataset.pipelines.PIPELINES`,
the one mapping): :func:`model_for_dataset`. The registry loads without torch (the command line
lists the models from it); networks are built by :func:`load_network` and the kinds.
"""

from __future__ import annotations

import dataclasses
import inspect
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from kinectdata.core.errors import ConfigError, KinectDataError
from kinectdata.models.bundled import CdhcKind, YaltaKind
from kinectdata.models.kind import ModelKind

DEFAULT_MODEL = "yalta"
"""The model of a :class:`~kinectdata.training.config.TrainConfig` that names none, and of run
folders written before runs named their model."""

MODELS: dict[str, ModelKind] = {}
"""The registered models by name, in registration order."""

MEMBERS = (
    *("name", "description", "settings_type", "training_defaults", "network_type", "resets", "streams"),
    *("engines", "exports", "run_exports", "state_names", "sweep", "check_dataset", "network_config", "build"),
    *("fill_previous", "predict", "loss", "free_batch", "init_output", "free_run", "free_runs", "stream"),
    *("example_frame", "export_metadata", "describe", "loss_name"),
)
"""What a kind declares (:class:`ModelKind`; a subclass of it inherits defaults for all but
``name``, ``settings_type``, ``network_type``, ``network_config``, ``build``, ``predict``,
``loss`` and ``free_run``)."""


def _absent(kind: Any, member: str) -> bool:
    try:  # static: a lazy property (network_type) is not evaluated, so registering imports no network
        inspect.getattr_static(kind, member)
    except AttributeError:
        return True
    return False


def register_model(kind: ModelKind, *, replace: bool = False) -> ModelKind:
    """Add a model under ``kind.name``; ConfigError if the name is taken (unless ``replace``) or
    the kind lacks what it must declare. Returns the kind."""
    missing = [m for m in MEMBERS if _absent(kind, m)]
    if missing:
        raise ConfigError(f"{type(kind).__name__} is not a model kind: it has no {', '.join(missing)}")
    name = kind.name
    if not isinstance(name, str) or not name.isidentifier():
        raise ConfigError(f"a model's name must be an identifier, not {name!r}")
    if name in MODELS and MODELS[name] is not kind and not replace:
        raise ConfigError(f"model {name!r} is already registered; pass replace=True")
    if not dataclasses.is_dataclass(kind.settings_type):
        raise ConfigError(f"the {name} model's settings_type must be a dataclass")
    try:
        kind.settings_type()
    except (TypeError, KinectDataError) as exc:
        raise ConfigError(f"the {name} model's default settings are not valid: {exc}") from exc
    MODELS[name] = kind
    return kind


def unregister_model(name: str) -> None:
    """Remove a registered model (a no-op if there is none of that name)."""
    MODELS.pop(name, None)


def model_names() -> list[str]:
    """The registered models' names, in registration order."""
    return list(MODELS)


def model_kind(name: str) -> ModelKind:
    """The model registered under ``name``; ConfigError listing the known ones otherwise."""
    try:
        return MODELS[name]
    except KeyError:
        raise ConfigError(f"unknown model {name!r}; known: {', '.join(MODELS)}") from None


def kind_of(net: Any) -> ModelKind:
    """The registered model whose networks ``net`` is one of."""
    for kind in MODELS.values():
        if isinstance(net, kind.network_type):
            return kind
    raise ConfigError(f"{type(net).__name__} is not the network of a registered model ({', '.join(MODELS)})")


def make_settings(kind: ModelKind, base: Any = None, /, **changes: Any) -> Any:
    """The model's settings (an instance of ``kind.settings_type``): ``base`` (an instance or a
    mapping; None: the defaults) with ``changes``. ConfigError naming an unknown or bad setting."""
    cls = kind.settings_type
    if base is None:
        values: dict[str, Any] = {}
    elif isinstance(base, cls):
        values = {f.name: getattr(base, f.name) for f in dataclasses.fields(cls)}
    elif isinstance(base, Mapping):
        values = dict(base)
    else:
        raise ConfigError(f"the {kind.name} model's settings must be a {cls.__name__} or a mapping, not {base!r}")
    values.update(changes)
    known = [f.name for f in dataclasses.fields(cls)]
    unknown = sorted(set(values) - set(known))
    if unknown:
        raise ConfigError(
            f"the {kind.name} model has no setting {', '.join(unknown)} (its settings: {', '.join(known) or 'none'})"
        )
    try:
        return cls(**values)
    except TypeError as exc:
        raise ConfigError(f"the {kind.name} model's settings: {exc}") from exc


def pipelines_for(name: str) -> list[str]:
    """The pipelines (``build-dataset --pipeline``) that build datasets for the named model."""
    from kinectdata.dataset.pipelines import PIPELINES

    return [p for p, chosen in PIPELINES.items() if chosen.get("model") == name]


def _fits(kind: ModelKind, manifest: dict[str, Any]) -> bool:
    try:
        kind.check_dataset(manifest)
    except KinectDataError:
        return False
    return True


def model_for_dataset(manifest: dict[str, Any]) -> str:
    """The model a dataset (its manifest) is for: its pipeline's (a manifest that names one), else
    the model of the pipeline whose features have the dataset's extractor, else the first
    registered model the dataset fits, else :data:`DEFAULT_MODEL`."""
    from kinectdata.dataset.pipelines import PIPELINES
    from kinectdata.features import PRESETS, feature_config

    config = manifest.get("config", {})
    named = PIPELINES.get(config.get("pipeline") or "", {}).get("model")
    if named in MODELS:
        return named
    try:
        extractor = type(feature_config(config["features"]))
    except (KeyError, TypeError, ValueError, KinectDataError):
        extractor = None
    for chosen in PIPELINES.values():
        if chosen["model"] in MODELS and type(PRESETS[chosen["features"]]) is extractor:
            return chosen["model"]
    return next((name for name, kind in MODELS.items() if _fits(kind, manifest)), DEFAULT_MODEL)


def check_fits(kind: ModelKind, manifest: dict[str, Any], dataset: str | Path) -> None:
    """ConfigError naming the dataset, why it does not fit the model and what to do (the model the
    dataset fits, the pipeline that builds the model's datasets); None if it fits."""
    try:
        kind.check_dataset(manifest)
    except KinectDataError as exc:
        advice = []
        fits = model_for_dataset(manifest)
        if fits != kind.name and _fits(MODELS[fits], manifest):
            advice.append(f"use --model {fits}, this dataset's model")
        pipelines = pipelines_for(kind.name)
        if pipelines:
            advice.append(f"build the dataset with --pipeline {' or '.join(pipelines)} for the {kind.name} model")
        raise ConfigError(f"{dataset}: {exc}" + (f" ({'; or '.join(advice)})" if advice else "")) from None


def load_network(model: str, config: dict[str, Any], state: dict[str, Any], where: str):
    """A network (``nn.Module``) of the named model with a state dict; KinectDataError starting
    with ``where`` if they disagree."""
    try:
        net = model_kind(model).build(config)
        net.load_state_dict(state)
    except (KeyError, TypeError, ValueError, RuntimeError, KinectDataError) as exc:
        raise KinectDataError(f"{where} ({model} model: {exc})") from exc
    return net


for _kind in (YaltaKind(), CdhcKind()):
    register_model(_kind)
