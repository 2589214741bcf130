"""Mirrored training windows: each joint set's sides, the target's columns in the mirror image, and
windows danced by their dancer's mirror image, checked against motions mirrored by hand."""

from __future__ import annotations

import re

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from kinectdata.core.errors import ConfigError, SchemaError  # noqa: E402
from kinectdata.core.jointsets import JointSet, joint_set_from_dict, load_joint_set, shipped_joint_sets  # noqa: E402
from kinectdata.targets.normalization import Normalizer, NormStats  # noqa: E402
from kinectdata.targets.specs import generic_target, load_target_spec  # noqa: E402
from kinectdata.training.augment import Mirror, mirror_windows  # noqa: E402

KINECT_V2_PAIRS = [
    ("ShoulderLeft", "ShoulderRight"), ("ElbowLeft", "ElbowRight"), ("WristLeft", "WristRight"),
    ("HandLeft", "HandRight"), ("HipLeft", "HipRight"), ("KneeLeft", "KneeRight"), ("AnkleLeft", "AnkleRight"),
    ("FootLeft", "FootRight"), ("HandTipLeft", "HandTipRight"), ("ThumbLeft", "ThumbRight"),
]  # fmt: skip
"""Kinect v2's sides, written out from the SDK's JointType list."""


def test_each_shipped_joint_set_pairs_left_with_right_and_keeps_the_midline():
    js = load_joint_set("kinect_v2")
    image = js.mirror_image()
    expected = {a: b for pair in KINECT_V2_PAIRS for a, b in (pair, pair[::-1])}
    assert {js.names[j]: js.names[image[j]] for j in range(len(js))} == {n: expected.get(n, n) for n in js.names}
    named = {
        "openpose_mpi": ("RShoulder", "LShoulder"),
        "nite": ("LEFT_HIP", "RIGHT_HIP"),
        "azure_kinect": ("HANDTIP_LEFT", "HANDTIP_RIGHT"),
        "tang2018": ("left_point_21", "right_point_22"),  # named in its file: the names do not say it
        "smpl24": ("left_collar", "right_collar"),
    }
    for name in shipped_joint_sets():
        js = load_joint_set(name)
        image = js.mirror_image()
        assert np.array_equal(image[image], np.arange(len(js))), name  # an image's image is the joint
        for j, k in enumerate(image):
            n = js.names[j]
            sided = "left" in n.lower() or "right" in n.lower() or re.match("^[LR][A-Z]", n) is not None
            assert (j != k) == sided, (name, n)
        if name in named:
            a, b = named[name]
            assert image[js.index(a)] == js.index(b), name


def test_a_joint_named_for_one_side_alone_is_refused_unless_its_image_is_named():
    js = JointSet.custom("one_hand", ["pelvis", "left_hand", "grip"], [None, "pelvis", "left_hand"])
    with pytest.raises(ConfigError, match=r"joint set 'one_hand': joint 'left_hand' has no mirror image 'right_hand'"):
        js.mirror_image()
    doc = {**js.to_dict(), "mirror": {"left_hand": "grip"}}
    named = joint_set_from_dict(doc)
    assert named.mirror_image().tolist() == [0, 2, 1]
    assert joint_set_from_dict(named.to_dict()) == named  # the pairs are kept
    with pytest.raises(SchemaError, match="mirror names unknown joint 'right_hand'"):
        joint_set_from_dict({**doc, "mirror": {"left_hand": "right_hand"}})
    with pytest.raises(SchemaError, match="mirror names a joint in two pairs"):
        joint_set_from_dict({**doc, "mirror": {"left_hand": "grip", "pelvis": "left_hand"}})


def test_targets_that_cannot_be_mirrored_say_why():
    with pytest.raises(ConfigError, match="only positions and limb lengths can be mirrored, not orientations"):
        load_target_spec("yalta65").mirror_columns()
    with pytest.raises(ConfigError, match="positions scaled per recording cannot be mirrored"):
        load_target_spec("listen_to_dance").mirror_columns()
    spec = generic_target("positions", load_joint_set("kinect_v2"))
    one_sided = type(spec)(**{**spec.__dict__, "positions": ("SpineBase", "HandLeft")})
    with pytest.raises(ConfigError, match="its positions hold 'HandLeft' but not its mirror image 'HandRight'"):
        one_sided.mirror_columns()


def _manifest(spec, normaliser: Normalizer) -> dict:
    return {
        "config": {"target": spec.to_dict()},
        "normalisation": normaliser.to_dict(),
    }


