"""A model's streaming network as a file a robot can run: TorchScript or ONNX, self-describing.

A model that exports (its kind's ``exports``: :class:`~kinectdata.models.kind.ModelKind`) has a
stream (its kind's ``stream``), one frame per call: inputs ``features`` [*F] (the frame's
features, ``features`` in the metadata), ``previous`` [D] (the previous pose, normalised; first
call: ``start_pose``) and its state tensors (the kind's ``state_names``; zeros, or the stream's
``initial_state()``, at the start: for the cdhc model, zeros, then as many frames of zero
features stepped through as the metadata's ``start_silence_frames``); outputs ``pose`` [D] (normalised: denormalise with
``normalisation``) and the new state, ``NAME_out`` for each state tensor, to pass back in with
the next frame. The yalta model's (:class:`~kinectdata.models.yalta.StreamingYalta`):

======== =============== ==========================================================
input    shape           meaning
======== =============== ==========================================================
features [1, 129, 5]     the frame's STFT features
previous [D]             the previous pose, normalised
h1, c1   [3, units]      LSTM1-3 state (zeros at the start)
h2, c2   [3, units]      LSTM4-6 state (zeros at the start)
======== =============== ==========================================================

The metadata (JSON) says everything needed around the network: frame and sample rate, the
feature settings, the target components and their normalisation, the start pose, the inputs'
shapes, the turning about the vertical and the travel across the floor to draw around the network
(``turning``, ``travel``: the processes of :mod:`kinectdata.targets.turning` and
:mod:`kinectdata.targets.travel`, which the network does not make; null: none), how the travel plants
the standing foot (``foot_lock``: the catch-up time and the feet's height softness of
:mod:`kinectdata.targets.foot_lock`, and ``steps_at_reach``: the other foot stands when the standing
leg reaches no further; null: the whole body moves), the low-pass run on the poses
after them (``smoothing``: a causal Butterworth's order and cutoff, started at rest on the first
pose, :mod:`kinectdata.inference.smoothing`; null: none), and what the model
adds (:meth:`~kinectdata.models.kind.ModelKind.export_metadata`).
TorchScript keeps it as the extra file ``kinectdata.json``
(``torch.jit.load(path, _extra_files={"kinectdata.json": ""})``); ONNX as the model property
``kinectdata`` (``onnxruntime.InferenceSession(path).get_modelmeta().custom_metadata_map``).

TorchScript loads in Python and in C++ (libtorch) without kinectdata; torch marks it deprecated
but it still works in the torch versions kinectdata supports. ONNX (``pip install
kinectdata[export]``) runs in ONNX Runtime on any platform, and at batch 1 on a CPU it is the
fastest way to run the yalta model's float32 network (``benchmarks/bench_model.py``).
"""

from __future__ import annotations

import json
import logging
import warnings
from pathlib import Path
from typing import Any

import torch

from kinectdata.core.atomic import atomic_output
from kinectdata.core.errors import ConfigError, KinectDataError
from kinectdata.inference.smoothing import ORDER, run_smoothing
from kinectdata.models.kind import ModelKind
from kinectdata.models.registry import MODELS, kind_of, model_kind
from kinectdata.models.run import load_model, model_name, read_config
from kinectdata.targets.foot_lock import CATCH_UP_S, LEAD_S, SHIFT_S, STANCE_MARGIN_M, VELOCITY_SMOOTHING_S, legs_of
from kinectdata.targets.specs import TargetSpec

FORMATS = ("torchscript", "onnx")
METADATA_KEY = "kinectdata"
TORCHSCRIPT_METADATA = "kinectdata.json"


def stream_names(kind: ModelKind, model_config: dict[str, Any]) -> tuple[list[str], list[str]]:
    """The exported stream's (input names, output names): ``features``, ``previous`` and the
    state's (:meth:`~kinectdata.models.kind.ModelKind.stream_state_names` of the network's
    configuration); ``pose`` and ``NAME_out`` for each state tensor."""
    names = kind.stream_state_names(model_config)
    return ["features", "previous", *names], ["pose", *(f"{n}_out" for n in names)]


