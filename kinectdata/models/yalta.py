"""The DCNN + deep LSTM of Yalta et al. (2016), "Sequential Deep Learning for Dancing Motion Generation".

Per motion frame (their Table 1):

- input [1, 129, 5] (the STFT features); four convolutions with 33x2 kernels and 16, 32, 64, 65
  channels, each followed by batch normalisation and the activation: 129x5 -> 97x4 -> 65x3 ->
  33x2 -> 1x1, a 65-value audio code;
- LSTM1-3 (three stacked LSTM layers of ``units`` each) over the codes; fc1 to 65 values and the
  activation;
- that, concatenated with the previous frame's pose (D values), goes through LSTM4-6 and fc2 to
  the pose (D values, no activation: the targets are normalised into -0.9..0.9).

Side channels (not the paper's): with ``side_channels`` = S, the last S input channels are
constant planes: the style input (:mod:`kinectdata.features.style_input`) and the pulse's
clocks (:data:`kinectdata.features.YALTA_CLOCK_PLANES`). They bypass the convolutions and LSTM1-3:
each plane's mean joins the fc1 code before LSTM4-6 (65 + S values): the decoder is told which
dance and where the beat and the bar are, and the convolutions, whose 33x2 kernels would otherwise
mix a constant plane into every spectral feature, hear the music alone, as in the paper.

The previous pose is the model's own previous output (``feedback="predicted"``, their Figure 4)
or the true one (``"teacher"``); with ``inputs="music"`` LSTM4-6 are given zeros in its place,
so each pose is a function of the music so far. The convolutions and LSTM1-3 do not depend on it, so they run over
a whole sequence at once; only LSTM4-6 and fc2 step frame by frame when the predictions are fed
back. :class:`StreamingYalta` is the same network one frame at a time, for live use and export.

A phrase code (not the paper's; ``latent_dims`` > 0, :mod:`kinectdata.models.latent`) joins
LSTM4-6's input after the previous pose: inferred from the true poses in training, drawn from the
network's table in generation (:class:`PhrasedStreamingYalta` carries the frame count that picks
each phrase's draw).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import torch
from torch import nn

from kinectdata.core.errors import ConfigError
from kinectdata.models.kind import check_inputs
from kinectdata.models.latent import PhraseCode, without_unused_code

ACTIVATIONS = {"tanh": nn.Tanh, "relu": nn.ReLU, "elu": nn.ELU}
CONV_CHANNELS = (16, 32, 64, 65)
KERNEL = (33, 2)
CODE = 65  # fc1 output and conv4 channels


@dataclass(frozen=True)
class YaltaConfig:
    """The network's hyperparameters.

    Attributes:
        output_dim: D, the pose vector's size (from the dataset's target spec).
        units: LSTM units per layer (the paper tries 250, 500, 1000).
        activation: ``tanh``, ``relu`` or ``elu`` (after each convolution and fc1).
        input_shape: (channels, frequency bins, STFT frames) of a frame's features.
        inputs: ``music-and-poses`` (the paper's: LSTM4-6 are given the previous pose) or
            ``music`` (they are given zeros in its place: no feedback).
        side_channels: S, the last input channels that bypass the convolutions (module docstring;
            0: every channel is convolved, as runs before them were).
        latent_dims: the size of a phrase code given to LSTM4-6 (0: none, the paper's).
        phrase_frames: frames per phrase of the code.
        latent_draws: rows of the code's table of prior draws.
    """

    output_dim: int
    units: int = 500
    activation: str = "elu"
    input_shape: tuple[int, int, int] = (1, 129, 5)
    inputs: str = "music-and-poses"
    side_channels: int = 0
    latent_dims: int = 0
    phrase_frames: int = 60
    latent_draws: int = 64

    def __post_init__(self) -> None:
        check_inputs(self.inputs)
        if self.latent_dims < 0 or self.phrase_frames < 1 or self.latent_draws < 1:
            raise ConfigError(
                f"latent_dims must be at least 0, phrase_frames and latent_draws positive, not "
                f"{self.latent_dims}, {self.phrase_frames}, {self.latent_draws}"
            )
        if not 0 <= self.side_channels < self.input_shape[0]:
            raise ConfigError(
                f"side_channels must leave at least one of the {self.input_shape[0]} input channels to convolve, "
                f"not {self.side_channels}"
            )
        if self.activation not in ACTIVATIONS:
            raise ConfigError(f"activation must be one of {', '.join(ACTIVATIONS)}, not {self.activation!r}")
        if self.units < 1 or self.output_dim < 1:
            raise ConfigError("units and output_dim must be positive")
        _, h, w = self.input_shape
        if (h - 4 * (KERNEL[0] - 1), w - 4 * (KERNEL[1] - 1)) != (1, 1):
            raise ConfigError(f"four 33x2 convolutions map {h}x{w} to 1x1 only for 129x5 inputs, not {h}x{w}")

    def to_dict(self) -> dict:
        d = asdict(self)
        d["input_shape"] = list(self.input_shape)
        return without_unused_code(d)

    @classmethod
    def from_dict(cls, d: dict) -> YaltaConfig:
        return cls(**{**d, "input_shape": tuple(d.get("input_shape", (1, 129, 5)))})


def _each_distinct_frame_once(convs: nn.Module, frames: torch.Tensor) -> torch.Tensor:
    """``convs(frames)`` [N, ...] with each distinct frame (equal bytes) computed once: the
    convolutions act on each frame alone (batch normalisation from its running statistics). On a
    GPU, or in a dtype numpy has not, every frame is convolved: finding the repeats would cost more."""
    if frames.device.type != "cpu" or frames.dtype not in (torch.float32, torch.float64, torch.float16):
        return convs(frames)
    flat = np.ascontiguousarray(frames.reshape(frames.shape[0], -1).cpu().numpy())
    keys = flat.view(np.dtype((np.void, flat.shape[1] * flat.itemsize))).ravel()
    _, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
    if first.size == frames.shape[0]:
        return convs(frames)
    return convs(frames[torch.from_numpy(first)])[torch.from_numpy(inverse.reshape(-1))]


def _in_float32(x: torch.Tensor):
    """A context with ``torch.autocast`` off on x's device: under a bfloat16 training step
    (``TrainConfig.precision``) the convolutions run in bfloat16 and the LSTMs, whose state is
    carried over hundreds of frames, in float32."""
    return torch.autocast(x.device.type, enabled=False)


class YaltaNet(nn.Module):
    """The network for training and sequence evaluation (see the module docstring)."""

    def __init__(self, config: YaltaConfig):
        super().__init__()
        self.config = config
        act = ACTIVATIONS[config.activation]
        layers: list[nn.Module] = []
        self.convolved = config.input_shape[0] - config.side_channels
        channels = (self.convolved, *CONV_CHANNELS)
        for cin, cout in zip(channels[:-1], channels[1:]):
            layers += [nn.Conv2d(cin, cout, KERNEL), nn.BatchNorm2d(cout), act()]
        self.convs = nn.Sequential(*layers)
        self.lstm1 = nn.LSTM(CODE, config.units, num_layers=3, batch_first=True)
        self.fc1 = nn.Sequential(nn.Linear(config.units, CODE), act())
        self.lstm2 = nn.LSTM(
            CODE + config.side_channels + config.output_dim + config.latent_dims,
            config.units,
            num_layers=3,
            batch_first=True,
        )
        self.fc2 = nn.Linear(config.units, config.output_dim)
        self.phrase_code = (
            PhraseCode(config.latent_dims, config.phrase_frames, config.output_dim, None, config.latent_draws)
            if config.latent_dims
            else None
        )
        self.latent_kl: torch.Tensor | None = None  # the last posterior pass's KL [B, phrases, dims]

    def encode(self, audio: torch.Tensor, state=None):
        """[B, T, C, 129, 5] features -> ([B, T, 65 + S] fc1 codes and the side channels' means,
        LSTM1-3 state).

        Outside training (evaluation mode, no gradient) the convolutions see each distinct frame
        once: a batch's padding, a silent song's frames and repeated inputs cost one frame each."""
        b, t = audio.shape[:2]
        frames = audio[:, :, : self.convolved].reshape(b * t, self.convolved, *audio.shape[3:])
        if self.training or torch.is_grad_enabled():
            codes = self.convs(frames).reshape(b, t, CODE)
        else:
            codes = _each_distinct_frame_once(self.convs, frames).reshape(b, t, CODE)
        with _in_float32(codes):
            hidden, state = self.lstm1(codes.to(self.lstm1.weight_ih_l0.dtype), state)
            code = self.fc1(hidden)
            if self.config.side_channels:
                side = audio[:, :, self.convolved :].mean(dim=(-2, -1))
                code = torch.cat([code, side.to(code.dtype)], dim=-1)
            return code, state

    def decode(
        self,
        codes: torch.Tensor,
        previous: torch.Tensor,
        feedback: str,
        state=None,
        phrase: torch.Tensor | None = None,
    ):
        """Poses from fc1 codes [B, T, 65 + S] (:meth:`encode`).

        Args:
            previous: ``teacher``: [B, T, D], the true pose before each frame; ``predicted``:
                [B, D], the true pose before the first frame (then the model's own outputs).
            state: LSTM4-6 state to start from (None: zeros).
            phrase: a network with a phrase code: each frame's code [B, T, latent dims].

        Returns:
            ([B, T, D] poses, LSTM4-6 state).
        """
        if (phrase is None) != (self.phrase_code is None):
            raise ConfigError("a network with a phrase code decodes with one, a network without none")
        with _in_float32(codes):
            dtype = self.fc2.weight.dtype
            return self._decode(
                codes.to(dtype), previous, feedback, state, None if phrase is None else phrase.to(dtype)
            )

    def _decode(self, codes: torch.Tensor, previous: torch.Tensor, feedback: str, state, phrase):
        if self.config.inputs == "music":
            previous = torch.zeros_like(previous)
        if feedback == "teacher" or self.config.inputs == "music":  # music only: no feedback to step
            if previous.dim() == 2:
                previous = previous[:, None].expand(-1, codes.shape[1], -1)
            given = [codes, previous] + ([] if phrase is None else [phrase])
            hidden, state = self.lstm2(torch.cat(given, dim=-1), state)
            return self.fc2(hidden), state
        if feedback != "predicted":
            raise ConfigError(f"feedback must be 'predicted' or 'teacher', not {feedback!r}")
        pose, outputs = previous, []
        for t in range(codes.shape[1]):
            given = [codes[:, t], pose] + ([] if phrase is None else [phrase[:, t]])
            hidden, state = self.lstm2(torch.cat(given, dim=-1)[:, None], state)
            pose = self.fc2(hidden[:, 0])
            outputs.append(pose)
        return torch.stack(outputs, dim=1), state

    def forward(
        self,
        audio: torch.Tensor,
        previous: torch.Tensor,
        feedback: str = "predicted",
        free: bool = False,
        posterior: bool = False,
        draw: torch.Tensor | int = 0,
    ):
        """[B, T, C, 129, 5] features and the previous poses (see :meth:`decode`; [B, T, D] also
        under ``predicted``, whose first pose is then the start) -> [B, T, D] poses.

        With ``free`` (``previous`` [B, T, D], the true poses before each frame), also the free run
        from the first of them on the same audio codes: ``(poses, free poses [B, T, D])``.

        A network with a phrase code takes it, with ``posterior``, from the true poses in
        ``previous`` [B, T, D] (training: its KL is kept in :attr:`latent_kl` for the loss), else from
        its table of draws from row ``draw`` on ([B] or one for all; frame 0 the first of a phrase).
        """
        codes, _ = self.encode(audio)
        phrase = self._phrase(previous, codes.shape[:2], posterior, draw)
        first = previous[:, 0] if previous.dim() == 3 else previous
        given = first if feedback == "predicted" else previous
        poses = self.decode(codes, given, feedback, phrase=phrase)[0]
        if not free:
            return poses
        if self.config.inputs == "music":  # the free run is this same pass
            return poses, poses
        return poses, self.decode(codes, first, "predicted", phrase=phrase)[0]

    def _phrase(
        self, previous: torch.Tensor, shape: torch.Size, posterior: bool, draw: torch.Tensor | int
    ) -> torch.Tensor | None:
        """Every frame's phrase code [B, T, latent dims] (None without one)."""
        if self.phrase_code is None:
            return None
        if not posterior:
            return self.phrase_code.drawn(shape[0], shape[1], draw)
        if previous.dim() != 3:
            raise ConfigError(f"a phrase code is inferred from the true poses [B, T, D], not {list(previous.shape)}")
        code, self.latent_kl = self.phrase_code.posterior(previous)
        return code


def _packed(lstm: nn.LSTM) -> tuple[list[torch.Tensor], list[torch.Tensor]]:
    """Per layer, [W_ih | W_hh] as [4 units, inputs + units] and b_ih + b_hh: one product per
    layer and step."""
    weights, biases = [], []
    for k in range(lstm.num_layers):
        w = torch.cat([getattr(lstm, f"weight_ih_l{k}"), getattr(lstm, f"weight_hh_l{k}")], dim=1)
        weights.append(w.detach().clone())
        biases.append((getattr(lstm, f"bias_ih_l{k}") + getattr(lstm, f"bias_hh_l{k}")).detach().clone())
    return weights, biases


def _folded_conv(conv: nn.Conv2d, bn: nn.BatchNorm2d) -> nn.Conv2d:
    """A convolution with the (evaluation-mode) batch normalisation after it folded in."""
    folded = nn.Conv2d(conv.in_channels, conv.out_channels, conv.kernel_size)
    scale = bn.weight / torch.sqrt(bn.running_var + bn.eps)
    with torch.no_grad():
        folded.weight.copy_(conv.weight * scale[:, None, None, None])
        folded.bias.copy_((conv.bias - bn.running_mean) * scale + bn.bias)
    return folded.requires_grad_(False)


class _Affine(nn.Module):
    """y = W x + b for one vector x, W stored in the layout fastest at batch 1 for its precision:
    float32 as [inputs, outputs] (x @ W: about 1.2x faster in torch than W @ x, and ONNX Runtime
    pre-packs it, where W @ x is several times slower), float16 as [outputs, inputs] (addmv: the
    half-precision x @ W is slow on CPUs). Returns x's dtype."""

    def __init__(self, weight: torch.Tensor, bias: torch.Tensor, dtype: torch.dtype):
        super().__init__()
        self.vector_matrix = dtype == torch.float32
        w = weight.detach().t() if self.vector_matrix else weight.detach()
        self.register_buffer("weight", w.contiguous().to(dtype))
        self.register_buffer("bias", bias.detach().clone().to(dtype))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if self.vector_matrix:
            return (x.to(self.weight.dtype) @ self.weight + self.bias).to(x.dtype)
        return torch.addmv(self.bias, self.weight, x.to(self.weight.dtype)).to(x.dtype)


class _PackedLSTM(nn.Module):
    """A stacked LSTM stepped one frame at a time: x [inputs], h and c [layers, units]."""

    def __init__(self, lstm: nn.LSTM, dtype: torch.dtype):
        super().__init__()
        self.cells = nn.ModuleList(_Affine(w, b, dtype) for w, b in zip(*_packed(lstm)))

    def forward(self, x: torch.Tensor, h: torch.Tensor, c: torch.Tensor):
        hs: list[torch.Tensor] = []
        cs: list[torch.Tensor] = []
        for k, cell in enumerate(self.cells):
            i, f, g, o = cell(torch.cat([x, h[k]])).chunk(4)
            ck = torch.sigmoid(f) * c[k] + torch.sigmoid(i) * torch.tanh(g)
            x = torch.sigmoid(o) * torch.tanh(ck)
            hs.append(x)
            cs.append(ck)
        return x, torch.stack(hs), torch.stack(cs)


class StreamingYalta(nn.Module):
    """:class:`YaltaNet` one frame at a time, with its state carried by the caller (TorchScript-able).

    ``forward(features [C, 129, 5], previous [D], h1, c1, h2, c2 [3, units])`` returns the pose
    [D] and the new states; start with :meth:`initial_state`. Batch normalisation is folded into
    the convolutions and each LSTM layer is one matrix-vector product. With ``precision="float16"``
    the LSTM and fc weights are stored in half precision: half the memory traffic per frame,
    which is what limits batch-1 speed on a CPU, at a cost measured in ``benchmarks/bench_model.py``.
    Weights are buffers: ``.to(device)`` moves them, ``state_dict()`` holds them.
    """

    def __init__(self, net: YaltaNet, precision: str = "float32"):
        super().__init__()
        if precision not in ("float32", "float16"):
            raise ConfigError(f"precision must be float32 or float16, not {precision!r}")
        net = net.eval()
        dtype = torch.float16 if precision == "float16" else torch.float32
        self.units = net.config.units
        self.activation = net.config.activation
        self.convolved = net.convolved
        self.side_channels = net.config.side_channels
        modules = list(net.convs)
        self.convs = nn.ModuleList(_folded_conv(c, bn) for c, bn in zip(modules[0::3], modules[1::3]))
        self.lstm1 = _PackedLSTM(net.lstm1, dtype)
        self.fc1 = _Affine(net.fc1[0].weight, net.fc1[0].bias, dtype)
        self.lstm2 = _PackedLSTM(net.lstm2, dtype)
        if net.config.inputs == "music":  # the pose's weights, zeroed, give what zeros in its place give
            with torch.no_grad():
                first = self.lstm2.cells[0].weight
                codes = CODE + net.config.side_channels
                poses = slice(codes, codes + net.config.output_dim)
                if self.lstm2.cells[0].vector_matrix:
                    first[poses] = 0
                else:
                    first[:, poses] = 0
        self.fc2 = _Affine(net.fc2.weight, net.fc2.bias, dtype)

    @torch.jit.export
    def initial_state(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        like = self.convs[0].weight  # float32 even with float16 LSTM weights, whose states stay float32
        z = torch.zeros(3, self.units, device=like.device, dtype=like.dtype)
        return z, z.clone(), z.clone(), z.clone()

    def _act(self, x: torch.Tensor) -> torch.Tensor:
        if self.activation == "tanh":
            return torch.tanh(x)
        if self.activation == "relu":
            return torch.relu(x)
        return torch.nn.functional.elu(x)

    def _audio_code(self, features: torch.Tensor, h1: torch.Tensor, c1: torch.Tensor):
        """The convolutions, LSTM1-3 and fc1 on one frame: (code [65 + S], h1, c1)."""
        x = features[None, : self.convolved]
        for conv in self.convs:
            x = self._act(conv(x))
        hidden, h1, c1 = self.lstm1(x.reshape(-1), h1, c1)
        code = self._act(self.fc1(hidden))
        if self.side_channels:
            code = torch.cat([code, features[self.convolved :].mean(dim=(1, 2))])
        return code, h1, c1

    def forward(
        self,
        features: torch.Tensor,
        previous: torch.Tensor,
        h1: torch.Tensor,
        c1: torch.Tensor,
        h2: torch.Tensor,
        c2: torch.Tensor,
    ):
        code, h1, c1 = self._audio_code(features, h1, c1)
        hidden, h2, c2 = self.lstm2(torch.cat([code, previous]), h2, c2)
        return self.fc2(hidden), h1, c1, h2, c2


class PhrasedStreamingYalta(StreamingYalta):
    """:class:`StreamingYalta` of a network with a phrase code: its state also carries the frames
    counted since the start [1] (from phrase ``draw`` of the table on), which pick each phrase's code
    from the network's table of draws: ``forward(features, previous, h1, c1, h2, c2, frame)``
    returns ``(pose, h1, c1, h2, c2, frame + 1)``."""

    def __init__(self, net: YaltaNet, precision: str = "float32", draw: int = 0):
        super().__init__(net, precision)
        if net.phrase_code is None:
            raise ConfigError("this network has no phrase code: StreamingYalta steps it")
        self.phrase = net.config.phrase_frames
        self.start = float(draw * net.config.phrase_frames)
        self.register_buffer("draws", net.phrase_code.draws.detach().clone())

    @torch.jit.export
    def initial_state(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        like = self.convs[0].weight
        z = torch.zeros(3, self.units, device=like.device, dtype=like.dtype)
        frame = torch.full((1,), self.start, device=like.device, dtype=like.dtype)
        return z, z.clone(), z.clone(), z.clone(), frame

    def forward(
        self,
        features: torch.Tensor,
        previous: torch.Tensor,
        h1: torch.Tensor,
        c1: torch.Tensor,
        h2: torch.Tensor,
        c2: torch.Tensor,
        frame: torch.Tensor,
    ):
        code, h1, c1 = self._audio_code(features, h1, c1)
        row = torch.div(frame, self.phrase, rounding_mode="floor").long() % self.draws.shape[0]
        phrase = self.draws[row].reshape(-1).to(code.dtype)
        hidden, h2, c2 = self.lstm2(torch.cat([code, previous, phrase]), h2, c2)
        return self.fc2(hidden), h1, c1, h2, c2, frame + 1


def free_run(
    net: YaltaNet, audio: np.ndarray, first_pose: np.ndarray, reset_every: int | None = None, draw: int = 0
) -> np.ndarray:
    """Poses [T-1, D] for frames 1..T-1 of features [T, 1, 129, 5], starting from the true pose
    [D] of frame 0 and then fed the model's own outputs, in evaluation mode (the net's mode is
    restored after). With ``reset_every`` = L every LSTM state is zeroed every L frames (the
    paper's "with reset"); the fed-back pose carries on. A phrase code is drawn from row ``draw``
    of the network's table on, its phrases counted from frame 1."""
    return free_runs(net, [audio], [first_pose], reset_every, [draw])[0]


def free_runs(
    net: YaltaNet,
    audios: list[np.ndarray],
    first_poses: list[np.ndarray],
    reset_every: int | None = None,
    draws: list[int] | None = None,
) -> list[np.ndarray]:
    """:func:`free_run` for several recordings as one batch (the per-frame cost is mostly fixed).
    Shorter feature sequences are padded with zeros at their end, which (the network being
    causal) leaves their frames as :func:`free_run` makes them, up to float rounding.

    Returns:
        per recording, poses [T_i - 1, D].
    """
    lengths = [len(a) - 1 for a in audios]
    longest = max(lengths)
    x = torch.zeros(len(audios), longest, *np.shape(audios[0])[1:])
    for i, a in enumerate(audios):
        x[i, : lengths[i]] = torch.from_numpy(np.ascontiguousarray(a[1:], np.float32))
    previous = torch.from_numpy(np.stack([np.asarray(p, np.float32) for p in first_poses]))
    pieces, step = [], reset_every or max(longest, 1)
    phrase, code = None, getattr(net, "phrase_code", None)  # a network written before codes has none
    if code is not None:
        phrase = code.drawn(len(audios), longest, torch.as_tensor([0] * len(audios) if draws is None else draws))
    was_training = net.training
    net.eval()  # batch normalisation from its running statistics: the padding must not enter them
    try:
        with torch.no_grad():
            for s in range(0, longest, step):
                codes, _ = net.encode(x[:, s : s + step])
                drawn = {} if phrase is None else {"phrase": phrase[:, s : s + step]}
                poses, _ = net.decode(codes, previous, "predicted", **drawn)
                pieces.append(poses.numpy())
                previous = poses[:, -1]
    finally:
        net.train(was_training)
    out = np.concatenate(pieces, axis=1) if pieces else np.zeros((len(audios), 0, net.config.output_dim), np.float32)
    return [out[i, :n] for i, n in enumerate(lengths)]