@pytest.mark.parametrize("method", ["maxabs", "minmax"])
def test_mirrored_targets_are_the_targets_of_the_motion_mirrored_by_hand(method):
    """Positions in metres [T, J, 3] mirrored by hand (x negated, Kinect v2's pairs swapped), then
    normalised, against the normalised targets mirrored; minmax's offsets check the shift."""
    js = load_joint_set("kinect_v2")
    spec = generic_target("positions", js)
    assert spec.positions == js.names
    rng = np.random.default_rng(5)
    T, J = 50, len(js)
    positions = rng.normal([0.3, 1.0, 2.5], [0.4, 0.5, 0.3], size=(T, J, 3))
    mask = rng.random((T, J)) > 0.1
    by_hand = positions.copy()
    for a, b in KINECT_V2_PAIRS:
        i, k = js.index(a), js.index(b)
        by_hand[:, [i, k]] = positions[:, [k, i]]
    by_hand[..., 0] *= -1
    hand_mask = mask.copy()
    for a, b in KINECT_V2_PAIRS:
        i, k = js.index(a), js.index(b)
        hand_mask[:, [i, k]] = mask[:, [k, i]]
    flat = lambda a: a.reshape(len(a), -1)  # noqa: E731
    columns = lambda m: np.repeat(m, 3, axis=1)  # noqa: E731
    both, both_masks = np.concatenate([positions, by_hand]), np.concatenate([mask, hand_mask])
    stats = NormStats.from_arrays(flat(both), columns(both_masks))
    normaliser = Normalizer.fit(stats, method)
    targets = normaliser.apply(flat(positions), columns(mask))
    expected = normaliser.apply(flat(by_hand), columns(hand_mask))
    mirror = Mirror.of_dataset(_manifest(spec, normaliser))
    got = mirror.poses(torch.from_numpy(targets), torch.from_numpy(columns(mask)))
    np.testing.assert_allclose(got.numpy(), expected, atol=2e-6)
    np.testing.assert_array_equal(torch.from_numpy(columns(mask))[..., mirror.source].numpy(), columns(hand_mask))


def _batch(B: int = 64, L: int = 30) -> tuple[dict, Mirror]:
    js = load_joint_set("kinect_v2")
    spec = generic_target("positions", js)
    D = spec.dim
    gen = torch.Generator().manual_seed(2)
    current = torch.rand(B, L + 2, D, generator=gen) * 1.6 - 0.8
    mask = torch.rand(B, L + 1, D, generator=gen) > 0.05
    current[:, : L + 1][~mask] = 0.0  # masked values are stored as 0; mask[:, t] is frame t's
    batch = {
        "audio": torch.rand(B, L, 7, generator=gen),
        "pose": current[:, 1 : L + 1],
        "previous": current[:, :L],
        "next": current[:, 2:],
        "mask": mask[:, 1:],
        "previous_mask": mask[:, :L],
    }
    normaliser = Normalizer("maxabs", np.full(D, 0.9), np.zeros(D), np.ones(D, np.int64))
    return batch, Mirror.of_dataset(_manifest(spec, normaliser))


def test_windows_are_mirrored_whole_and_only_their_poses():
    batch, mirror = _batch()
    kept = {k: v.clone() for k, v in batch.items()}
    out = mirror_windows(batch, mirror, 0.5, torch.Generator().manual_seed(0))
    for k, v in kept.items():  # the given tensors are left as they were
        assert torch.equal(batch[k], v)
    assert torch.equal(out["audio"], batch["audio"])  # the same music
    flipped = [b for b in range(64) if not torch.equal(out["pose"][b], batch["pose"][b])]
    assert 20 <= len(flipped) <= 44  # binomial(64, 0.5): 32 +- 4
    for b in range(64):
        expect = b in flipped
        for values, mask in (("pose", "mask"), ("previous", "previous_mask"), ("next", None)):
            given = None if mask is None else batch[mask][b]
            want = mirror.poses(batch[values][b], given) if expect else batch[values][b]
            assert torch.equal(out[values][b], want), (b, values)
    # teacher forcing still sees the frame before: previous[t] == pose[t - 1], in the mirror too
    assert torch.equal(out["previous"][:, 1:], out["pose"][:, :-1])
    assert torch.equal(out["previous_mask"][:, 1:], out["mask"][:, :-1])
    again = mirror_windows(batch, mirror, 1.0, torch.Generator().manual_seed(0))
    back = mirror_windows(again, mirror, 1.0, torch.Generator().manual_seed(0))
    torch.testing.assert_close(back["pose"], batch["pose"], atol=1e-6, rtol=0)  # the mirror's mirror
    assert torch.equal(back["mask"], batch["mask"])


def test_share_zero_changes_nothing_and_one_seed_gives_one_batch():
    batch, mirror = _batch(B=16)
    assert mirror_windows(batch, mirror, 0.0, torch.Generator().manual_seed(0)) is batch
    one = mirror_windows(batch, mirror, 0.5, torch.Generator().manual_seed(7))
    two = mirror_windows(batch, mirror, 0.5, torch.Generator().manual_seed(7))
    other = mirror_windows(batch, mirror, 0.5, torch.Generator().manual_seed(8))
    assert all(torch.equal(one[k], two[k]) for k in batch)
    assert not torch.equal(one["pose"], other["pose"])
