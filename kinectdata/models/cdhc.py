"""The causal dilated highway convolution (CDHC) encoder-decoder of Lee, Kim, Lee (2018),
"Listen to Dance: Music-driven choreography generation using Autoregressive Encoder-Decoder Network".

Per motion frame t (30 fps), from audio features [T, F] and the previous poses [T, D] (``previous[t]``
is the pose of frame t-1):

- an audio encoder and a skeleton encoder of the same shape: three 1x1 convolutions (F or D -> C,
  C -> C, C -> C, ReLU between them; 1x1 for the first too, as in DC-TTS's audio encoder: any
  temporal context comes from the highway blocks, which keeps every layer's look-back explicit),
  then highway blocks with dilations 1, 3, 9, 27, 1, 3, 9, 27, 3, 3 (C = 256 channels);
- gated fusion of the audio code A and the skeleton code S: ``g = sigmoid(1x1 conv(concat(A, S)))``
  (C channels), ``fused = 1x1 conv to 128 channels of (g * A + (1 - g) * S)``. The paper only says
  it "fuses the two codes with a 1x1 conv (128 channels)"; our specification asks for the gate;
- a decoder: highway blocks with dilations 1, 3, 9, 27, 3, 3 at 128 channels, three 128-channel
  1x1 convolutions each followed by tanh, a 1x1 convolution to D and a sigmoid (targets are
  normalised into 0..1). 1x1 convolutions are ``nn.Linear`` layers over each frame's channels
(the same parameters, and the same code for a sequence [B, T, C] and one frame [B, C]).

A highway block is DC-TTS's (Tachibana et al. 2018, and Kyubyong Park's implementation):
``H = causal dilated conv(X)`` with 2C channels (kernel k, left padding (k-1) * dilation);
``H1, H2 = split(H)``; each half is layer-normalised over its C channels (separately, with its own
gain and bias, per frame); ``Y = dropout(sigmoid(H1) * H2 + (1 - sigmoid(H1)) * X)``. Dropout is
applied there only, to each block's output. Every layer mixes only the present and past frames,
so output t depends on frames t - R + 1 .. t (R = :attr:`CdhcNet.receptive_field`, 265 frames,
8.8 s at 30 fps, with the default sizes).

With the default pose layout (D = 44, ``OPENPOSE_MPI_LIMBS``), the first 30 components are the
``openpose_mpi`` joints' x, y (Head, Neck, RShoulder, RElbow, RWrist, LShoulder, LElbow, LWrist,
RHip, RKnee, RAnkle, LHip, LKnee, LAnkle, Chest) and the next 14 the lengths of the links from each
joint but the root Chest to its parent, all in per-video min-max units. :func:`cdhc_loss` is the L1
loss plus the limb-length loss. With ``output="residual"`` the decoder's last layer gives the change
from the previous pose, added to it (a residual connection to the output as in Martinez, Black,
Romero 2017, "On human motion prediction using recurrent neural networks"): on real dance the
paper's output, which must rebuild the whole pose from the codes, stays at the mean pose for
hundreds of steps (docs/training.md). :func:`generate` runs the network autoregressively with
:class:`StreamingCdhc`, one frame at a time with per-layer caches (O(T), not O(T^2)).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from kinectdata.core.errors import KinectDataError
from kinectdata.models.kind import check_inputs
from kinectdata.models.latent import PhraseCode, without_unused_code

OPENPOSE_MPI_LIMBS = (
    (0, 1),  # Head-Neck
    (1, 14),  # Neck-Chest
    (2, 1),  # RShoulder-Neck
    (3, 2),  # RElbow-RShoulder
    (4, 3),  # RWrist-RElbow
    (5, 1),  # LShoulder-Neck
    (6, 5),  # LElbow-LShoulder
    (7, 6),  # LWrist-LElbow
    (8, 14),  # RHip-Chest
    (9, 8),  # RKnee-RHip
    (10, 9),  # RAnkle-RKnee
    (11, 14),  # LHip-Chest
    (12, 11),  # LKnee-LHip
    (13, 12),  # LAnkle-LKnee
)
"""The 14 limbs of ``openpose_mpi`` as (joint, parent) indices into its 15 joints."""


OUTPUTS = ("sigmoid", "linear", "residual")


@dataclass(frozen=True)
class CdhcConfig:
    """The network's hyperparameters and the layout of its pose vectors.

    Attributes:
        output_dim: D, the pose vector's size (44 for the paper's layout).
        input_dim: F, audio features per frame (mel bands).
        channels: C, the encoders' width (256 in the paper).
        decoder_channels: the fused code's and the decoder's width (128).
        kernel_size: k of every highway block's causal convolution.
        dropout: dropout probability on each highway block's output (DC-TTS's 0.05).
        encoder_dilations: one highway block per dilation, in each encoder.
        decoder_dilations: one highway block per dilation, in the decoder.
        coordinates: the pose vector starts with this many joint coordinates (15 joints x 2 = 30).
        joint_dims: coordinates per joint (2: x, y); joint j is components ``joint_dims * j ..``.
        limbs: (joint, parent) index pairs; limb i's target length is component ``coordinates + i``.
            Empty: no limb-length loss.
        output: the last layer's activation: ``sigmoid`` for targets in 0..1 (the paper's per-video
            min-max coordinates), ``linear`` for targets normalised into -0.9..0.9 (any other dataset),
            ``residual`` for those too, the linear output being the change from the previous pose.
        leak: under a residual output, the share of the previous pose's distance from the anchor
            (the mean training pose, :func:`init_output_bias`) taken back every frame, 0..1: a pure
            sum of changes (0) drifts off the body over a song.
        inputs: ``music-and-poses`` (the paper's: the previous poses through the skeleton encoder)
            or ``music``: the skeleton encoder sees zeros whatever poses it is given, so each pose
            is a function of the music up to its frame (no feedback: the free run is the
            teacher-forced pass; needs a ``linear`` or ``sigmoid`` output).
        start_silence: frames of silence (zero features) the network hears before every song it
            generates, its outputs over them dropped, from :func:`generate` and from the streams'
            initial state alike: the silence its training windows had before each song
            (``TrainConfig.song_starts``: as many frames as its context). 0 (runs written before):
            the song starts with every layer's history zero. Only with ``inputs`` ``music``.
        latent_dims: the size of a phrase code added to the fused code (:mod:`kinectdata.models.latent`):
            inferred from the true poses in training, drawn in generation. 0: none (the paper's).
        phrase_frames: frames per phrase of the code.
        latent_draws: rows of the code's table of prior draws.
    """

    output_dim: int
    input_dim: int
    channels: int = 256
    decoder_channels: int = 128
    kernel_size: int = 3
    dropout: float = 0.05
    encoder_dilations: tuple[int, ...] = (1, 3, 9, 27, 1, 3, 9, 27, 3, 3)
    decoder_dilations: tuple[int, ...] = (1, 3, 9, 27, 3, 3)
    coordinates: int = 30
    joint_dims: int = 2
    limbs: tuple[tuple[int, int], ...] = OPENPOSE_MPI_LIMBS
    output: str = "sigmoid"
    leak: float = 0.0
    inputs: str = "music-and-poses"
    start_silence: int = 0
    latent_dims: int = 0
    phrase_frames: int = 60
    latent_draws: int = 64

    def __post_init__(self) -> None:
        if self.latent_dims < 0 or self.phrase_frames < 1 or self.latent_draws < 1:
            raise KinectDataError(
                f"CDHC config: latent_dims must be at least 0, phrase_frames and latent_draws positive, not "
                f"{self.latent_dims}, {self.phrase_frames}, {self.latent_draws}"
            )
        if not 0.0 <= self.leak <= 1.0:
            raise KinectDataError(f"CDHC config: leak must be in 0..1, not {self.leak}")
        check_inputs(self.inputs, "CDHC config: ")
        if self.inputs == "music" and self.output == "residual":
            raise KinectDataError("CDHC config: a residual output adds to the previous pose: inputs 'music' has none")
        if self.start_silence < 0 or (self.start_silence and self.inputs != "music"):
            raise KinectDataError(
                f"CDHC config: start_silence must be at least 0 (0 unless inputs is 'music'), not {self.start_silence}"
            )
        if self.output not in OUTPUTS:
            raise KinectDataError(f"CDHC config: output must be one of {', '.join(OUTPUTS)}, not {self.output!r}")
        sizes = {k: getattr(self, k) for k in ("output_dim", "input_dim", "channels", "decoder_channels")}
        sizes |= {"kernel_size": self.kernel_size, "joint_dims": self.joint_dims}
        for name, value in sizes.items():
            if value < 1:
                raise KinectDataError(f"CDHC config: {name} must be positive, not {value}")
        if not 0.0 <= self.dropout < 1.0:
            raise KinectDataError(f"CDHC config: dropout must be in [0, 1), not {self.dropout}")
        for name in ("encoder_dilations", "decoder_dilations"):
            if any(d < 1 for d in getattr(self, name)):
                raise KinectDataError(f"CDHC config: {name} must be positive, not {getattr(self, name)}")
        if self.coordinates < 0 or self.coordinates % self.joint_dims:
            raise KinectDataError(
                f"CDHC config: coordinates ({self.coordinates}) must be a multiple of joint_dims ({self.joint_dims})"
            )
        if self.coordinates + len(self.limbs) > self.output_dim:
            raise KinectDataError(
                f"CDHC config: {self.coordinates} coordinates and {len(self.limbs)} limb lengths do not fit "
                f"in output_dim {self.output_dim}"
            )
        joints = self.coordinates // self.joint_dims
        for i, (a, b) in enumerate(self.limbs):
            if not (0 <= a < joints and 0 <= b < joints) or a == b:
                raise KinectDataError(f"CDHC config: limb {i} ({a}, {b}) must join two of the {joints} joints")

    @property
    def receptive_field(self) -> int:
        """Frames an output sees, itself included: 1 + (k - 1) * (encoder + decoder dilations)."""
        return 1 + (self.kernel_size - 1) * (sum(self.encoder_dilations) + sum(self.decoder_dilations))

    def to_dict(self) -> dict:
        d = asdict(self)
        d["encoder_dilations"] = list(self.encoder_dilations)
        d["decoder_dilations"] = list(self.decoder_dilations)
        d["limbs"] = [list(pair) for pair in self.limbs]
        return without_unused_code(d)

    @classmethod
    def from_dict(cls, d: dict) -> CdhcConfig:
        d = dict(d)
        for name in ("encoder_dilations", "decoder_dilations"):
            if name in d:
                d[name] = tuple(d[name])
        if "limbs" in d:
            d["limbs"] = tuple(tuple(pair) for pair in d["limbs"])
        return cls(**d)


class CausalConv1d(nn.Conv1d):
    """A dilated Conv1d over channels-last [B, T, Cin] whose output t sees inputs t - (k-1) * dilation .. t
    (zeros before frame 0)."""

    def __init__(self, in_channels: int, out_channels: int, kernel_size: int, dilation: int):
        super().__init__(in_channels, out_channels, kernel_size, dilation=dilation)
        self.history = (kernel_size - 1) * dilation

    def forward(self, x: torch.Tensor, padded: bool = True) -> torch.Tensor:
        """[B, T, Cin] -> [B, T, Cout] with zeros before frame 0; unpadded, [B, T - history, Cout]:
        the first ``history`` rows of x serve as the history of the next one."""
        x = x.transpose(1, 2)
        return super().forward(F.pad(x, (self.history, 0)) if padded else x).transpose(1, 2)

    def step(self, x: torch.Tensor, cache: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """One frame x [B, Cin] and the previous ``history`` inputs [B, Cin, history] -> ([B, Cout], new cache)."""
        window = torch.cat([cache, x[:, :, None]], dim=2)
        # the k taps as one matrix product: torch's dilated conv1d is several times slower on one frame
        taps = window[:, :, :: self.dilation[0]].flatten(1)
        return F.linear(taps, self.weight.flatten(1), self.bias), window[:, :, 1:]


class Highway(nn.Module):
    """The DC-TTS highway block over [B, T, C] (see the module docstring)."""

    def __init__(self, channels: int, kernel_size: int, dilation: int, dropout: float):
        super().__init__()
        self.conv = CausalConv1d(channels, 2 * channels, kernel_size, dilation)
        self.gate_norm = nn.LayerNorm(channels)
        self.info_norm = nn.LayerNorm(channels)
        self.dropout = nn.Dropout(dropout)

    def _mix(self, h: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
        """H [..., 2C], X [..., C] -> Y [..., C]."""
        gate, info = h.chunk(2, dim=-1)
        gate = torch.sigmoid(self.gate_norm(gate))
        return self.dropout(gate * self.info_norm(info) + (1.0 - gate) * x)

    def forward(self, x: torch.Tensor, drop: int = 0) -> torch.Tensor:
        """X [B, T, C] -> Y [B, T - drop, C], the outputs of rows ``drop``.. of X. Dropped rows still
        serve as the convolution's history (zeros before row 0), so rows 0.. of X must be frames 0..
        unless ``drop`` is at least the block's history."""
        look_back = self.conv.history
        h = self.conv(x[:, drop - look_back :], padded=False) if drop >= look_back else self.conv(x)[:, drop:]
        return self._mix(h, x[:, drop:])

    def step(self, x: torch.Tensor, cache: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """One frame x [B, C] and the conv's cache -> ([B, C], new cache)."""
        h, cache = self.conv.step(x, cache)
        return self._mix(h, x), cache


def _highways(channels: int, dilations: tuple[int, ...], config: CdhcConfig) -> nn.ModuleList:
    return nn.ModuleList(Highway(channels, config.kernel_size, d, config.dropout) for d in dilations)


def history(blocks: nn.ModuleList) -> int:
    """Frames before its own that a stack of highway blocks' output depends on."""
    return sum(block.conv.history for block in blocks)


def _run_blocks(
    blocks: nn.ModuleList, x: torch.Tensor, caches: list[torch.Tensor] | None, skip: int = 0
) -> tuple[torch.Tensor, list[torch.Tensor]]:
    """Highway blocks over a sequence [B, T, C] (caches None) or one frame [B, C] with one cache per
    block. On a sequence whose rows are frames 0.., outputs of frames ``skip``.. only ([B, T - skip,
    C]): each block computes only the rows the blocks after it read, which on a training window
    with a long context saves a large share of the work."""
    if caches is None:
        start, wanted = 0, skip - history(blocks)  # the frame x's row 0 holds; the first one read of it
        for block in blocks:
            wanted += block.conv.history  # the first frame of this block's output that is read
            x = block(x, drop=max(wanted, 0) - start)
            start = max(wanted, 0)
        return x, []
    new = []
    for block, cache in zip(blocks, caches):
        x, cache = block.step(x, cache)
        new.append(cache)
    return x, new


class Encoder(nn.Module):
    """Three 1x1 convolutions (ReLU between them) and highway blocks: [B, T, in] -> [B, T, C].

    1x1 convolutions are ``nn.Linear`` over the channels of each frame (the same parameters).
    """

    def __init__(self, in_channels: int, config: CdhcConfig):
        super().__init__()
        c = config.channels
        self.convs = nn.Sequential(nn.Linear(in_channels, c), nn.ReLU(), nn.Linear(c, c), nn.ReLU(), nn.Linear(c, c))
        self.blocks = _highways(c, config.encoder_dilations, config)

    def forward(
        self, x: torch.Tensor, caches: list[torch.Tensor] | None = None, skip: int = 0
    ) -> tuple[torch.Tensor, list[torch.Tensor]]:
        """A sequence [B, T, in] -> ([B, T - skip, C] codes of frames ``skip``.., []), or one frame
        [B, in] and the blocks' caches -> ([B, C], new caches)."""
        return _run_blocks(self.blocks, self.convs(x), caches, skip)


class Decoder(nn.Module):
    """Gated fusion of the two codes, highway blocks, three 1x1 convs each followed by tanh, a 1x1
    conv to D and a sigmoid: audio and skeleton codes [B, T, C] -> poses [B, T, D] in 0..1."""

    def __init__(self, config: CdhcConfig):
        super().__init__()
        c, cd = config.channels, config.decoder_channels
        self.gate = nn.Linear(2 * c, c)
        self.fuse = nn.Linear(c, cd)
        self.blocks = _highways(cd, config.decoder_dilations, config)
        self.convs = nn.Sequential(*[m for _ in range(3) for m in (nn.Linear(cd, cd), nn.Tanh())])
        self.output = nn.Linear(cd, config.output_dim)
        self.squash = config.output == "sigmoid"

    def forward(
        self,
        audio: torch.Tensor,
        skeleton: torch.Tensor,
        caches: list[torch.Tensor] | None = None,
        skip: int = 0,
        phrase: torch.Tensor | None = None,
    ) -> tuple[torch.Tensor, list[torch.Tensor]]:
        """Codes [B, T, C] -> ([B, T - skip, D] poses of rows ``skip``.., []), or one frame of codes
        [B, C] and the blocks' caches -> ([B, D], new caches). Dropped rows still feed the blocks'
        history: rows 0.. must be frames 0.. unless ``skip`` is at least the blocks' history.
        ``phrase``: the projected phrase code ([B, T, decoder channels] or [B, decoder channels]),
        added to the fused code."""
        g = torch.sigmoid(self.gate(torch.cat([audio, skeleton], dim=-1)))
        fused = self.fuse(g * audio + (1.0 - g) * skeleton)
        x, caches = _run_blocks(self.blocks, fused if phrase is None else fused + phrase, caches, skip)
        out = self.output(self.convs(x))
        return (torch.sigmoid(out) if self.squash else out), caches


class CdhcNet(nn.Module):
    """The encoder-decoder for training and sequence evaluation (see the module docstring).

    With the default sizes, F = 80 and D = 44, it has 9,004,332 parameters.
    """

    def __init__(self, config: CdhcConfig):
        super().__init__()
        self.config = config
        self.audio_encoder = Encoder(config.input_dim, config)
        self.skeleton_encoder = Encoder(config.output_dim, config)
        self.decoder = Decoder(config)
        self.phrase_code = (
            PhraseCode(
                config.latent_dims,
                config.phrase_frames,
                config.output_dim,
                config.decoder_channels,
                config.latent_draws,
            )
            if config.latent_dims
            else None
        )
        self.latent_kl: torch.Tensor | None = None  # the last posterior pass's KL [B, phrases, dims]
        if config.output == "residual":  # the pose a leaky residual output returns to (init_output_bias)
            self.register_buffer("anchor", torch.zeros(config.output_dim))

    def seen_poses(self, previous: torch.Tensor) -> torch.Tensor:
        """What the skeleton encoder is given of the previous poses [..., D]: them, or zeros when
        the config's ``inputs`` is ``music``."""
        return torch.zeros_like(previous) if self.config.inputs == "music" else previous

    def add_change(self, change: torch.Tensor, previous: torch.Tensor) -> torch.Tensor:
        """A residual output's pose [..., D]: ``previous + change - leak * (previous - anchor)``."""
        leak = self.config.leak
        return previous + change - leak * (previous - self.anchor) if leak else previous + change

    @property
    def receptive_field(self) -> int:
        """Frames (at the motion rate) that output t depends on: t - R + 1 .. t, in both inputs."""
        return self.config.receptive_field

    def forward(
        self,
        audio: torch.Tensor,
        previous: torch.Tensor,
        free: bool = False,
        skip: int = 0,
        posterior: bool = False,
        draw: torch.Tensor | int = 0,
    ):
        """Poses from audio features and the previous poses (teacher forcing); with ``free``, also
        the free run from ``previous[:, 0]`` (the network fed its own outputs, frame by frame with
        the blocks' caches, differentiable): ``(poses, free poses)``.

        A network with a phrase code takes it, with ``posterior``, from the true poses in
        ``previous`` (training: its KL is kept in :attr:`latent_kl` for the loss), else from its
        table of draws from row ``draw`` on ([B] or one for all; frame 0 the first of a phrase).

        Args:
            audio: [B, T, F] features, frame t at the motion's frame t.
            previous: [B, T, D], ``previous[:, t]`` the pose of frame t-1 (the true poses shifted
                by one frame, the first being a start pose).
            skip: the first ``skip`` frames are input only (a training window's context): their
                poses are neither returned nor computed beyond what later frames depend on.

        Returns:
            [B, T - skip, D] poses of frames ``skip``.. (in 0..1 under a sigmoid output); frame t
            depends only on ``audio[:, :t+1]`` and ``previous[:, :t+1]``.
        """
        _check_inputs(self.config, audio, previous)
        if not 0 <= skip < audio.shape[1]:
            raise KinectDataError(f"CDHC input: skip must be in 0..{audio.shape[1] - 1}, not {skip}")
        first = max(skip - history(self.decoder.blocks), 0)  # the first frame whose codes the decoder reads
        steps_free = free and self.config.inputs != "music"  # the free run reads every frame's audio code
        codes, _ = self.audio_encoder(audio, skip=0 if steps_free else first)
        a = codes[:, first:] if steps_free else codes
        phrase = self._phrase(previous, posterior, draw)
        cut = None if phrase is None else phrase[:, first:]
        poses = self.decoder(a, self._skeleton_codes(previous, first), skip=skip - first, phrase=cut)[0]
        if self.config.output == "residual":
            poses = self.add_change(poses, previous[:, skip:])
        if not free:
            return poses
        if not steps_free:  # no feedback: running free is this same pass
            return poses, poses
        stream = StreamingCdhc(self)
        _, caches = stream.initial_state(audio.shape[0])
        pose, steps = previous[:, 0], []
        for t in range(audio.shape[1]):
            pose, caches = stream.decode(codes[:, t], pose, caches, None if phrase is None else phrase[:, t])
            steps.append(pose)
        return poses, torch.stack(steps[skip:], dim=1)

    def _phrase(self, previous: torch.Tensor, posterior: bool, draw: torch.Tensor | int) -> torch.Tensor | None:
        """The projected phrase code of every frame [B, T, decoder channels] (None without one)."""
        if self.phrase_code is None:
            return None
        if posterior:
            code, self.latent_kl = self.phrase_code.posterior(previous)
        else:
            code = self.phrase_code.drawn(previous.shape[0], previous.shape[1], draw)
        return self.phrase_code.project(code.to(previous.dtype))

    def _skeleton_codes(self, previous: torch.Tensor, first: int) -> torch.Tensor:
        """The skeleton encoder's codes [B, T - first, C] of frames ``first``.. of the previous poses [B, T, D]."""
        if self.config.inputs != "music" or (self.training and self.config.dropout > 0):
            return self.skeleton_encoder(self.seen_poses(previous), skip=first)[0]
        # Zeros in, the same for every window of the batch: the codes change only while the zero
        # padding before frame 0 is in view and are constant after it, so one short pass gives them all.
        span = min(previous.shape[1], history(self.skeleton_encoder.blocks) + 1)
        codes, _ = self.skeleton_encoder(previous.new_zeros(1, span, self.config.output_dim))
        rows = torch.arange(first, previous.shape[1], device=codes.device).clamp(max=span - 1)
        return codes[:, rows].expand(previous.shape[0], -1, -1)


def _check_inputs(config: CdhcConfig, audio: torch.Tensor, previous: torch.Tensor) -> None:
    if audio.dim() != 3 or audio.shape[-1] != config.input_dim or audio.shape[1] < 1:
        raise KinectDataError(f"CDHC input: audio must be [B, T >= 1, {config.input_dim}], not {list(audio.shape)}")
    if previous.dim() != 3 or previous.shape[-1] != config.output_dim or previous.shape[:2] != audio.shape[:2]:
        raise KinectDataError(
            f"CDHC input: previous poses must be [B, T, D] = {[*audio.shape[:2], config.output_dim]}, "
            f"not {list(previous.shape)}"
        )


class StreamingCdhc(nn.Module):
    """:class:`CdhcNet` one frame at a time, each causal convolution keeping its last (k-1) * dilation
    inputs in a cache carried by the caller.

    ``forward(audio [B, F], previous [B, D], audio_caches, pose_caches)`` returns the pose [B, D]
    and the new caches; start with :meth:`initial_state` (zeros, the zero padding before frame 0
    of :class:`CdhcNet`, after the config's ``start_silence``). A network with a phrase code also
    carries, last of the pose caches, the frames [B] counted since the start (its draw's offset
    included), which choose each frame's code from its table of draws. The audio encoder does not depend
    on the poses: when the whole audio is known, its codes can come from one parallel pass and
    :meth:`decode` does the rest. Results equal :meth:`CdhcNet.forward` over the same sequences up
    to float rounding. The network is shared, not copied, and evaluated in its current mode: call
    ``net.eval()`` first.
    """

    def __init__(self, net: CdhcNet):
        super().__init__()
        self.net = net

    def initial_state(
        self, batch: int = 1, draw: torch.Tensor | int = 0
    ) -> tuple[list[torch.Tensor], list[torch.Tensor]]:
        """The caches at a song's start for a batch, one [B, channels, history] tensor per highway
        block: (audio encoder's, skeleton encoder's and decoder's), and the frame counter of a
        phrase code (``draw`` phrases: the row of its table of draws the dance starts from, [B] or
        one for all). Zeros, then the config's ``start_silence`` frames of zero features stepped
        through (poses not used: music only)."""
        like = self.net.decoder.output.weight

        def zeros(blocks) -> list[torch.Tensor]:
            return [like.new_zeros(batch, b.conv.in_channels, b.conv.history) for b in blocks]

        pose_blocks = [*self.net.skeleton_encoder.blocks, *self.net.decoder.blocks]
        audio_caches, pose_caches = zeros(self.net.audio_encoder.blocks), zeros(pose_blocks)
        if self.net.phrase_code is not None:
            offset = torch.as_tensor(draw, dtype=like.dtype, device=like.device).reshape(-1).expand(batch)
            pose_caches.append(offset * self.net.config.phrase_frames)
        silence = like.new_zeros(batch, self.net.config.input_dim)
        nothing = like.new_zeros(batch, self.net.config.output_dim)
        with torch.no_grad():
            for _ in range(self.net.config.start_silence):
                _, audio_caches, pose_caches = self(silence, nothing, audio_caches, pose_caches)
        return audio_caches, pose_caches

    def decode(
        self,
        code: torch.Tensor,
        previous: torch.Tensor,
        pose_caches: list[torch.Tensor],
        phrase: torch.Tensor | None = None,
    ) -> tuple[torch.Tensor, list[torch.Tensor]]:
        """One frame from its audio code [B, C] and the previous pose [B, D] -> ([B, D] pose, new
        caches). ``phrase``: the projected phrase code [B, decoder channels] to use instead of the
        drawn one (a free run in training, on the posterior's codes)."""
        n = len(self.net.skeleton_encoder.blocks)
        m = n + len(self.net.decoder.blocks)
        counted = []
        if self.net.phrase_code is not None:
            frame = pose_caches[m]
            if phrase is None:
                phrase = self.net.phrase_code.project(self.net.phrase_code.at_frame(frame).to(code.dtype))
            counted = [frame + 1]
        s, skeleton_caches = self.net.skeleton_encoder(self.net.seen_poses(previous), pose_caches[:n])
        pose, decoder_caches = self.net.decoder(code, s, pose_caches[n:m], phrase=phrase)
        if self.net.config.output == "residual":
            pose = self.net.add_change(pose, previous)
        return pose, skeleton_caches + decoder_caches + counted

    def forward(
        self,
        audio: torch.Tensor,
        previous: torch.Tensor,
        audio_caches: list[torch.Tensor],
        pose_caches: list[torch.Tensor],
    ) -> tuple[torch.Tensor, list[torch.Tensor], list[torch.Tensor]]:
        code, audio_caches = self.net.audio_encoder(audio, audio_caches)
        pose, pose_caches = self.decode(code, previous, pose_caches)
        return pose, audio_caches, pose_caches


class FrameCdhc(nn.Module):
    """:class:`StreamingCdhc` for one unbatched frame with its caches as one flat state, the stream
    interface of :class:`kinectdata.models.kind.Stream`: ``forward(features [F], previous [D], *caches)``
    returns ``(pose [D], *new caches)``, the audio encoder's caches first, then the skeleton
    encoder's and the decoder's, and for a network with a phrase code the frame counter [1] (from
    phrase ``draw`` of its table of draws)."""

    def __init__(self, net: CdhcNet, draw: int = 0):
        super().__init__()
        self.stream = StreamingCdhc(net.eval())
        self.audio_blocks = len(net.audio_encoder.blocks)
        self.draw = draw

    def initial_state(self) -> tuple[torch.Tensor, ...]:
        audio_caches, pose_caches = self.stream.initial_state(draw=self.draw)
        return (*audio_caches, *pose_caches)

    def forward(self, features: torch.Tensor, previous: torch.Tensor, *state: torch.Tensor):
        n = self.audio_blocks
        pose, audio_caches, pose_caches = self.stream(features[None], previous[None], list(state[:n]), list(state[n:]))
        return (pose[0], *audio_caches, *pose_caches)


def generate(
    net: CdhcNet, audio: torch.Tensor | np.ndarray, first_pose: torch.Tensor | np.ndarray, draw: int = 0
) -> np.ndarray:
    """Dance for a whole audio feature sequence, autoregressively.

    The previous pose at frame 0 is ``first_pose``, at frame t the network's own output at t-1;
    a music-only network hears its config's ``start_silence`` frames of silence before frame 0.
    The audio codes come from one pass of the (causal) audio encoder, then
    :meth:`StreamingCdhc.decode` steps frame by frame, in evaluation mode (no dropout; the net's
    mode is restored after), on the net's device and dtype.

    Args:
        net: a trained network.
        audio: [T, F] features at the motion's frame rate.
        first_pose: [D], normalised (e.g. the mean training pose).
        draw: a network with a phrase code: the row of its table of draws the dance starts from
            (another draw, another dance to the same music).

    Returns:
        [T, D] float32 poses in 0..1.
    """
    return generate_many(net, [audio], [first_pose], [draw])[0]


def generate_many(
    net: CdhcNet,
    audios: list[torch.Tensor | np.ndarray],
    first_poses: list[torch.Tensor | np.ndarray],
    draws: list[int] | None = None,
) -> list[np.ndarray]:
    """:func:`generate` for several songs at once, stepped as one batch: the per-frame cost is
    mostly fixed, so N songs cost little more than the longest one. Shorter songs are padded
    with zero features at their end, which (the network being causal) leaves their frames as
    :func:`generate` makes them, up to float rounding.

    Args:
        audios: N feature sequences [T_i, F].
        first_poses: N poses [D].
        draws: N draws (:func:`generate`'s ``draw``; None: 0 for each).

    Returns:
        N arrays [T_i, D] float32 in 0..1.
    """
    config = net.config
    like = net.decoder.output.weight
    if len(audios) != len(first_poses) or not audios:
        raise KinectDataError(f"CDHC generate: {len(audios)} songs but {len(first_poses)} first poses")
    audios = [torch.as_tensor(a).to(like) for a in audios]
    poses = [torch.as_tensor(p).to(like) for p in first_poses]
    for a, p in zip(audios, poses):
        if a.dim() != 2 or a.shape[1] != config.input_dim or len(a) < 1:
            raise KinectDataError(f"CDHC generate: audio must be [T >= 1, {config.input_dim}], not {list(a.shape)}")
        if p.shape != (config.output_dim,):
            raise KinectDataError(f"CDHC generate: first_pose must be [{config.output_dim}], not {list(p.shape)}")
    draw = torch.as_tensor([0] * len(audios) if draws is None else draws, device=like.device)
    if draw.shape != (len(audios),):
        raise KinectDataError(f"CDHC generate: {len(audios)} songs but {draw.numel()} draws")
    lengths = [len(a) for a in audios]
    audio = torch.zeros(len(audios), max(lengths), config.input_dim, dtype=like.dtype, device=like.device)
    for i, a in enumerate(audios):
        audio[i, : len(a)] = a
    stream = StreamingCdhc(net)
    was_training = net.training
    net.eval()
    try:
        with torch.inference_mode():
            if config.inputs == "music":  # nothing fed back: the whole song in one causal pass
                silence = config.start_silence
                audio = torch.cat([audio.new_zeros(len(audios), silence, config.input_dim), audio], dim=1)
                nothing = torch.zeros(*audio.shape[:2], config.output_dim, dtype=like.dtype, device=like.device)
                out = net(audio, nothing, skip=silence, draw=draw)
                return [out[i, :n].float().cpu().numpy() for i, n in enumerate(lengths)]
            codes, _ = net.audio_encoder(audio)
            _, caches = stream.initial_state(len(audios), draw)
            out = torch.empty(len(audios), max(lengths), config.output_dim, dtype=like.dtype, device=like.device)
            pose = torch.stack(poses)
            for t in range(max(lengths)):
                pose, caches = stream.decode(codes[:, t], pose, caches)
                out[:, t] = pose
    finally:
        net.train(was_training)
    out = out.float().cpu().numpy()
    return [out[i, :n] for i, n in enumerate(lengths)]


def init_output_bias(net: CdhcNet, mean_pose: torch.Tensor | np.ndarray) -> None:
    """Set the last convolution's bias so that a net whose last layer's input is near zero starts
    at the mean pose: logit(``mean_pose`` clipped to 0.01..0.99) under a sigmoid output (``mean_pose``
    [D] in 0..1), the mean pose itself under a linear one; under a residual output, no change (0),
    and the mean pose becomes the anchor its leak returns to."""
    mean = np.asarray(torch.as_tensor(mean_pose).detach().cpu(), dtype=np.float64)
    if mean.shape != (net.config.output_dim,):
        raise KinectDataError(f"CDHC mean pose must be [{net.config.output_dim}], not {list(mean.shape)}")
    if not np.isfinite(mean).all():
        bad = np.flatnonzero(~np.isfinite(mean)).tolist()
        raise KinectDataError(f"CDHC mean pose: components {bad} are not finite (never valid in the data?)")
    p = np.clip(mean, 0.01, 0.99)
    bias = {"sigmoid": np.log(p / (1.0 - p)), "linear": mean, "residual": np.zeros_like(mean)}[net.config.output]
    with torch.no_grad():
        net.decoder.output.bias.copy_(torch.from_numpy(bias))
        if net.config.output == "residual":
            net.anchor.copy_(torch.from_numpy(mean))


def _limb_ends(config: CdhcConfig, device: torch.device) -> tuple[torch.Tensor, torch.Tensor]:
    """The limbs' joint and parent indices, [L] each."""
    ends = torch.tensor(config.limbs, dtype=torch.long, device=device).reshape(-1, 2)
    return ends[:, 0], ends[:, 1]


def limb_lengths(poses: torch.Tensor, config: CdhcConfig) -> torch.Tensor:
    """[..., D] poses -> [..., L] Euclidean lengths of the config's limbs, from the coordinates."""
    joints = poses[..., : config.coordinates].unflatten(-1, (-1, config.joint_dims))
    a, b = _limb_ends(config, poses.device)
    return torch.linalg.vector_norm(joints[..., a, :] - joints[..., b, :], dim=-1)


def cdhc_loss(
    pred: torch.Tensor,
    target: torch.Tensor,
    mask: torch.Tensor | None,
    config: CdhcConfig,
    limb_weight: float = 1.0,
) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    """The L1 loss plus the limb-length loss, over valid values (differentiable).

    - ``l1``: mean |pred - target| over the valid components (all D, limb lengths included);
    - ``limb``: mean |length of limb i from pred's coordinates - target's limb length i| over the
      (frame, limb) pairs where both joints' target coordinates and the target length are valid.

    A part with no valid value is 0. Invalid target values (NaN or anything) do not reach the loss
    or its gradient.

    Args:
        pred, target: [..., D] poses.
        mask: [..., D] bool, True where the target is valid (None: all valid).
        limb_weight: weight of the limb part in the total.

    Returns:
        (``l1 + limb_weight * limb``, {"l1": ..., "limb": ...}), scalar tensors.
    """
    if pred.shape != target.shape or pred.shape[-1] != config.output_dim:
        raise KinectDataError(
            f"CDHC loss: prediction {list(pred.shape)} and target {list(target.shape)} must both be [..., "
            f"{config.output_dim}]"
        )
    mask = torch.ones_like(target, dtype=torch.bool) if mask is None else mask.to(torch.bool)
    if mask.shape != target.shape:
        raise KinectDataError(f"CDHC loss: mask {list(mask.shape)} must match the target {list(target.shape)}")
    target = torch.where(mask, target, torch.zeros_like(target))
    l1 = _masked_mean((pred - target).abs(), mask)
    if not config.limbs:
        return l1, {"l1": l1, "limb": torch.zeros_like(l1)}
    joint_valid = mask[..., : config.coordinates].unflatten(-1, (-1, config.joint_dims)).all(dim=-1)
    a, b = _limb_ends(config, mask.device)
    span = slice(config.coordinates, config.coordinates + len(config.limbs))
    limb_valid = joint_valid[..., a] & joint_valid[..., b] & mask[..., span]
    limb = _masked_mean((limb_lengths(pred, config) - target[..., span]).abs(), limb_valid)
    return l1 + limb_weight * limb, {"l1": l1, "limb": limb}


def _masked_mean(values: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Mean of ``values`` where ``mask``; 0 when nothing is valid."""
    total = torch.where(mask, values, torch.zeros_like(values)).sum()
    return total / mask.sum().clamp(min=1).to(values.dtype)
