"""Speed of the Yalta et al. (2016) network: live generation per frame, and training.

**Streaming latency** (the issue's target: median at most 2 ms per frame for the 500-unit model
at batch 1 on one CPU core; the paper reports 10.94 ms on a GTX Titan X). One thread
(``torch.set_num_threads(1)``, ONNX Runtime ``intra_op_num_threads=1``), 65 outputs, the
model's own output fed back, 1500 timed frames after 100 warm-up frames, per-call wall time.
Engines: the sequence network called one frame at a time (``YaltaNet`` with torch's LSTM, the
naive way), the streaming network (``StreamingYalta``: batch norm folded, one product per LSTM
layer) eager and as TorchScript in float32 and float16 weights, and the exported ONNX file in
ONNX Runtime (when installed). Latency does not depend on the weights' values, so the networks
are freshly initialised. Also the largest deviation of float16 weights from float32 over 300
fed-back frames, and the 250- and 1000-unit models of the paper's Table 4.

**Training throughput**: frames per second of one optimisation step (forward, MSE, backward,
annealed gradient noise, Adam) with the paper's default configuration (500 units, sequences of
150, batches of 50) on random inputs, both feedbacks, all cores; data loading is not included
(``log.csv`` of a real run reports the whole loop).

**The cdhc model's training step on a real-dance window**: the defaults' window (batches of 8,
300 counted frames after a context of 264, 153 features, 69 outputs, music only) computed as
training computes it (``skip``: only what the counted frames read; the skeleton encoder's codes of
its zero input from one short pass) against the whole window through every module and cut after
the context (the same weights, the same gradients to float rounding), in the same run.
"""

from __future__ import annotations

import os
import time
import warnings

import numpy as np
import torch

from kinectdata.inference.engines import OnnxRuntimeEngine, onnxruntime_available
from kinectdata.models.losses import masked_mse
from kinectdata.models.yalta import StreamingYalta, YaltaConfig, YaltaNet
from kinectdata.training.config import TrainConfig
from kinectdata.training.train import _add_gradient_noise

from .summary import record

D = 65
WARMUP, FRAMES = 100, 1500
PLAIN = "YaltaNet one frame per call (torch LSTM)"
DEFAULT_ENGINE = "StreamingYalta eager float32"  # what `generate` runs by default (engine torch, float32)
GENERATION_GOAL = 8.0  # issue 16: the default engine's per-frame latency at least 8x better than PLAIN's


def _net(units: int) -> YaltaNet:
    torch.manual_seed(0)
    return YaltaNet(YaltaConfig(output_dim=D, units=units)).eval()


def _features(n: int) -> torch.Tensor:
    return 0.1 + 0.8 * torch.rand(n, 1, 129, 5, generator=torch.Generator().manual_seed(1))


def _summary(times: list[float]) -> tuple[float, float]:
    t = np.array(times[WARMUP:]) * 1e3
    return float(np.median(t)), float(np.percentile(t, 95))


def time_stream(module, features: torch.Tensor) -> tuple[float, float]:
    state, pose, times = module.initial_state(), torch.zeros(D), []
    with torch.inference_mode():
        for k in range(features.shape[0]):
            start = time.perf_counter()
            pose, *state = module(features[k], pose, *state)
            times.append(time.perf_counter() - start)
    return _summary(times)


def time_sequence_net(net: YaltaNet, features: torch.Tensor) -> tuple[float, float]:
    s1 = s2 = None
    pose, times = torch.zeros(1, D), []
    with torch.inference_mode():
        for k in range(features.shape[0]):
            start = time.perf_counter()
            codes, s1 = net.encode(features[k][None, None], s1)
            out, s2 = net.decode(codes, pose, "predicted", s2)
            pose = out[:, 0]
            times.append(time.perf_counter() - start)
    return _summary(times)


def time_onnx(net: YaltaNet, features: torch.Tensor) -> tuple[float, float] | None:
    if not onnxruntime_available():
        return None
    engine = OnnxRuntimeEngine(net, threads=1)
    pose, times = np.zeros(D, np.float32), []
    x = features.numpy()
    for k in range(x.shape[0]):
        start = time.perf_counter()
        pose = engine.step(x[k], pose)
        times.append(time.perf_counter() - start)
    return _summary(times)


def script(net: YaltaNet, precision: str):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        return torch.jit.script(StreamingYalta(net, precision).eval())


def half_precision_error(net: YaltaNet, frames: int = 300) -> float:
    features = _features(frames)
    outputs = []
    for precision in ("float32", "float16"):
        module = StreamingYalta(net, precision)
        state, pose, out = module.initial_state(), torch.zeros(D), []
        with torch.inference_mode():
            for k in range(frames):
                pose, *state = module(features[k], pose, *state)
                out.append(pose)
        outputs.append(torch.stack(out))
    return float((outputs[0] - outputs[1]).abs().max())


