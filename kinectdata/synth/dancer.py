"""The synthetic dancer: true (noise-free) Kinect v2 motion that dances to a beat grid.

The body is the 25-joint ``kinect_v2`` joint set, posed by forward kinematics. Every joint with
children has a frame (a rotation in camera space); a child's position is its parent's position
plus the parent's frame applied to a fixed offset (:attr:`Body.offsets`, in the parent's local
axes). The frame of a joint points its local +y axis at its main child (SpineBase -> SpineMid,
ShoulderLeft -> ElbowLeft, AnkleLeft -> FootLeft, ...), so that offset is ``(0, bone length, 0)``;
other children (hips, shoulders, thumbs) sit at fixed vectors in the parent's frame. The frames
are the orientations written out (global, x y z w); leaf joints have none.

Camera space as the Kinect reports it: metres, x to the dancer's right (the sensor's left),
y up, z away from the sensor. The dancer stands about 2.5 m from the sensor facing it (-z) on
a floor near y = -0.95 m.

Choreography, on the music clock (the clock of ``times_s`` and ``beat_times_s``):

- before ``music_start_s``: a relaxed stand with a tiny breathing sway, and one clap whose hands
  meet at exactly ``clap_time_s`` (HandLeft and HandRight :data:`CLAP_HAND_GAP_M` apart, closing
  at 2-3 m/s just before), held :data:`CLAP_HOLD_S`, then released;
- from ``music_start_s``: a knee bounce on every beat (lowest on the beat), hip sway alternating
  each beat, a side step every two beats (feet land on the beats), a head nod on the beat, and
  arm figures that change every two bars (seeded); the first two bars (the music's drum intro)
  keep the arms to a small swing. The groove fades in over the first two beats.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from kinectdata.core.errors import ConfigError
from kinectdata.core.jointsets import JointSet, load_joint_set, parents_first
from kinectdata.core.motion import Motion
from kinectdata.core.quaternions import make_continuous
from kinectdata.synth.music import BEATS_PER_BAR, INTRO_BARS

JOINT_SET_NAME = "kinect_v2"
UP = np.array([0.0, 1.0, 0.0])
FORWARD = np.array([0.0, 0.0, -1.0])
"""The direction the dancer faces (towards the sensor)."""
RIGHT = np.array([1.0, 0.0, 0.0])
"""The dancer's right when facing the sensor."""

CLAP_HAND_GAP_M = 0.02
"""HandLeft-HandRight distance at the clap instant (palm centres, palms touching)."""
CLAP_HOLD_S = 0.06
"""The hands stay together this long after the clap instant before they part."""
CLAP_LEAD_S = 0.85
"""The clap movement starts at most this long before the clap instant."""
CLAP_CLEARANCE_S = 1.0
"""The clap must be at least this long before the music starts (the arms are back by then)."""
BLOCK_BEATS = INTRO_BARS * BEATS_PER_BAR
"""Beats per choreography block (two bars, the length of the music's drum intro, which is block
0): arm figure, step pattern and groove amounts change per block."""
FADE_BEATS = 2.0
"""Blocks cross-fade over their last two beats."""
MAX_BLOCKS = 512

_PRIMARY_CHILD = {
    "SpineBase": "SpineMid",
    "SpineMid": "SpineShoulder",
    "SpineShoulder": "Neck",
    "Neck": "Head",
    "ShoulderLeft": "ElbowLeft",
    "ElbowLeft": "WristLeft",
    "WristLeft": "HandLeft",
    "HandLeft": "HandTipLeft",
    "ShoulderRight": "ElbowRight",
    "ElbowRight": "WristRight",
    "WristRight": "HandRight",
    "HandRight": "HandTipRight",
    "HipLeft": "KneeLeft",
    "KneeLeft": "AnkleLeft",
    "AnkleLeft": "FootLeft",
    "HipRight": "KneeRight",
    "KneeRight": "AnkleRight",
    "AnkleRight": "FootRight",
}
FIGURES = ("swing", "pump", "punch", "open_close", "disco", "v_sway", "hips")
"""Arm figures; block 0 (the intro) is always a small ``swing``."""


# -- the body ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Body:
    """Geometry of the dancer.

    Attributes:
        joint_set: the ``kinect_v2`` joint set.
        height_m: standing height (top of the head), metres.
        rest_positions: [J, 3] rest pose, camera axes, SpineBase at the origin, facing -z.
        rest_frames: [J, 4] rest-pose joint frames (x, y, z, w); leaves copy their parent's.
        offsets: [J, 3] each joint's offset from its parent in the parent's local axes (zeros
            for the root); ``(0, bone length, 0)`` for a main child.
        root_height_m: SpineBase height above the floor in the rest pose (legs straight).
        ankle_height_m: ankle height above the floor with the foot flat.
        order: joint indices, parents before children.
    """

    joint_set: JointSet
    height_m: float
    rest_positions: np.ndarray
    rest_frames: np.ndarray
    offsets: np.ndarray
    root_height_m: float
    ankle_height_m: float
    order: tuple[int, ...]

    def index(self, name: str) -> int:
        return self.joint_set.index(name)

    def length(self, child: str) -> float:
        """Length of the bone from ``child``'s parent to ``child``, metres."""
        return float(np.linalg.norm(self.offsets[self.index(child)]))