def network_config(net: torch.nn.Module) -> dict[str, Any]:
    """A network's configuration as its run's ``config.json`` ``model`` record holds it (its
    ``config.to_dict()``; empty for a network without one), for the stream's state names."""
    config = getattr(net, "config", None)
    return config.to_dict() if hasattr(config, "to_dict") else {}


def stream_metadata(
    run_config: dict[str, Any], precision: str = "float32", kind: ModelKind | None = None
) -> dict[str, Any]:
    """What a program running the exported network needs besides it, from a run's config.json."""
    kind = kind or model_kind(model_name(run_config))
    data = run_config["dataset"]
    extra = dict(kind.export_metadata(run_config["model"]))
    inputs = {"features": list(data["feature_shape"]), "previous": [data["target_dim"]], **extra.pop("inputs", {})}
    return {
        "model": kind.name,
        "precision": precision,
        "inputs": inputs,
        "outputs": stream_names(kind, run_config["model"])[1],
        "fps": data["fps"],
        "sample_rate": data["sample_rate"],
        "features": data["features"],
        "target": data["target"],
        "root_centre": data["root_centre"],
        "normalisation": data["normalisation"],
        "start_pose": data["start_pose"],
        "sway": run_config.get("sway"),
        "turning": run_config.get("turning"),
        "travel": run_config.get("travel"),
        "foot_lock": _foot_lock(run_config),
        "drawn_by_metre": run_config.get("drawn_by_metre"),
        "smoothing": _smoothing(run_config),
        **extra,
    }


def _smoothing(run_config: dict[str, Any]) -> dict[str, Any] | None:
    """The low-pass to run on the poses after the drawn processes, or None (the run does not smooth)."""
    cutoff = run_smoothing(run_config)
    return None if cutoff is None else {"filter": "butterworth", "order": ORDER, "cutoff_hz": cutoff, "causal": True}


def _foot_lock(run_config: dict[str, Any]) -> dict[str, float] | None:
    """How the run's travel plants the standing foot, or None (no travel, or a target without legs)."""
    if run_config.get("travel") is None or not run_config["dataset"].get("root_centre"):
        return None
    if legs_of(TargetSpec.from_dict(run_config["dataset"]["target"])) is None:
        return None
    return {
        "catch_up_s": CATCH_UP_S,
        "lead_s": LEAD_S,
        "velocity_smoothing_s": VELOCITY_SMOOTHING_S,
        "stance_margin_m": STANCE_MARGIN_M,
        "shift_s": SHIFT_S,
        "steps_at_reach": True,
    }


def check_export(kind: ModelKind, fmt: str, precision: str = "float32") -> None:
    """ConfigError unless the model exports ``fmt`` with ``precision`` weights (ONNX: float32;
    TorchScript: the precisions of the model's torch engine)."""
    if fmt not in FORMATS:
        raise ConfigError(f"export format must be one of {', '.join(FORMATS)}, not {fmt!r}")
    if fmt not in kind.exports:
        others = [k.name for k in MODELS.values() if fmt in k.exports]
        raise ConfigError(
            f"the {kind.name} model has no {fmt} export (models that have: {', '.join(others) or 'none'}); "
            "run it with kinectdata generate"
        )
    if fmt == "onnx" and precision != "float32":
        raise ConfigError("ONNX export is float32 only (ONNX Runtime runs float32 fastest on CPUs)")
    precisions = kind.engines.get("torch", ("float32",))
    if precision not in precisions:
        raise ConfigError(f"the {kind.name} model exports {' or '.join(precisions)} weights only, not {precision!r}")


def export_torchscript(
    net: torch.nn.Module,
    path: str | Path,
    precision: str = "float32",
    metadata: dict[str, Any] | None = None,
    kind: ModelKind | None = None,
) -> torch.jit.ScriptModule:
    """Write a network's stream (its model's, ``kind`` or found from the network) as TorchScript
    (atomically) and return the scripted module."""
    kind = kind or kind_of(net)
    check_export(kind, "torchscript", precision)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # torch.jit is deprecated but still the libtorch path
        module = torch.jit.script(kind.stream(net.eval(), precision))
        extra = {TORCHSCRIPT_METADATA: json.dumps(metadata or {})}
        with atomic_output(path) as tmp:
            torch.jit.save(module, str(tmp), _extra_files=extra)
    return module


