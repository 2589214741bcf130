"""A phrase code: a small latent vector per phrase of the dance, so that a network that hears the
same music can still choose among the figures the dancers chose (a conditional VAE's latent, as in
Kingma and Welling 2014 and Sohn, Lee, Yan 2015, held for a phrase of frames).

A deterministic regressor trained on dances whose figures the music does not fix learns their
average: the legs of every bundled model swung at 0.4-0.65 x the dancers' (docs/notebook/
2026-12-real-dance-variety.md). With a phrase code the network is told, in training, which figure
the dancer chose, as a code inferred from the true poses of that phrase (the posterior, with a KL
term towards N(0, I)); in generation the code of each phrase is drawn from N(0, I).

Phrases are ``phrase`` frames long, counted from the first frame a network is given (a training
window's first row; a generated song's first frame, the silence before it included). The draws are
a table stored with the weights (``draws`` x ``dims``, from a fixed seed), and phrase ``i`` of a
dance with draw ``d`` takes row ``(d + i) mod draws``: generation is reproducible, every path (a
whole file, a batch of songs, the one-frame stream, an exported file) takes the same codes, and
``d`` chooses another dance for the same music.
"""

from __future__ import annotations

import torch
from torch import nn

from kinectdata.core.errors import KinectDataError

PHRASE_FIELDS = ("latent_dims", "phrase_frames", "latent_draws")
"""A network config's phrase code entries: a config without a code (``latent_dims`` 0) records none."""


def without_unused_code(config: dict) -> dict:
    """A network config's dict without its phrase code entries when it has no code."""
    return config if config.get("latent_dims") else {k: v for k, v in config.items() if k not in PHRASE_FIELDS}


DRAW_SEED = 20261206
"""The seed of every network's table of draws (the table is saved with its weights)."""


class PhraseCode(nn.Module):
    """The posterior encoder, the table of prior draws and the code's projection into a network.

    Args:
        dims: the code's size per phrase.
        phrase: frames per phrase.
        pose_dim: D, the pose vector's size.
        out_channels: the width the code is projected to (added to the network's own code); None:
            the code itself (joined to the network's inputs).
        draws: rows of the table of prior draws.
        width: the posterior encoder's hidden width.
    """

    def __init__(
        self, dims: int, phrase: int, pose_dim: int, out_channels: int | None, draws: int = 64, width: int = 128
    ):
        super().__init__()
        if min(dims, phrase, pose_dim, out_channels or 1, draws, width) < 1:
            raise KinectDataError(
                f"phrase code: dims, phrase, pose_dim, out_channels, draws and width must be positive, "
                f"not {dims}, {phrase}, {pose_dim}, {out_channels}, {draws}, {width}"
            )
        self.dims, self.phrase = dims, phrase
        self.encoder = nn.Sequential(nn.Linear(phrase * pose_dim, width), nn.ReLU(), nn.Linear(width, 2 * dims))
        self.project = nn.Identity() if out_channels is None else nn.Linear(dims, out_channels)
        table = torch.randn(draws, dims, generator=torch.Generator().manual_seed(DRAW_SEED))
        self.register_buffer("draws", table)

    def posterior(self, poses: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Codes inferred from true poses: a draw from the posterior in training mode, its mean in
        evaluation mode.

        Args:
            poses: [B, T, D], frame 0 the first of phrase 0 (a last partial phrase is padded with
                its own last pose).

        Returns:
            ``(codes [B, T, dims], kl [B, phrases, dims])``: each frame's phrase's code, and each
            phrase's KL divergence from N(0, I) per dimension, in nats.
        """
        B, T, D = poses.shape
        phrases = -(-T // self.phrase)
        padded = torch.cat([poses, poses[:, -1:].expand(B, phrases * self.phrase - T, D)], dim=1)
        mean, log_var = self.encoder(padded.reshape(B, phrases, self.phrase * D)).chunk(2, dim=-1)
        log_var = log_var.clamp(-10.0, 10.0)
        kl = 0.5 * (mean.square() + log_var.exp() - 1.0 - log_var)
        code = mean + torch.randn_like(mean) * (0.5 * log_var).exp() if self.training else mean
        return code.repeat_interleave(self.phrase, dim=1)[:, :T], kl

    def drawn(self, batch: int, frames: int, draw: torch.Tensor | int = 0) -> torch.Tensor:
        """Codes from the table of prior draws: [B, T, dims] for frames 0 .. T - 1, ``draw`` a row
        offset per dance ([B] or one for all)."""
        draw = torch.as_tensor(draw, device=self.draws.device).reshape(-1, 1).expand(batch, 1)
        t = torch.arange(frames, device=self.draws.device)
        return self.draws[(draw + torch.div(t, self.phrase, rounding_mode="floor")) % len(self.draws)]

    def at_frame(self, frame: torch.Tensor) -> torch.Tensor:
        """The drawn code [B, dims] of frames ``frame`` [B] (float counts of frames since the start,
        the draw's offset included as ``draw * phrase``): the one-frame stream's."""
        row = torch.div(frame, self.phrase, rounding_mode="floor").long() % len(self.draws)
        return self.draws[row]


def kl_term(kl: torch.Tensor, free_nats: float = 0.0) -> torch.Tensor:
    """The KL penalty of :meth:`PhraseCode.posterior`'s ``kl`` [B, phrases, dims]: per phrase, the sum
    over dimensions of each dimension's KL past ``free_nats`` (free bits, Kingma et al. 2016: a code
    may carry that much per dimension at no cost, so that it is not left unused), averaged over the
    batch's phrases; nats."""
    if free_nats < 0:
        raise KinectDataError(f"phrase code: free_nats must be at least 0, not {free_nats}")
    return (kl.mean(dim=(0, 1)) - free_nats).clamp(min=0.0).sum()