def make_body(height_m: float = 1.70) -> Body:
    """A Kinect-proportioned adult of the given height in a relaxed rest pose."""
    js = load_joint_set(JOINT_SET_NAME)
    s = height_m / 1.70
    p: dict[str, np.ndarray] = {}

    def put(name, *xyz):
        p[name] = np.array(xyz, float) * s

    def along(name, start, length, direction):
        d = np.asarray(direction, float)
        p[name] = p[start] + length * s * d / np.linalg.norm(d)

    # Heights above the floor (y), x to the dancer's right, z backwards (the dancer faces -z).
    put("SpineBase", 0, 0.95, 0)
    put("SpineMid", 0, 1.18, 0.01)
    put("SpineShoulder", 0, 1.42, 0.0)
    put("Neck", 0, 1.49, -0.005)
    put("Head", 0, 1.61, -0.02)
    for side, sx in (("Left", -1), ("Right", 1)):
        put(f"Shoulder{side}", 0.17 * sx, 1.39, 0.01)
        along(f"Elbow{side}", f"Shoulder{side}", 0.28, (0.10 * sx, -1, 0.02))
        along(f"Wrist{side}", f"Elbow{side}", 0.25, (0.03 * sx, -1, -0.12))
        along(f"Hand{side}", f"Wrist{side}", 0.08, (0, -1, -0.1))
        along(f"HandTip{side}", f"Hand{side}", 0.07, (0, -1, -0.1))
        p[f"Thumb{side}"] = p[f"Wrist{side}"] + np.array([0.0, -0.045, -0.035]) * s
        put(f"Hip{side}", 0.085 * sx, 0.89, 0)
        along(f"Knee{side}", f"Hip{side}", 0.41, (0, -1, 0))
        along(f"Ankle{side}", f"Knee{side}", 0.40, (0, -1, 0))
        along(f"Foot{side}", f"Ankle{side}", 0.117, (0.1 * sx, -0.35, -1))
    root = p["SpineBase"].copy()
    rest = np.array([p[n] - root for n in js.names])

    J = len(js)
    frames = np.zeros((J, 3, 3))
    for j, name in enumerate(js.names):
        if name in _PRIMARY_CHILD:
            frames[j] = _frame_yz(p[_PRIMARY_CHILD[name]] - p[name], UP if name.startswith("Ankle") else FORWARD)
    for side in ("Left", "Right"):  # arms: the same hinge frames as the animation (see _pose_arm)
        sign = 1.0 if side == "Right" else -1.0
        shoulder, elbow, wrist, hand = (p[f"{n}{side}"][None] for n in ("Shoulder", "Elbow", "Wrist", "Hand"))
        pole = _dancer_coords(_ELBOW_POLE * [sign, 1, 1])[None]
        normal = _unit(np.cross(wrist - shoulder, pole))
        upper, lower = _unit(elbow - shoulder), _unit(wrist - elbow)
        normal = _unit(normal - np.sum(normal * upper, -1, keepdims=True) * upper)
        frames[js.index(f"Shoulder{side}")] = _matrix_xy(normal, upper)[0]
        normal = _unit(normal - np.sum(normal * lower, -1, keepdims=True) * lower)
        elbow_frame = Rotation.from_matrix(_matrix_xy(normal, lower))
        wrist_frame = (_min_rotation(lower, _unit(hand - wrist)) * elbow_frame).as_matrix()
        frames[js.index(f"Elbow{side}")] = elbow_frame.as_matrix()[0]
        frames[js.index(f"Wrist{side}")] = frames[js.index(f"Hand{side}")] = wrist_frame[0]
    order = tuple(parents_first(js.parents))
    for j in order:  # leaves take their parent's frame (never written, only for completeness)
        if js.names[j] not in _PRIMARY_CHILD:
            frames[j] = frames[js.parents[j]]
    offsets = np.zeros((J, 3))
    for c, par in enumerate(js.parents):
        if par >= 0:
            offsets[c] = frames[par].T @ (rest[c] - rest[par])
    return Body(
        joint_set=js,
        height_m=float(height_m),
        rest_positions=rest,
        rest_frames=Rotation.from_matrix(frames).as_quat(),
        offsets=offsets,
        root_height_m=float(root[1]),
        ankle_height_m=float(p["AnkleLeft"][1]),
        order=order,
    )


