"""Engines that run a model's stream one frame at a time, with its state kept inside.

Which engines and weight precisions a model runs on, its kind says (``engines``:
:class:`~kinectdata.models.kind.ModelKind`); :func:`make_engine` picks one for a network:

- ``torch``: the model's stream (its kind's ``stream``) in PyTorch, e.g. the yalta model's
  :class:`~kinectdata.models.yalta.StreamingYalta` with float32 or float16 weights, the cdhc
  model's :class:`~kinectdata.models.cdhc.FrameCdhc` (float32);
- ``onnxruntime``: the stream exported to ONNX (:func:`~kinectdata.inference.export.export_onnx`)
  and run by ONNX Runtime (``pip install kinectdata[export]``), float32. On a CPU at batch 1 it
  is the fastest for the yalta model (``benchmarks/bench_model.py``): it pre-packs the weight
  matrices.

All take and return numpy arrays: ``step(features [*feature shape], previous [D]) -> pose [D]``,
normalised poses; :meth:`reset` puts the state back to the stream's initial one (LSTM states,
the causal convolutions' caches, ...).
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import torch

from kinectdata.core.errors import ConfigError, KinectDataError
from kinectdata.inference.export import export_onnx, network_config, stream_names
from kinectdata.models.kind import ModelKind
from kinectdata.models.registry import kind_of

ENGINES = ("torch", "onnxruntime")


class TorchEngine:
    """A network's stream in torch (``precision``: its weights', as its model offers)."""

    def __init__(self, net: torch.nn.Module, precision: str = "float32", kind: ModelKind | None = None, draw: int = 0):
        self.module = _stream(kind or kind_of(net), net, precision, draw).eval()
        self.initial = tuple(self.module.initial_state())  # once: the cdhc stream's steps through its start silence
        self.name = f"torch {precision}"
        self.reset()

    def reset(self) -> None:
        self.state = [s.clone() for s in self.initial]

    def step(self, features: np.ndarray, previous: np.ndarray) -> np.ndarray:
        with torch.inference_mode():
            x = torch.from_numpy(np.asarray(features, np.float32))
            pose, *self.state = self.module(x, torch.from_numpy(np.asarray(previous, np.float32)), *self.state)
        return pose.numpy()


class OnnxRuntimeEngine:
    """A network's stream exported to ONNX and run by ONNX Runtime on the CPU with ``threads``
    threads (one is fastest at batch 1)."""

    def __init__(self, net: torch.nn.Module, threads: int = 1, kind: ModelKind | None = None, draw: int = 0):
        try:
            import onnxruntime as ort
        except ImportError:
            raise KinectDataError(
                "the onnxruntime engine needs ONNX Runtime: pip install 'kinectdata[export]'"
            ) from None
        kind = kind or kind_of(net)
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "stream.onnx"
            export_onnx(net, path, kind=kind, traced=True)
            options = ort.SessionOptions()
            options.intra_op_num_threads = threads
            options.inter_op_num_threads = 1
            self.session = ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
        self.inputs = stream_names(kind, network_config(net))[0]  # by name: an exporter may drop an input it ignores
        self.kept = {i.name for i in self.session.get_inputs()}
        self.initial = [s.detach().cpu().numpy() for s in _stream(kind, net, "float32", draw).initial_state()]
        self.name = "onnxruntime float32"
        self.reset()

    def reset(self) -> None:
        self.state = [s.copy() for s in self.initial]

    def step(self, features: np.ndarray, previous: np.ndarray) -> np.ndarray:
        values = [features, np.asarray(previous, np.float32), *self.state]
        feeds = {name: value for name, value in zip(self.inputs, values) if name in self.kept}
        pose, *self.state = self.session.run(None, feeds)
        return pose


def engine_pairs(kind: ModelKind) -> list[tuple[str, str]]:
    """Every (engine, precision) the model runs on."""
    return [(engine, precision) for engine, precisions in kind.engines.items() for precision in precisions]


def check_engine(kind: ModelKind, engine: str, precision: str) -> None:
    """ConfigError unless the model runs on ``engine`` with ``precision`` weights."""
    if engine not in ENGINES:
        raise ConfigError(f"engine must be one of {', '.join(ENGINES)}, not {engine!r}")
    if not kind.streams or engine not in kind.engines:
        runs = f"runs on {', '.join(kind.engines)} only" if kind.streams and kind.engines else "does not stream"
        raise ConfigError(f"the {kind.name} model {runs}, not {engine}")
    if precision not in kind.engines[engine]:
        raise ConfigError(
            f"the {kind.name} model runs on {engine} with {' or '.join(kind.engines[engine])} weights only, "
            f"not {precision}"
        )


def make_engine(
    net: torch.nn.Module,
    engine: str = "torch",
    precision: str = "float32",
    kind: ModelKind | None = None,
    draw: int = 0,
) -> TorchEngine | OnnxRuntimeEngine:
    """A streaming engine for a trained network of a model (``kind``, or found from the network),
    from draw ``draw`` of a network that draws (:meth:`~kinectdata.models.kind.ModelKind.takes_draws`)."""
    kind = kind or kind_of(net)
    check_engine(kind, engine, precision)
    if engine == "onnxruntime":
        return OnnxRuntimeEngine(net, kind=kind, draw=draw)
    return TorchEngine(net, precision, kind, draw)


def _stream(kind: ModelKind, net: torch.nn.Module, precision: str, draw: int):
    """The kind's stream of the network, from ``draw`` when its network draws."""
    if kind.takes_draws(network_config(net)):
        return kind.stream(net, precision, draw=draw)
    return kind.stream(net, precision)


def onnxruntime_available() -> bool:
    try:
        import onnxruntime  # noqa: F401
        import onnxscript  # noqa: F401
    except ImportError:
        return False
    return True