def latency() -> None:
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    features = _features(WARMUP + FRAMES)
    print(f"streaming latency per frame, batch 1, one thread, {FRAMES} frames (ms median / p95):")
    try:
        for units in (500, 250, 1000):
            net = _net(units)
            rows = {}
            if units == 500:
                rows[PLAIN] = time_sequence_net(net, features)
                rows[DEFAULT_ENGINE] = time_stream(StreamingYalta(net), features)
            rows["StreamingYalta TorchScript float32"] = time_stream(script(net, "float32"), features)
            rows["StreamingYalta TorchScript float16 weights"] = time_stream(script(net, "float16"), features)
            onnx = time_onnx(net, features)
            if onnx is not None:
                rows["ONNX Runtime float32"] = onnx
            for name, (median, p95) in rows.items():
                mark = "  <= 2 ms" if units == 500 and median <= 2.0 else ""
                if units == 500 and name != PLAIN:
                    record("generation", f"yalta 500 units, {name}, per frame", f"{median:.2f} ms (p95 {p95:.2f})")
                print(f"  {units:>4} units  {name:<44} {median:6.3f} / {p95:6.3f}{mark}")
            if units == 500:
                ratio = rows[PLAIN][0] / rows[DEFAULT_ENGINE][0]
                verdict = "met" if ratio >= GENERATION_GOAL else "not met"
                print(
                    f"  default engine (torch float32: {DEFAULT_ENGINE}) against the plain model per frame: "
                    f"{ratio:.1f}x (goal >= {GENERATION_GOAL:g}x: {verdict})"
                )
                record("generation", "yalta 500 units, default engine against plain PyTorch", f"{ratio:.1f}x")
        error = half_precision_error(_net(500))
        print(f"  float16 weights: max deviation from float32 over 300 fed-back frames {error:.1e}")
    finally:
        torch.set_num_threads(threads)


def _training_setup(config: TrainConfig):
    """A fresh paper-size network in training mode, its Adam, and one random batch: features [B, T,
    1, 129, 5], poses and the poses before them [B, T, D], an all-true mask."""
    torch.manual_seed(0)
    net = YaltaNet(YaltaConfig(output_dim=D, units=config.units)).train()
    optimizer = torch.optim.Adam(net.parameters(), lr=config.lr)
    g = torch.Generator().manual_seed(3)
    shape = (config.batch_size, config.sequence)
    audio = 0.1 + 0.8 * torch.rand(*shape, 1, 129, 5, generator=g)
    pose = torch.rand(*shape, D, generator=g) * 1.8 - 0.9
    previous = torch.cat([pose[:, :1], pose[:, :-1]], dim=1)
    return net, optimizer, (audio, pose, previous, torch.ones_like(pose, dtype=torch.bool))


def training_throughput(steps: int = 2) -> None:
    config = TrainConfig(paper=True)  # the paper-size network and batches the docs describe
    print(
        f"training throughput: {config.units} units, sequences of {config.sequence}, batches of "
        f"{config.batch_size}, {torch.get_num_threads()} threads, {steps} timed steps after one warm-up:"
    )
    for feedback in ("predicted", "teacher"):
        net, optimizer, (audio, pose, previous, mask) = _training_setup(config)
        noise = torch.Generator().manual_seed(2)
        times = []
        for step in range(steps + 1):
            start = time.perf_counter()
            out = net(audio, previous if feedback == "teacher" else previous[:, 0], feedback)
            loss = masked_mse(out, pose, mask)
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            _add_gradient_noise(list(net.parameters()), step, config, noise)
            optimizer.step()
            times.append(time.perf_counter() - start)
        seconds = float(np.mean(times[1:]))
        frames = config.batch_size * config.sequence
        rate = frames / seconds
        print(f"  {feedback:<9} feedback: {seconds:6.2f} s per batch of {frames} frames = {rate:7.0f} frames/s")
        record(
            "training",
            f"yalta step, batch {config.batch_size} x {config.sequence}, {feedback} feedback",
            f"{seconds:.2f} s ({rate:.0f} frames/s)",
        )


TRAINING_GOAL = 1.5  # issue 16: training at least 1.5x a plain PyTorch implementation of the same model and loop
_OP_GROUPS = {
    "convolutions": ("convolution",),
    "LSTMs": ("rnn", "lstm"),
    "batch normalisation": ("batch_norm",),
    "activations (ELU)": ("elu",),
}