def export_onnx(
    net: torch.nn.Module,
    path: str | Path,
    metadata: dict[str, Any] | None = None,
    kind: ModelKind | None = None,
    *,
    traced: bool = False,
) -> Path:
    """Write a network's float32 stream (its model's, ``kind`` or found from the network) as one
    self-contained ONNX file (atomically), by torch's exporter (``torch.export``).

    ``traced``: by torch's earlier exporter, which traces the stream once: ten times faster (0.3 s
    against 1-3 s for the yalta model), for the file ONNX Runtime's engine makes for itself and
    throws away (``generate``, ``live``, ``evaluate``'s timing); the same graph, as their tests
    check against torch. Where a torch no longer has it, the current exporter is used."""
    kind = kind or kind_of(net)
    check_export(kind, "onnx")
    try:
        import onnx
        import onnxscript  # noqa: F401  (torch's ONNX exporter needs it)
    except ImportError:
        raise KinectDataError("ONNX export needs onnx and onnxscript: pip install 'kinectdata[export]'") from None
    stream = kind.stream(net.eval(), "float32").eval()
    example = (*kind.example_frame(net), *stream.initial_state())
    inputs, outputs = stream_names(kind, network_config(net))
    quiet = logging.getLogger("torch.onnx")
    level = quiet.level
    quiet.setLevel(logging.ERROR)
    try:
        with warnings.catch_warnings(), atomic_output(path) as tmp:
            warnings.simplefilter("ignore")
            if traced and _traced_export(stream, example, inputs, outputs, tmp):
                return Path(path)
            program = torch.onnx.export(
                stream,
                example,
                dynamo=True,
                input_names=inputs,
                output_names=outputs,
                external_data=False,
                verbose=False,
            )
            model = program.model_proto
            onnx.helper.set_model_props(model, {METADATA_KEY: json.dumps(metadata or {})})
            onnx.save(model, str(tmp))
    finally:
        quiet.setLevel(level)
    return Path(path)


def _traced_export(stream: torch.nn.Module, example: tuple, inputs: list[str], outputs: list[str], tmp) -> bool:
    """The stream by torch's tracing exporter into ``tmp``; False where this torch has none left."""
    try:
        torch.onnx.export(stream, example, str(tmp), dynamo=False, input_names=inputs, output_names=outputs)
    except (TypeError, NotImplementedError, RuntimeError):  # the keyword or the exporter gone
        return False
    return True


def export_network(
    net: torch.nn.Module,
    path: str | Path,
    fmt: str,
    precision: str = "float32",
    metadata: dict[str, Any] | None = None,
    kind: ModelKind | None = None,
) -> Path:
    """Write a network's stream as ``fmt`` (``torchscript`` or ``onnx``)."""
    kind = kind or kind_of(net)
    check_export(kind, fmt, precision)
    if fmt == "onnx":
        return export_onnx(net, path, metadata, kind)
    export_torchscript(net, path, precision, metadata, kind)
    return Path(path)


def export_run(run: str | Path, path: str | Path, fmt: str | None = None, precision: str = "float32") -> Path:
    """Export a trained run's stream to ``path``; ``fmt`` from the suffix when None (``.onnx``:
    ONNX, else TorchScript). ONNX is float32 only. ConfigError for a model that does not export
    ``fmt``."""
    fmt = fmt or ("onnx" if Path(path).suffix.lower() == ".onnx" else "torchscript")
    kind = model_kind(model_name(read_config(run)))
    try:
        check_export(kind, fmt, precision)
    except ConfigError as exc:
        raise ConfigError(f"{run}: {exc}") from None
    net, config = load_model(run)
    return export_network(net, path, fmt, precision, stream_metadata(config, precision, kind), kind)
