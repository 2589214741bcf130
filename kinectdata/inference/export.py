"""The streaming network as a file a robot can run: TorchScript or ONNX, self-describing.

Both files hold :class:`~kinectdata.models.yalta.StreamingYalta`, one frame per call:

======== =============== ==========================================================
input    shape           meaning
======== =============== ==========================================================
features [1, 129, 5]     the frame's STFT features (``features`` in the metadata)
previous [D]             the previous pose, normalised (first call: ``start_pose``)
h1, c1   [3, units]      LSTM1-3 state (zeros at the start)
h2, c2   [3, units]      LSTM4-6 state (zeros at the start)
======== =============== ==========================================================

and it returns the pose [D] (normalised: denormalise with ``normalisation``) and the four new
states, to pass back in with the next frame. The metadata (JSON) says everything needed around
the network: frame and sample rate, the feature settings, the target components and their
normalisation, the start pose. TorchScript keeps it as the extra file ``kinectdata.json``
(``torch.jit.load(path, _extra_files={"kinectdata.json": ""})``); ONNX as the model property
``kinectdata`` (``onnxruntime.InferenceSession(path).get_modelmeta().custom_metadata_map``).

TorchScript loads in Python and in C++ (libtorch) without kinectdata; torch marks it deprecated
but it still works in the torch versions kinectdata supports. ONNX (``pip install
kinectdata[export]``) runs in ONNX Runtime on any platform, and at batch 1 on a CPU it is the
fastest way to run the float32 network (``benchmarks/bench_model.py``).
"""

from __future__ import annotations

import json
import logging
import warnings
from pathlib import Path
from typing import Any

import torch

from kinectdata.core.atomic import atomic_output
from kinectdata.core.errors import KinectDataError
from kinectdata.models.yalta import StreamingYalta, YaltaNet

FORMATS = ("torchscript", "onnx")
INPUTS = ["features", "previous", "h1", "c1", "h2", "c2"]
OUTPUTS = ["pose", "h1_out", "c1_out", "h2_out", "c2_out"]
METADATA_KEY = "kinectdata"
TORCHSCRIPT_METADATA = "kinectdata.json"


def stream_metadata(run_config: dict[str, Any], precision: str = "float32") -> dict[str, Any]:
    """What a program running the exported network needs besides it, from a run's config.json."""
    data = run_config["dataset"]
    model = run_config["model"]
    return {
        "model": "yalta2016",
        "precision": precision,
        "inputs": {
            "features": list(model["input_shape"]),
            "previous": [model["output_dim"]],
            **{name: [3, model["units"]] for name in INPUTS[2:]},
        },
        "outputs": OUTPUTS,
        "fps": data["fps"],
        "sample_rate": data["sample_rate"],
        "features": data["features"],
        "target": data["target"],
        "root_centre": data["root_centre"],
        "normalisation": data["normalisation"],
        "start_pose": data["start_pose"],
        "activation": model["activation"],
        "units": model["units"],
    }


def export_torchscript(
    net: YaltaNet, path: str | Path, precision: str = "float32", metadata: dict[str, Any] | None = None
) -> torch.jit.ScriptModule:
    """Write the streaming network as TorchScript (atomically) and return the scripted module."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # torch.jit is deprecated but still the libtorch path
        module = torch.jit.script(StreamingYalta(net.eval(), precision))
        extra = {TORCHSCRIPT_METADATA: json.dumps(metadata or {})}
        with atomic_output(path) as tmp:
            torch.jit.save(module, str(tmp), _extra_files=extra)
    return module


def export_onnx(net: YaltaNet, path: str | Path, metadata: dict[str, Any] | None = None) -> Path:
    """Write the float32 streaming network as one self-contained ONNX file (atomically)."""
    try:
        import onnx
        import onnxscript  # noqa: F401  (torch's ONNX exporter needs it)
    except ImportError:
        raise KinectDataError("ONNX export needs onnx and onnxscript: pip install 'kinectdata[export]'") from None
    stream = StreamingYalta(net.eval(), "float32").eval()
    example = (torch.zeros(*net.config.input_shape), torch.zeros(net.config.output_dim), *stream.initial_state())
    quiet = logging.getLogger("torch.onnx")
    level = quiet.level
    quiet.setLevel(logging.ERROR)
    try:
        with warnings.catch_warnings(), atomic_output(path) as tmp:
            warnings.simplefilter("ignore")
            program = torch.onnx.export(
                stream,
                example,
                dynamo=True,
                input_names=INPUTS,
                output_names=OUTPUTS,
                external_data=False,
                verbose=False,
            )
            model = program.model_proto
            onnx.helper.set_model_props(model, {METADATA_KEY: json.dumps(metadata or {})})
            onnx.save(model, str(tmp))
    finally:
        quiet.setLevel(level)
    return Path(path)


def export_run(run: str | Path, path: str | Path, fmt: str | None = None, precision: str = "float32") -> Path:
    """Export a trained run's network to ``path``; ``fmt`` from the suffix when None
    (``.onnx``: ONNX, else TorchScript). ONNX is float32 only."""
    from kinectdata.models.run import load_model

    fmt = fmt or ("onnx" if Path(path).suffix.lower() == ".onnx" else "torchscript")
    if fmt not in FORMATS:
        raise KinectDataError(f"export format must be one of {', '.join(FORMATS)}, not {fmt!r}")
    if fmt == "onnx" and precision != "float32":
        raise KinectDataError("ONNX export is float32 only (ONNX Runtime runs float32 fastest on CPUs)")
    from kinectdata.models.run import model_name, read_config

    if model_name(read_config(run)) != "yalta":
        raise KinectDataError(
            f"{run}: export writes the yalta model's streaming network; this run is {model_name(read_config(run))} "
            "(run it with kinectdata generate)"
        )
    net, config = load_model(run)
    metadata = stream_metadata(config, precision)
    if fmt == "onnx":
        return export_onnx(net, path, metadata)
    export_torchscript(net, path, precision, metadata)
    return Path(path)