def _op_group(name: str) -> str:
    low = name.lower()
    return next((group for group, keys in _OP_GROUPS.items() if any(k in low for k in keys)), "the rest")


def _sgemm_rate(size: int = 2048, repeats: int = 5) -> float:
    """GFLOP/s of one float32 [size, size] @ [size, size] product on torch's threads: what this
    machine's CPU does at best in float32 (best of ``repeats``)."""
    a = torch.rand(size, size)
    b = torch.rand(size, size)
    a @ b
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        a @ b
        best = min(best, time.perf_counter() - start)
    return 2 * size**3 / best / 1e9


def training_profile(feedback: str = "teacher") -> None:
    """Where one paper-size training step's time goes (torch.profiler, self CPU time by operator
    kind), the convolutions' rate against this machine's float32 matrix product, and what that
    leaves for issue 16's goal: kinectdata trains the plain PyTorch modules (nn.Conv2d, nn.BatchNorm2d,
    nn.LSTM, Adam), so a faster loop would have to cut the time of these operators themselves."""
    from torch.profiler import ProfilerActivity, profile

    config = TrainConfig(paper=True)  # the paper-size network and batches the docs describe
    net, optimizer, (audio, pose, previous, mask) = _training_setup(config)

    def step() -> None:
        out = net(audio, previous if feedback == "teacher" else previous[:, 0], feedback)
        optimizer.zero_grad(set_to_none=True)
        masked_mse(out, pose, mask).backward()
        optimizer.step()

    step()
    with profile(activities=[ProfilerActivity.CPU]) as prof:
        step()
    groups: dict[str, float] = {}
    for event in prof.key_averages():
        if event.key.startswith("aten::"):
            groups[_op_group(event.key)] = groups.get(_op_group(event.key), 0.0) + event.self_cpu_time_total / 1e6
    total = sum(groups.values())
    frames = config.batch_size * config.sequence
    convs = [m for m in net.convs if isinstance(m, torch.nn.Conv2d)]
    outputs = [(97, 4), (65, 3), (33, 2), (1, 1)]  # each convolution's output height x width (129 x 5 in)
    macs = [
        frames * m.out_channels * m.in_channels * m.kernel_size[0] * m.kernel_size[1] * h * w
        for m, (h, w) in zip(convs, outputs)
    ]
    # forward and weight gradient for all four; input gradient for all but the first (its input is the data)
    flops = 2 * (2 * sum(macs) + sum(macs[1:]))
    conv_rate = flops / groups["convolutions"] / 1e9
    peak = _sgemm_rate()
    print(f"where a {feedback}-feedback training step's operator time goes (torch.profiler, self CPU time):")
    for group, seconds in sorted(groups.items(), key=lambda kv: -kv[1]):
        print(f"  {group:<22} {seconds:6.2f} s  {100 * seconds / total:4.0f} %")
    print(
        f"  the convolutions run at {conv_rate:.0f} GFLOP/s, {100 * conv_rate / peak:.0f} % of this machine's float32 "
        f"matrix product ({peak:.0f} GFLOP/s, 2048 x 2048, {torch.get_num_threads()} threads)"
    )
    bound = total / (groups["convolutions"] * conv_rate / peak)
    print(
        f"  kinectdata trains these plain PyTorch modules, so against plain PyTorch it is 1.0x (goal >= "
        f"{TRAINING_GOAL:g}x: not met); convolutions at the matrix product's full rate with every other "
        f"operator free would make the step {bound:.1f}x faster"
    )
    share = 100 * groups["convolutions"] / total
    record("training", f"yalta {feedback}-feedback step: share in convolutions", f"{share:.0f} %")