def forward_kinematics(body: Body, root_position: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """Joint positions from the root position [T, 3] and global joint frames [T, J, 4] (x y z w).

    Returns [T, J, 3]: ``p[child] = p[parent] + R[parent] @ offsets[child]``.
    """
    T = root_position.shape[0]
    pos = np.zeros((T, len(body.joint_set), 3))
    for j in body.order:
        par = body.joint_set.parents[j]
        if par < 0:
            pos[:, j] = root_position
        else:
            pos[:, j] = pos[:, par] + Rotation.from_quat(frames[:, par]).apply(body.offsets[j])
    return pos


# -- the dance ---------------------------------------------------------------------------------
def dance(
    *,
    seed: int | np.random.SeedSequence,
    times_s: np.ndarray,
    beat_times_s: np.ndarray,
    music_start_s: float,
    clap_time_s: float | None,
    tempo_bpm: float,
) -> Motion:
    """True motion of the dancer at ``times_s`` (seconds, music clock; increasing).

    Args:
        seed: seed of the dancer's choices (height, place, figures, steps, clap speed). The
            choices do not depend on ``times_s``: the same seed gives the same dance at any times.
        times_s: [T] sample times.
        beat_times_s: [B] beat times (the music's beat grid, first one at ``music_start_s``).
        music_start_s: the first beat; before it the dancer stands still (breathing, the clap).
        clap_time_s: when the hands meet, or None for no clap. At least
            :data:`CLAP_CLEARANCE_S` before ``music_start_s``.
        tempo_bpm: the tempo; beats are extrapolated with it outside ``beat_times_s``.

    Returns:
        A Motion on the ``kinect_v2`` joint set with positions [T, 25, 3] (metres, camera space),
        global orientations [T, 25, 4] (x, y, z, w; leaves masked), confidence 1, and metadata
        ``height_m``, ``floor_y_m``, ``blocks`` (per 2-bar block: start beat, arm figure, step
        pattern), ``clock`` = "music".
    """
    t = np.asarray(times_s, dtype=np.float64)
    if t.ndim != 1 or t.size == 0:
        raise ConfigError("times_s must be a non-empty one-dimensional array")
    period = 60.0 / tempo_bpm
    if clap_time_s is not None and clap_time_s > music_start_s - CLAP_CLEARANCE_S:
        raise ConfigError(
            f"the clap ({clap_time_s} s) must be at least {CLAP_CLEARANCE_S} s before the music "
            f"starts ({music_start_s} s)"
        )
    rng = np.random.default_rng(seed)
    plan = _Plan.draw(rng)
    body = make_body(plan.height_m)
    sc = plan.height_m / 1.70
    beat = _beat_coordinate(t, np.asarray(beat_times_s, float), music_start_s, period)
    if beat.size and beat.max() >= (MAX_BLOCKS - 1) * BLOCK_BEATS:
        raise ConfigError("the dance is too long for the choreography plan")
    groove = _smootherstep((t - music_start_s) / (2 * period))
    bounce_shape = 0.5 * (1 + np.cos(2 * np.pi * beat))  # 1 on the beat, 0 half-way
    alt = np.cos(np.pi * beat)  # +1 on even beats, -1 on odd ones
    blocks = np.clip(np.floor(beat / BLOCK_BEATS).astype(int), 0, None)

    def block_param(values):
        return _block_blend(beat, np.asarray(values, float))

    breath = np.sin(2 * np.pi * plan.breath_hz * t + plan.breath_phase)
    drift = np.sin(2 * np.pi * 0.09 * t + plan.drift_phase)

    # Feet and pelvis.
    feet_x, feet_lift, feet_pitch = _feet(plan, beat, sc)
    floor = plan.floor_y
    ankle_y = floor + body.ankle_height_m + feet_lift  # [T, 2] (left, right)
    crouch = 0.004 * sc + groove * (0.02 * sc + block_param(plan.bounce) * bounce_shape)
    root = np.zeros((t.size, 3))
    root[:, 0] = feet_x.mean(axis=1) + groove * block_param(plan.sway) * alt + 0.004 * sc * drift
    root[:, 1] = floor + body.root_height_m - crouch + 0.0015 * sc * breath
    root[:, 2] = plan.z0 + 0.003 * drift
    facing = groove * block_param(plan.facing)
    roll = groove * block_param(plan.roll) * alt
    yaw = facing + groove * 0.05 * np.sin(np.pi * beat)
    pitch = -groove * 0.05 * bounce_shape
    pelvis = Rotation.from_euler("YZX", np.stack([yaw, roll, pitch], axis=1))

    # Arms, as targets in the chest's rest axes (blended figures), then the torso.
    arms = _arm_plan(plan, beat, blocks, groove, t, clap_time_s, sc)
    J = len(body.joint_set)
    ix = body.index
    frames = np.tile(body.rest_frames, (t.size, 1, 1))  # limbs are set after the trunk
    rest = Rotation.from_quat(body.rest_frames)
    frames[:, ix("SpineBase")] = (pelvis * rest[ix("SpineBase")]).as_quat()
    spine_local = {  # rotation vectors in each joint's own axes (x = dancer's left, y up, z forward)
        "SpineMid": np.stack([0.01 * breath + groove * 0.03 * bounce_shape, -0.4 * (yaw - facing), 0.5 * roll], 1),
        "SpineShoulder": np.stack([0.006 * breath, -0.3 * (yaw - facing) + arms.shimmy, 0.4 * roll], 1),
        "Neck": np.stack(
            [-0.004 * breath + groove * block_param(plan.nod) * bounce_shape, 0.2 * (yaw - facing), -0.3 * roll], 1
        ),
    }
    for name, rotvec in spine_local.items():
        j, par = ix(name), body.joint_set.parents[ix(name)]
        local_rest = rest[par].inv() * rest[j]
        frames[:, j] = (Rotation.from_quat(frames[:, par]) * local_rest * Rotation.from_rotvec(rotvec)).as_quat()
    pos = forward_kinematics(body, root, frames)  # trunk positions are final; limbs follow

    chest = Rotation.from_quat(frames[:, ix("SpineShoulder")]) * rest[ix("SpineShoulder")].inv()
    for side, k in (("Left", 0), ("Right", 1)):
        _pose_arm(body, side, frames, pos, chest, arms, k)
        toe = FORWARD * np.cos(plan.toe_out) + RIGHT * np.sin(plan.toe_out) * (1 if side == "Right" else -1)
        foot_dir = toe[None] * np.cos(feet_pitch[:, k, None]) - UP[None] * np.sin(feet_pitch[:, k, None])
        ankle = np.stack([feet_x[:, k], ankle_y[:, k], np.full(t.size, plan.z0 + 0.01 * sc)], axis=1)
        _pose_leg(body, side, frames, pos, ankle, np.broadcast_to(toe, ankle.shape), foot_dir)
    pos = forward_kinematics(body, root, frames)

    orient_mask = np.broadcast_to(body.joint_set.orientation_mask, (t.size, J))
    quats = make_continuous(frames)  # leaves hold copies of their parents' rest frames until here
    quats[:, ~body.joint_set.orientation_mask] = np.nan
    n_blocks = int(blocks.max()) + 1
    meta = {
        "generator": "kinectdata.synth.dancer",
        "clock": "music",
        "height_m": plan.height_m,
        "floor_y_m": plan.floor_y,
        "clap_time_s": clap_time_s,
        "blocks": [
            {
                "start_beat": b * BLOCK_BEATS,
                "figure": FIGURES[plan.figure[b]],
                "steps": ("touch", "out_in")[plan.step_pattern[b]],
            }
            for b in range(n_blocks)
        ],
    }
    return Motion(
        times=t,
        positions=pos,
        joint_set=body.joint_set,
        confidence=np.ones((t.size, J), np.float32),
        orientations=quats,
        orientation_mask=orient_mask,
        metadata=meta,
    )


# -- random choices ----------------------------------------------------------------------------
@dataclass(frozen=True)
class _Plan:
    """Every random choice of a dance, drawn up front in a fixed order (independent of the times)."""

    height_m: float
    floor_y: float
    x0: float
    z0: float
    toe_out: float
    breath_hz: float
    breath_phase: float
    drift_phase: float
    clap_close_s: float
    figure: np.ndarray  # [MAX_BLOCKS] index into FIGURES
    figure_amp: np.ndarray
    figure_side: np.ndarray  # +1 right arm leads, -1 left
    pump_mode: np.ndarray  # 0 both, 1 alternating, 2 one arm
    bounce: np.ndarray  # metres
    sway: np.ndarray  # metres
    roll: np.ndarray  # radians
    facing: np.ndarray  # radians
    nod: np.ndarray  # radians
    step_pattern: np.ndarray  # 0 step-touch (travel), 1 out and in
    step_size: np.ndarray  # metres
    step_lift: np.ndarray  # metres

    @classmethod
    def draw(cls, rng: np.random.Generator) -> _Plan:
        height = float(rng.uniform(1.62, 1.80))
        scalars = dict(
            height_m=height,
            floor_y=float(rng.uniform(-0.98, -0.92)),
            x0=float(rng.uniform(-0.15, 0.15)),
            z0=float(rng.uniform(2.35, 2.65)),
            toe_out=float(rng.uniform(0.08, 0.2)),
            breath_hz=float(rng.uniform(0.22, 0.3)),
            breath_phase=float(rng.uniform(0, 2 * np.pi)),
            drift_phase=float(rng.uniform(0, 2 * np.pi)),
            clap_close_s=float(rng.uniform(0.22, 0.3)),
        )
        n = MAX_BLOCKS
        figure = np.zeros(n, int)
        for b in range(1, n):  # never the same figure twice in a row
            choices = [f for f in range(len(FIGURES)) if f != figure[b - 1]]
            figure[b] = choices[int(rng.integers(len(choices)))]
        sc = height / 1.70
        arrays = dict(
            figure=figure,
            figure_amp=rng.uniform(0.6, 1.0, n),
            figure_side=rng.choice([-1.0, 1.0], n),
            pump_mode=rng.integers(0, 3, n),
            bounce=rng.uniform(0.025, 0.04, n) * sc,
            sway=rng.uniform(0.015, 0.035, n) * sc,
            roll=rng.uniform(0.03, 0.07, n),
            facing=np.concatenate([[0.0], rng.uniform(-0.15, 0.15, n - 1)]),
            nod=rng.uniform(0.08, 0.18, n),
            step_pattern=rng.integers(0, 2, n),
            step_size=rng.uniform(0.14, 0.22, n) * sc,
            step_lift=rng.uniform(0.03, 0.06, n) * sc,
        )
        arrays["figure_amp"][0] = 0.35
        return cls(**scalars, **arrays)


# -- timing helpers ----------------------------------------------------------------------------
def _smootherstep(x: np.ndarray) -> np.ndarray:
    """0 -> 1 with zero first and second derivatives at both ends (x clipped to 0..1)."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * x * (x * (6 * x - 15) + 10)


def _beat_coordinate(t: np.ndarray, beats: np.ndarray, start: float, period: float) -> np.ndarray:
    """Continuous beat count at ``t``: 0 at the first beat, integers on the beats.

    Interpolates the beat grid and extrapolates with ``period`` before and after it.
    """
    if beats.size < 2:
        return (t - start) / period
    idx = np.arange(beats.size, dtype=float)
    out = np.interp(t, beats, idx)
    out = np.where(t < beats[0], (t - beats[0]) / period, out)
    return np.where(t > beats[-1], idx[-1] + (t - beats[-1]) / period, out)


def _block_weights(beat: np.ndarray, b: int) -> np.ndarray:
    """Weight of block ``b`` at each beat coordinate: each block cross-fades into the next over its
    last :data:`FADE_BEATS` beats; the weights of all blocks sum to 1 (block 0 also covers
    everything before it)."""
    start, end = b * BLOCK_BEATS, (b + 1) * BLOCK_BEATS
    w_in = np.ones_like(beat) if b == 0 else _smootherstep((beat - (start - FADE_BEATS)) / FADE_BEATS)
    return w_in - _smootherstep((beat - (end - FADE_BEATS)) / FADE_BEATS)


def _block_blend(beat: np.ndarray, values: np.ndarray) -> np.ndarray:
    """A per-block value at each beat coordinate, cross-faded like :func:`_block_weights`."""
    k = np.clip(np.floor(beat / BLOCK_BEATS).astype(int), 0, values.size - 2)
    w = _smootherstep((beat - ((k + 1) * BLOCK_BEATS - FADE_BEATS)) / FADE_BEATS)
    return values[k] + (values[k + 1] - values[k]) * w


# -- feet --------------------------------------------------------------------------------------
def _feet(plan: _Plan, beat: np.ndarray, sc: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ankle x [T, 2], ankle lift above flat-foot height [T, 2], foot pitch [T, 2] (left, right).

    From beat 4 on, a side step every two beats (unit m covers beats 2m and 2m+1; units alternate
    right-leading and left-leading). Step-touch: the lead foot steps out and lands on beat 2m, the
    other foot closes on beat 2m+1. Out-and-in: the lead foot steps out on 2m and back on 2m+1.
    A foot's swing takes the half beat before its landing.
    """
    half_width = 0.10 * sc
    x = np.array([plan.x0 - half_width, plan.x0 + half_width])  # left, right
    last = int(np.ceil(beat.max())) + 2 if beat.size else 0
    keys: list[list[tuple[float, float, float]]] = [[(-1e9, x[0], 0.0)], [(-1e9, x[1], 0.0)]]  # (land, x, lift)
    for m in range(2, max(last // 2 + 1, 2)):
        b = (2 * m) // BLOCK_BEATS
        d = 1 if m % 2 == 0 else -1
        lead, other = (1, 0) if d > 0 else (0, 1)
        size, lift = plan.step_size[b], plan.step_lift[b]
        if plan.step_pattern[b] == 0:  # step-touch, travelling towards the lead side
            x[lead] = x[other] + d * (2 * half_width + size)
            keys[lead].append((2 * m, x[lead], lift))
            x[other] = x[lead] - d * 2 * half_width
            keys[other].append((2 * m + 1, x[other], 0.6 * lift))
        else:  # out and back in
            home = x[lead]
            keys[lead].append((2 * m, home + d * size, lift))
            keys[lead].append((2 * m + 1, home, 0.6 * lift))
    swing = 0.5
    xs, lifts, pitches = (np.zeros((beat.size, 2)) for _ in range(3))
    for k in range(2):
        keys[k].append((1e9, keys[k][-1][1], 0.0))  # a far-future key: every beat has a next key
        land, kx, kl = (np.array(col) for col in zip(*keys[k], strict=True))
        nxt = np.searchsorted(land, beat, side="right")
        u = np.clip((beat - (land[nxt] - swing)) / swing, 0, 1)  # 0 planted, 0..1 swinging
        xs[:, k] = kx[nxt - 1] + (kx[nxt] - kx[nxt - 1]) * _smootherstep(u)
        lifts[:, k] = kl[nxt] * np.sin(np.pi * u) ** 2
        pitches[:, k] = 0.33 + 0.3 * np.sin(np.pi * u) ** 2  # toes point down while the foot swings
    return xs, lifts, pitches


# -- arms --------------------------------------------------------------------------------------
@dataclass
class _Arms:
    """Arm targets in the chest's rest axes (camera axes of the rest pose), relative to SpineShoulder.

    ``wrist`` [T, 2, 3] wrist targets (left, right); ``bias`` [T, 2, 3] added to the forearm
    direction to give the hand direction; ``hand`` [T, 2, 3] an explicit hand direction used with
    weight ``hand_w`` [T] (the clap); ``twist`` [T, 2] forearm pronation, radians (0: the hand
    follows the elbow's hinge frame, thumb on the side the forearm flexes towards); ``curl``
    [T, 2] finger curl, radians; ``shimmy`` [T] extra chest twist, radians.
    """

    wrist: np.ndarray
    bias: np.ndarray
    hand: np.ndarray
    hand_w: np.ndarray
    twist: np.ndarray
    curl: np.ndarray
    shimmy: np.ndarray


def _dancer_coords(v) -> np.ndarray:
    """(right, up, forward) -> camera rest axes (x, y, z)."""
    v = np.asarray(v, float)
    return v * np.array([1.0, 1.0, -1.0])


def _mirror(v: np.ndarray) -> np.ndarray:
    return v * np.array([-1.0, 1.0, 1.0])


def _sides(right: np.ndarray, left: np.ndarray | None = None) -> np.ndarray:
    """[T, 2, 3] (left, right) from right-arm vectors in dancer coordinates; left mirrors right
    unless given (also in right-arm coordinates, mirrored here)."""
    right = np.asarray(right, float)
    left = right if left is None else np.asarray(left, float)
    return np.stack([_dancer_coords(_mirror(left)), _dancer_coords(right)], axis=-2)


def _lerp(a, b, w):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return a + (b - a) * np.asarray(w, float)[..., None]


def _figure(name: str, beat: np.ndarray, amp: float, side: float, mode: int) -> dict[str, np.ndarray]:
    """One arm figure as dancer-coordinate arrays (right arm's view; the left arm is mirrored).

    Positions are metres for a 1.70 m dancer relative to SpineShoulder: (right, up, forward).
    """
    T = beat.size
    c = np.cos(np.pi * beat)  # +1 even beats, -1 odd beats
    on = 0.5 * (1 + np.cos(2 * np.pi * beat))  # 1 on every beat
    ones = np.ones(T)
    hip = np.array([0.24, -0.40, -0.02])
    fist = {"curl": 1.2 * ones}
    if name == "swing":
        r, lft = (_lerp([0.22, -0.42, -0.10], [0.21, -0.36, 0.24], 0.5 + 0.5 * amp * s * c) for s in (1.0, -1.0))
        r[:, 1] += 0.03 * amp * on
        lft[:, 1] += 0.03 * amp * on
        return {
            "wrist": _sides(r, lft),
            "bias": _sides(np.tile([0, -0.3, 0.2], (T, 1))),
            "twist": 0 * ones,
            "curl": 0.6 * ones,
        }
    if name == "pump":
        low, high = np.array([0.26, -0.05, 0.14]), np.array([0.24, 0.46, 0.06])
        if mode == 0:
            er = el = on * amp
        elif mode == 1:
            er, el = ((1 + c) / 2) ** 2, ((1 - c) / 2) ** 2
        else:
            er, el = on, None
        r = _lerp(low, high, er)
        lft = _lerp(low, high, el) if el is not None else np.tile(hip, (T, 1))
        if side < 0:
            r, lft = lft, r
        return {"wrist": _sides(r, lft), "bias": np.zeros((T, 2, 3)), "twist": 0.3 * ones, **fist}
    if name == "punch":
        chamber, reach = np.array([0.20, -0.22, 0.10]), np.array([0.19, -0.05, 0.46])
        er, el = ((1 + side * c) / 2) ** 2 * amp, ((1 - side * c) / 2) ** 2 * amp
        return {
            "wrist": _sides(_lerp(chamber, reach, er), _lerp(chamber, reach, el)),
            "bias": np.zeros((T, 2, 3)),
            "twist": 1.2 * ones,
            **fist,
        }
    if name == "open_close":
        closed, opened = np.array([0.20, -0.12, 0.36]), np.array([0.20 + 0.38 * amp, 0.02, 0.05])
        w = _lerp(closed, opened, on)
        return {
            "wrist": _sides(w),
            "bias": _sides(np.tile([0.15, 0.05, 0.0], (T, 1))),
            "twist": -0.6 * on,
            "curl": 0.2 * ones,
        }
    if name == "disco":
        up, low = np.array([0.42, 0.38, 0.10]), np.array([0.33, -0.42, 0.18])
        point = _lerp(low, up, (1 + c) / 2)
        r, lft = point, np.tile(hip, (T, 1))
        if side < 0:
            r, lft = lft, r
        return {"wrist": _sides(r, lft), "bias": np.zeros((T, 2, 3)), "twist": 0.3 * ones, "curl": 0.5 * ones}
    if name == "v_sway":
        base = np.array([0.36, 0.40, 0.08])
        shift = 0.06 * amp * c
        r = base + np.stack([shift, 0 * shift, 0 * shift], 1)
        lft = base + np.stack([-shift, 0 * shift, 0 * shift], 1)  # mirrored: both move the same way
        return {"wrist": _sides(r, lft), "bias": np.zeros((T, 2, 3)), "twist": -0.3 * ones, "curl": 0.3 * ones}
    if name == "hips":
        pulse = 0.04 * amp * c
        r = hip + np.stack([0 * pulse, 0 * pulse, pulse], 1)
        lft = hip + np.stack([0 * pulse, 0 * pulse, -pulse], 1)
        return {
            "wrist": _sides(r, lft),
            "bias": _sides(np.tile([0.2, 0, 0.3], (T, 1))),
            "twist": 1.0 * ones,
            "curl": 0.4 * ones,
            "shimmy": 0.06 * amp * np.sin(2 * np.pi * beat),
        }
    raise ConfigError(f"unknown figure {name!r}")


_ELBOW_POLE = np.array([0.6, -0.55, -0.55])
"""Where the right elbow points (out, down, back; dancer coordinates); mirrored for the left."""
_CURL_SIGN = -1.0
"""Finger curl turns the hand about its frame's -x axis (towards the palm)."""
_SHOULDER = np.array([0.17, -0.03, -0.01])
"""The right shoulder relative to SpineShoulder, dancer coordinates, 1.70 m dancer."""
_FADE_PUSH = np.array([0.10, 0.0, 0.22])
_RELAXED = {
    "wrist": np.array([0.215, -0.54, 0.05]),
    "bias": np.array([0.0, -0.3, 0.1]),
    "curl": 0.35,
}


def _arm_plan(plan: _Plan, beat, blocks, groove, t, clap_time_s, sc) -> _Arms:
    T = t.size
    ones = np.ones(T)
    # Before the music: relaxed, plus the clap.
    wrist = _sides(np.tile(_RELAXED["wrist"], (T, 1)))
    bias = _sides(np.tile(_RELAXED["bias"], (T, 1)))
    twist = np.zeros((T, 2))
    curl = _RELAXED["curl"] * np.stack([ones, ones], 1)
    hand = np.zeros((T, 2, 3))
    hand_w = np.zeros(T)
    if clap_time_s is not None:
        raise_w, close = _clap_profile(t, clap_time_s, plan.clap_close_s)
        h_dir = np.array([-0.12, 0.5, 0.85])
        h_dir /= np.linalg.norm(h_dir)
        ready_hand = np.array([0.16, -0.14, 0.30])
        contact_hand = np.array([CLAP_HAND_GAP_M / 2 / sc, -0.12, 0.30])
        hand_pos = _lerp(ready_hand, contact_hand, close)
        clap_wrist = hand_pos - 0.08 * h_dir  # the wrist-hand bone is 0.08 m for a 1.70 m dancer
        wrist = _lerp(wrist, _sides(clap_wrist), raise_w[:, None])
        hand = _sides(np.tile(h_dir, (T, 1)))
        hand_w = raise_w
        curl = curl * (1 - raise_w)[:, None]
    shimmy = np.zeros(T)
    # The dance: figures per block, cross-faded.
    dance_parts = {k: np.zeros_like(v) for k, v in (("wrist", wrist), ("bias", bias), ("twist", twist), ("curl", curl))}
    sum_sq = np.zeros(T)
    for b in range(int(blocks.max()) + 2):
        w = _block_weights(beat, b)
        sel = w > 0
        if not sel.any():
            continue
        sum_sq += w**2
        name = FIGURES[plan.figure[b]]
        fig = _figure(name, beat[sel], plan.figure_amp[b], plan.figure_side[b], int(plan.pump_mode[b]))
        for key in ("twist", "curl"):
            fig[key] = np.stack([fig[key]] * 2, axis=1)
        for key in dance_parts:
            dance_parts[key][sel] += fig[key] * (w[sel][:, None, None] if fig[key].ndim == 3 else w[sel][:, None])
        if "shimmy" in fig:
            shimmy[sel] += fig["shimmy"] * w[sel]
    # While two figures cross-fade, a straight line between their targets can pass through the
    # shoulder (arm up -> arm down): push the wrists forward and out, most at mid-fade.
    mixing = 2 * (1 - sum_sq)  # 0 outside fades, 1 at mid-fade
    near = np.linalg.norm(dance_parts["wrist"] - _sides(np.tile(_SHOULDER, (T, 1))), axis=-1)
    push = (mixing[:, None] * _smootherstep((0.36 - near) / 0.2))[..., None]
    dance_parts["wrist"] += push * _sides(np.tile(_FADE_PUSH, (T, 1)))
    g3, g2 = groove[:, None, None], groove[:, None]
    return _Arms(
        wrist=(wrist + (dance_parts["wrist"] - wrist) * g3) * sc,
        bias=bias + (dance_parts["bias"] - bias) * g3,
        hand=hand,
        hand_w=hand_w * (1 - groove),
        twist=twist + (dance_parts["twist"] - twist) * g2,
        curl=curl + (dance_parts["curl"] - curl) * g2,
        shimmy=shimmy * groove,
    )


def _clap_profile(t: np.ndarray, tc: float, close_s: float) -> tuple[np.ndarray, np.ndarray]:
    """(raise, close) weights of the clap at ``t``.

    ``raise`` lifts the hands from the relaxed pose to the ready pose in front of the chest and
    back; ``close`` brings them from ready (0) to touching (1) with a constant acceleration that
    ends at ``tc`` (the impact stops them: fastest just before), holds for :data:`CLAP_HOLD_S`,
    then parts them smoothly.
    """
    start_close = tc - close_s
    raise_w = _smootherstep((t - (start_close - 0.55)) / 0.5) - _smootherstep((t - (tc + 0.40)) / 0.55)
    u = np.clip((t - start_close) / close_s, 0, 1)
    close = np.where(t <= tc, u**2, 1.0 - _smootherstep((t - tc - CLAP_HOLD_S) / 0.28))
    return raise_w, close


def _pose_arm(body: Body, side: str, frames, pos, chest: Rotation, arms: _Arms, k: int) -> None:
    """Set the frames of one arm (shoulder, elbow, wrist, hand) by two-bone IK to the wrist target.

    Shoulder and elbow frames: y along the bone, x the elbow's hinge axis. The wrist frame is the
    elbow frame turned by the smallest rotation that takes the forearm onto the hand direction,
    then twisted about the hand direction (pronation); the hand frame adds the finger curl.
    """
    ix = body.index
    spine_shoulder = pos[:, ix("SpineShoulder")]
    shoulder = pos[:, ix(f"Shoulder{side}")]
    target = spine_shoulder + chest.apply(arms.wrist[:, k])
    sign = 1.0 if side == "Right" else -1.0
    pole = chest.apply(_dancer_coords(_ELBOW_POLE * [sign, 1, 1]))
    alt_pole = chest.apply(_dancer_coords([0.5 * sign, 0.3, -0.8]))
    l1, l2 = body.length(f"Elbow{side}"), body.length(f"Wrist{side}")
    upper, lower, normal, _ = _two_bone_ik(shoulder, target, l1, l2, pole, alt_pole)
    frames[:, ix(f"Shoulder{side}")] = _quat_xy(normal, upper)
    frames[:, ix(f"Elbow{side}")] = _quat_xy(normal, lower)
    hand_dir = _unit(lower + chest.apply(arms.bias[:, k]))
    if arms.hand_w.any():
        explicit = chest.apply(arms.hand[:, k])
        hand_dir = _unit(hand_dir * (1 - arms.hand_w)[:, None] + explicit * arms.hand_w[:, None])
    wrist = (
        Rotation.from_rotvec(hand_dir * (sign * arms.twist[:, k])[:, None])
        * _min_rotation(lower, hand_dir)
        * Rotation.from_quat(frames[:, ix(f"Elbow{side}")])
    )
    frames[:, ix(f"Wrist{side}")] = wrist.as_quat()
    x_axis = wrist.apply(np.array([1.0, 0.0, 0.0]))
    curl = Rotation.from_rotvec(x_axis * (_CURL_SIGN * arms.curl[:, k])[:, None])
    frames[:, ix(f"Hand{side}")] = (curl * wrist).as_quat()


def _pose_leg(body: Body, side: str, frames, pos, ankle, knee_dir, foot_dir) -> None:
    """Set the frames of one leg (hip, knee, ankle) by two-bone IK to the ankle target."""
    ix = body.index
    hip = pos[:, ix(f"Hip{side}")]
    l1, l2 = body.length(f"Knee{side}"), body.length(f"Ankle{side}")
    upper, lower, normal, _ = _two_bone_ik(hip, ankle, l1, l2, knee_dir, UP)
    frames[:, ix(f"Hip{side}")] = _quat_xy(normal, upper)
    frames[:, ix(f"Knee{side}")] = _quat_xy(normal, lower)
    frames[:, ix(f"Ankle{side}")] = Rotation.from_matrix(_frame_yz(foot_dir, UP)).as_quat()


# -- geometry ----------------------------------------------------------------------------------
def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _frame_yz(y: np.ndarray, z_hint: np.ndarray) -> np.ndarray:
    """[..., 3, 3] rotation matrices (columns x, y, z) with y along ``y`` and z as close as possible
    to ``z_hint`` (which must not be parallel to ``y``)."""
    y = _unit(np.asarray(y, float))
    x = _unit(np.cross(y, np.broadcast_to(np.asarray(z_hint, float), y.shape)))
    return np.stack([x, y, np.cross(x, y)], axis=-1)


def _matrix_xy(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """[T, 3, 3] rotation matrices (columns x, y, z) with the given orthonormal x and y axes [T, 3]."""
    return np.stack([x, y, np.cross(x, y)], axis=-1)


def _quat_xy(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Quaternions (x, y, z, w) of frames with the given orthonormal x and y axes [T, 3]."""
    return Rotation.from_matrix(_matrix_xy(x, y)).as_quat()


def _min_rotation(a: np.ndarray, b: np.ndarray) -> Rotation:
    """The smallest rotations taking unit vectors ``a`` onto unit vectors ``b`` ([T, 3]; never opposite)."""
    axis = np.cross(a, b)
    s = np.linalg.norm(axis, axis=-1)
    angle = np.arctan2(s, np.sum(a * b, axis=-1))
    scale = np.where(s > 1e-12, angle / np.maximum(s, 1e-12), 1.0)
    return Rotation.from_rotvec(axis * scale[:, None])


def _two_bone_ik(root, target, l1, l2, pole, alt_pole):
    """Analytic two-bone IK.

    Returns the unit directions of the upper and lower bones [T, 3], the unit normal of the
    limb's plane [T, 3] (the hinge axis) and the reach ratio |target - root| / (l1 + l2) [T].
    The middle joint bends towards ``pole`` (``alt_pole`` takes over smoothly where ``pole`` is
    nearly along the limb). Out-of-reach targets are softly clamped to 99.95 % of full extension,
    too near ones to a 150 degree bend.
    """
    u = target - root
    d = np.linalg.norm(u, axis=-1)
    u = u / d[:, None]
    d_min = np.sqrt(l1**2 + l2**2 - 2 * l1 * l2 * np.cos(np.radians(30)))
    d_max = 0.9995 * (l1 + l2)
    # Soft clamps (smooth; exact to a micrometre 3 cm above d_min and 1.5 cm below d_max).
    dc = d_min + 0.002 * np.logaddexp(0, (d - d_min) / 0.002)
    dc = d_max - 0.002 * np.logaddexp(0, (d_max - dc) / 0.002)

    def ortho(p):
        p = p - np.sum(p * u, axis=1, keepdims=True) * u
        return p, np.linalg.norm(p, axis=1, keepdims=True)

    v1, n1 = ortho(pole)
    v2, n2 = ortho(alt_pole)
    w = _smootherstep((n1 / np.linalg.norm(pole, axis=-1, keepdims=True) - 0.15) / 0.2)
    v = _unit(w * v1 / np.maximum(n1, 1e-9) + (1 - w) * v2 / np.maximum(n2, 1e-9))
    cos_a = np.clip((l1**2 + dc**2 - l2**2) / (2 * l1 * dc), -1, 1)
    sin_a = np.sqrt(1 - cos_a**2)
    mid = l1 * (cos_a[:, None] * u + sin_a[:, None] * v)
    upper = mid / l1
    lower = _unit(dc[:, None] * u - mid)
    normal = _unit(np.cross(u, v))
    return upper, lower, normal, d / (l1 + l2)
