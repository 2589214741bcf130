"""Engines that run the streaming network one frame at a time, with its state kept inside.

- ``torch``: :class:`~kinectdata.models.yalta.StreamingYalta`, float32 or float16 weights, or
  for the cdhc model :class:`~kinectdata.models.cdhc.StreamingCdhc` (float32);
- ``onnxruntime``: the yalta network exported to ONNX (:func:`~kinectdata.inference.export.export_onnx`)
  and run by ONNX Runtime (``pip install kinectdata[export]``), float32. On a CPU at batch 1 it
  is the fastest (``benchmarks/bench_model.py``): it pre-packs the weight matrices.

All take and return numpy arrays: ``step(features [*feature shape], previous [D]) -> pose [D]``,
normalised poses; :meth:`reset` zeroes the state (LSTM states, or the causal convolutions' caches).
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import torch

from kinectdata.core.errors import KinectDataError
from kinectdata.inference.export import INPUTS, export_onnx
from kinectdata.models.cdhc import CdhcNet, StreamingCdhc
from kinectdata.models.yalta import StreamingYalta, YaltaNet

ENGINES = ("torch", "onnxruntime")


class TorchEngine:
    """The streaming network in torch (``precision``: float32 or float16 weights)."""

    def __init__(self, net: YaltaNet, precision: str = "float32"):
        self.module = StreamingYalta(net, precision).eval()
        self.name = f"torch {precision}"
        self.reset()

    def reset(self) -> None:
        self.state = self.module.initial_state()

    def step(self, features: np.ndarray, previous: np.ndarray) -> np.ndarray:
        with torch.inference_mode():
            pose, *self.state = self.module(torch.from_numpy(features), torch.from_numpy(previous), *self.state)
        return pose.numpy()


class CdhcEngine:
    """The cdhc network one frame at a time (float32), its causal convolutions' caches kept inside."""

    def __init__(self, net: CdhcNet):
        self.module = StreamingCdhc(net.eval())
        self.name = "torch float32"
        self.reset()

    def reset(self) -> None:
        self.state = self.module.initial_state()

    def step(self, features: np.ndarray, previous: np.ndarray) -> np.ndarray:
        with torch.inference_mode():
            audio = torch.from_numpy(np.asarray(features, np.float32))[None]
            pose, *self.state = self.module(
                audio, torch.from_numpy(np.asarray(previous, np.float32))[None], *self.state
            )
        return pose[0].numpy()


class OnnxRuntimeEngine:
    """The streaming network exported to ONNX and run by ONNX Runtime on the CPU with ``threads``
    threads (one is fastest at batch 1)."""

    def __init__(self, net: YaltaNet, threads: int = 1):
        try:
            import onnxruntime as ort
        except ImportError:
            raise KinectDataError(
                "the onnxruntime engine needs ONNX Runtime: pip install 'kinectdata[export]'"
            ) from None
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "stream.onnx"
            export_onnx(net, path)
            options = ort.SessionOptions()
            options.intra_op_num_threads = threads
            options.inter_op_num_threads = 1
            self.session = ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
        self.units = net.config.units
        self.name = "onnxruntime float32"
        self.reset()

    def reset(self) -> None:
        self.state = [np.zeros((3, self.units), np.float32) for _ in range(4)]

    def step(self, features: np.ndarray, previous: np.ndarray) -> np.ndarray:
        feeds = dict(zip(INPUTS, [features, np.asarray(previous, np.float32), *self.state]))
        pose, *self.state = self.session.run(None, feeds)
        return pose


def make_engine(
    net: YaltaNet | CdhcNet, engine: str = "torch", precision: str = "float32"
) -> TorchEngine | OnnxRuntimeEngine | CdhcEngine:
    """A streaming engine for a trained network (see the module docstring)."""
    if isinstance(net, CdhcNet):
        if (engine, precision) != ("torch", "float32"):
            raise KinectDataError("the cdhc model runs on the torch engine with float32 weights only")
        return CdhcEngine(net)
    if engine == "torch":
        return TorchEngine(net, precision)
    if engine == "onnxruntime":
        if precision != "float32":
            raise KinectDataError("the onnxruntime engine runs float32 weights only")
        return OnnxRuntimeEngine(net)
    raise KinectDataError(f"engine must be one of {', '.join(ENGINES)}, not {engine!r}")


def onnxruntime_available() -> bool:
    try:
        import onnxruntime  # noqa: F401
        import onnxscript  # noqa: F401
    except ImportError:
        return False
    return True