def yalta_bfloat16_step(steps: int = 3) -> None:
    """Seconds per optimisation step of the yalta defaults' network (128 units, teacher feedback
    and its free run, 2-channel real-dance features, batches of 8 x 300) in float32 and with
    ``--precision bfloat16`` (the convolutions under autocast, the LSTMs in float32), interleaved
    in the same run; on a CPU without native bfloat16 it says so and measures nothing."""
    from kinectdata.training.train import native_bfloat16

    if not native_bfloat16(torch.device("cpu")):
        print("yalta step in bfloat16: this CPU has no native bfloat16 (train-baseline trains in float32 there)")
        return
    torch.manual_seed(0)
    net = YaltaNet(YaltaConfig(output_dim=75, units=128, input_shape=(2, 129, 5))).train()
    optimizer = torch.optim.Adam(net.parameters(), lr=1e-3)
    g = torch.Generator().manual_seed(3)
    audio = torch.rand(8, 300, 2, 129, 5, generator=g)
    pose = torch.rand(8, 300, 75, generator=g) * 1.8 - 0.9
    previous = torch.cat([pose[:, :1], pose[:, :-1]], dim=1)

    def step(precision: str, update: bool = True) -> torch.Tensor:
        with torch.autocast("cpu", dtype=torch.bfloat16, enabled=precision == "bfloat16"):
            poses, free = net(audio, previous, "teacher", free=True)
        loss = (poses.float() - pose).abs().mean() + (free.float() - pose).abs().mean()
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        gradient = [p.grad.clone() for p in net.parameters()]
        if update:
            optimizer.step()
        return gradient

    exact, rounded = step("float32", update=False), step("bfloat16", update=False)
    # per weight matrix or kernel: the convolutions' gradients are small beside fc2's, so a
    # whole-gradient figure would hide what bfloat16 changes; biases are left out, as the
    # convolutions' (batch normalisation after them) have a gradient of 0 but for rounding
    difference = max(float((r - e).norm() / e.norm()) for r, e in zip(rounded, exact) if e.dim() > 1)
    times: dict[str, list[float]] = {"float32": [], "bfloat16": []}
    for _ in range(steps + 1):
        for precision in times:
            start = time.perf_counter()
            step(precision)
            times[precision].append(time.perf_counter() - start)
    seconds = {k: float(np.median(v[1:])) for k, v in times.items()}
    print(f"yalta training step, 128 units, teacher feedback and its free run, batches of 8 x 300, {steps} steps each:")
    for precision, value in seconds.items():
        print(f"  {precision:<9} {value:6.2f} s per step")
    ratio = seconds["float32"] / seconds["bfloat16"]
    print(
        f"  bfloat16 {ratio:.2f}x faster than float32; each weight matrix's gradient within "
        f"{100 * difference:.1f} % of float32's"
    )
    record("training", "yalta step on a real-dance window, bfloat16 against float32", f"{ratio:.2f}x")


def _whole_window(net, audio: torch.Tensor, context: int) -> torch.Tensor:
    """The cdhc network's poses of frames ``context``.. with every module run over the whole
    window, the skeleton encoder over each window's zero input: the step before ``skip``."""
    codes, _ = net.audio_encoder(audio)
    skeleton, _ = net.skeleton_encoder(torch.zeros(*audio.shape[:2], net.config.output_dim))
    return net.decoder(codes, skeleton)[0][:, context:]


def cdhc_training_step(steps: int = 3) -> None:
    """Seconds per optimisation step (forward, L1, backward, Adam) of the cdhc defaults' network on
    a real-dance window, computed as training does against the whole window (module docstring)."""
    from kinectdata.models.cdhc import CdhcConfig, CdhcNet, history

    torch.manual_seed(0)
    sizes = {"channels": 128, "decoder_channels": 128, "dropout": 0.0, "coordinates": 69, "joint_dims": 3}
    config = CdhcConfig(output_dim=69, input_dim=153, **sizes, limbs=(), output="linear", inputs="music")
    net = CdhcNet(config).train()
    context = config.receptive_field - 1
    optimizer = torch.optim.Adam(net.parameters(), lr=1e-3)
    g = torch.Generator().manual_seed(3)
    audio = torch.rand(8, 300 + context, 153, generator=g)
    target = torch.rand(8, 300, 69, generator=g) * 1.8 - 0.9
    previous = torch.zeros(8, 300 + context, 69)
    ways = {
        "whole window, cut after the context": lambda: _whole_window(net, audio, context),
        "as training computes it (skip)": lambda: net(audio, previous, skip=context),
    }
    times = {}
    for _ in range(steps + 1):  # interleaved: the machine's load falls on both alike
        for name, poses in ways.items():
            start = time.perf_counter()
            loss = (poses() - target).abs().mean()
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            optimizer.step()
            times.setdefault(name, []).append(time.perf_counter() - start)
    print(
        f"cdhc training step: batches of 8 x (300 + {context} of context) frames, 128 channels, "
        f"{torch.get_num_threads()} threads, {steps} timed steps each after one warm-up "
        f"(the decoder reads {history(net.decoder.blocks)} frames back):"
    )
    seconds = {name: float(np.median(t[1:])) for name, t in times.items()}
    whole, skipped = seconds.values()
    for name, value in seconds.items():
        print(f"  {name:<36} {value:6.3f} s per step")
    print(f"  {whole / skipped:.2f}x faster than the whole window")
    record("training", "cdhc step on a real-dance window, against the whole window", f"{whole / skipped:.2f}x")


def main() -> None:
    print(f"torch {torch.__version__}, {os.cpu_count()} cores")
    latency()
    training_throughput()
    training_profile()
    cdhc_training_step()
    yalta_bfloat16_step()


if __name__ == "__main__":
    main()
