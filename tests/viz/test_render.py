"""Skeleton animations: where joints land in a frame, GIF and MP4 files, time selection, atomic writes, CLI."""

from __future__ import annotations

import re
import subprocess
import sys

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import REPO
from PIL import Image
from scipy import ndimage

from kinectdata.align.aligned import AlignedRecording
from kinectdata.cli import main
from kinectdata.core.errors import KinectDataError
from kinectdata.core.jointsets import joint_side, load_joint_set
from kinectdata.core.motion import Motion
from kinectdata.formats.csv_writer import write_csv
from kinectdata.viz import render

imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg")
SAMPLE_CSV = REPO / "sample_data" / "synth_001.csv"
SAMPLE_FLAC = REPO / "sample_data" / "synth_001.flac"
SMALL = (160, 120)

# A person standing 2.5 m in front of a Kinect, facing it, arms out: Kinect camera space, metres
# (x to the sensor's left, which is the person's right; y up; z away from the sensor).
STANDING = {
    "Head": (0.0, 0.70, 2.5),
    "Neck": (0.0, 0.55, 2.5),
    "SpineShoulder": (0.0, 0.45, 2.5),
    "SpineMid": (0.0, 0.15, 2.5),
    "SpineBase": (0.0, -0.10, 2.5),
    "ShoulderRight": (0.20, 0.45, 2.5),
    "ElbowRight": (0.45, 0.45, 2.5),
    "WristRight": (0.65, 0.45, 2.5),
    "HandRight": (0.72, 0.45, 2.5),
    "HandTipRight": (0.80, 0.45, 2.5),
    "ThumbRight": (0.70, 0.50, 2.45),
    "ShoulderLeft": (-0.20, 0.45, 2.5),
    "ElbowLeft": (-0.45, 0.45, 2.5),
    "WristLeft": (-0.65, 0.45, 2.5),
    "HandLeft": (-0.72, 0.45, 2.5),
    "HandTipLeft": (-0.80, 0.45, 2.5),
    "ThumbLeft": (-0.70, 0.50, 2.45),
    "HipRight": (0.10, -0.10, 2.5),
    "KneeRight": (0.10, -0.50, 2.5),
    "AnkleRight": (0.10, -0.88, 2.5),
    "FootRight": (0.10, -0.92, 2.38),
    "HipLeft": (-0.10, -0.10, 2.5),
    "KneeLeft": (-0.10, -0.50, 2.5),
    "AnkleLeft": (-0.10, -0.88, 2.5),
    "FootLeft": (-0.10, -0.92, 2.38),
}


def _one_joint_frames(joint_set, pose: dict, shown: list[list[str]], fps: float = 10.0) -> Motion:
    """Frame 0: the whole pose (it fixes the limits); frame i + 1: only the joints shown[i]."""
    base = np.array([pose[n] for n in joint_set.names], dtype=np.float64)
    T = len(shown) + 1
    mask = np.zeros((T, len(joint_set)), bool)
    mask[0] = True
    for i, names in enumerate(shown):
        mask[i + 1, [joint_set.index(n) for n in names]] = True
    return Motion(np.arange(T) / fps, np.repeat(base[None], T, axis=0), joint_set, position_mask=mask)


def _dots(rgb: np.ndarray, darkest: int = 60) -> list[tuple[float, float]]:
    """(row, column) centroids of the black joint dots; text and axes are lighter grey."""
    labels, n = ndimage.label(np.all(rgb < darkest, axis=-1))
    return ndimage.center_of_mass(np.ones(rgb.shape[:2]), labels, range(1, n + 1))


def _one_dot(rgb: np.ndarray) -> tuple[float, float]:
    dots = _dots(rgb)
    assert len(dots) == 1, dots
    return dots[0]


def _coloured(rgb: np.ndarray) -> int:
    """Pixels clearly red or blue (bones, and the side legend)."""
    r, b = rgb[..., 0].astype(int), rgb[..., 2].astype(int)
    return int(np.sum(np.abs(r - b) > 80))


def _probe(path) -> str:
    """ffmpeg's description of a media file (its standard error)."""
    run = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-i", str(path)], capture_output=True)
    return run.stderr.decode(errors="replace")


def _duration(probe: str) -> float:
    h, m, s = re.search(r"Duration: (\d+):(\d+):([\d.]+)", probe).groups()
    return 3600 * int(h) + 60 * int(m) + float(s)


# -- geometry and timing ---------------------------------------------------------------------------


@pytest.mark.parametrize("up", [0, 1, 2])
def test_view_coordinates_rotate_without_mirroring(up):
    rng = np.random.default_rng(up)
    p = rng.normal(size=(50, 3))
    v = render.view_coordinates(p, up)
    matrix, *_ = np.linalg.lstsq(p, v, rcond=None)  # v = p @ matrix
    assert np.allclose(matrix @ matrix.T, np.eye(3), atol=1e-9)
    assert np.linalg.det(matrix) == pytest.approx(1.0)
    assert np.allclose(v[:, 2], p[:, up])  # the up axis is drawn up


def test_kinect_axes_seen_from_the_sensor():
    # the sensor's left (+x) goes to the viewer's left (-right), z (away from the sensor) is depth, y up
    assert np.allclose(render.view_coordinates(np.array([1.0, 2.0, 3.0])), [-1.0, 3.0, 2.0])


@pytest.mark.parametrize(
    "name, side",
    [
        ("HandRight", "right"),
        ("ShoulderLeft", "left"),
        ("RIGHT_HAND", "right"),
        ("CLAVICLE_LEFT", "left"),
        ("RElbow", "right"),
        ("LAnkle", "left"),
        ("SpineBase", "centre"),
        ("NECK", "centre"),
        ("LOWER_BACK", "centre"),
        ("Head", "centre"),
        ("lShldr", "left"),
        ("L5", "centre"),
        ("mixamorig:RightForeArm", "right"),
        ("lhumerus", "left"),
        ("rtibia", "right"),
        ("LHIP", "left"),
        ("leftknee", "left"),
        ("lowerback", "centre"),
        ("root", "centre"),
        ("rhand", "right"),
        ("thorax", "centre"),
        ("ltoes", "left"),
    ],
)
def test_joint_side(name, side):
    assert joint_side(name) == side


def test_frame_times_and_nearest_frames():
    assert np.allclose(render.frame_times(1.0, 2.0, 10.0), 1.0 + np.arange(10) / 10)
    assert len(render.frame_times(0.0, 1.01, 10.0)) == 11  # a partial frame interval still gets a frame
    times = np.array([0.0, 0.1, 0.2])
    index, ended = render.nearest_frames(times, np.array([0.04, 0.05, 0.06, 0.26, 0.31]), span=0.3)
    assert index.tolist() == [0, 0, 1, 2, 2]  # the tie at 0.05 goes to the earlier frame
    assert ended.tolist() == [False, False, False, False, True]


def test_motion_span_is_last_frame_plus_one_interval():
    js = load_joint_set("kinect_v2")
    m = Motion(np.array([0.0, 0.04, 0.08, 0.12]), np.zeros((4, len(js), 3)), js)
    assert render.motion_span(m) == pytest.approx(0.16)


# -- single frames -----------------------------------------------------------------------------------


def test_3d_person_facing_the_sensor_is_upright_and_not_mirrored():
    js = load_joint_set("kinect_v2")
    shown = [["Head"], ["FootLeft", "FootRight"], ["HandRight"], ["HandLeft"], []]
    m = _one_joint_frames(js, STANDING, shown)
    r = render.SkeletonRenderer([m], size=SMALL)
    full, head, feet, right, left, empty = (r.render(t) for t in m.times)
    assert full.shape == (SMALL[1], SMALL[0], 3) and full.dtype == np.uint8
    head_row, _ = _one_dot(head)
    assert all(head_row < row for row, _ in _dots(feet)) and len(_dots(feet)) == 2
    assert _one_dot(right)[1] < _one_dot(left)[1]  # the person's right hand is on the viewer's left
    # the person's right side is drawn red, on the viewer's left; the left side blue
    r_, g_, b_ = (full[..., i].astype(int) for i in range(3))
    body = slice(int(0.1 * SMALL[1]), int(0.85 * SMALL[1]))  # without the legend text
    red_cols = np.nonzero((r_ - b_)[body] > 80)[1]
    blue_cols = np.nonzero((b_ - r_)[body] > 80)[1]
    assert red_cols.mean() < blue_cols.mean()
    # masked joints and bones touching them are not drawn: one joint draws a dot and no bone
    assert _coloured(head) == _coloured(empty) < _coloured(full)
    assert _dots(empty) == []


def test_3d_up_axis_from_gravity_metadata():
    js = load_joint_set("kinect_v2")
    z_up = {name: (x, z, y) for name, (x, y, z) in STANDING.items()}  # height on z now
    m = _one_joint_frames(js, z_up, [["Head"], ["FootLeft", "FootRight"]])
    m.metadata["gravity_axis"] = "Z"
    r = render.SkeletonRenderer([m], size=SMALL)
    head_row, _ = _one_dot(r.render(m.times[1]))
    assert all(head_row < row for row, _ in _dots(r.render(m.times[2])))


def test_2d_image_axes_y_down_equal_scale():
    js = load_joint_set("openpose_mpi")
    pose = {n: (500.0, 500.0) for n in js.names}
    pose.update({"Head": (500, 100), "RAnkle": (460, 900), "LAnkle": (540, 900), "RWrist": (300, 400)})
    pose.update({"LWrist": (700, 400), "Chest": (500, 400)})
    m = _one_joint_frames(js, pose, [["Head"], ["RAnkle"], ["RWrist"], ["LWrist"], ["Chest"]])
    r = render.SkeletonRenderer([m], size=SMALL)
    head, ankle, rwrist, lwrist, chest = (_one_dot(r.render(t)) for t in m.times[1:])
    assert head[0] < ankle[0]  # smaller y is higher up: y grows downwards
    assert rwrist[1] < lwrist[1]  # x is not flipped
    # one scale on both axes: screen pixels per data unit across (wrist to wrist) and down (head to chest)
    across = lwrist[1] - rwrist[1]  # 400 data units
    down = chest[0] - head[0]  # 300 data units
    assert across / 400 == pytest.approx(down / 300, rel=0.04)


def test_a_travelling_dancer_is_drawn_as_large_as_one_who_stays_and_kept_in_view():
    # the same standing body twice: once where it stands, once crossing 5 m of floor in 2 s
    js = load_joint_set("kinect_v2")
    base = np.array([STANDING[n] for n in js.names])
    T = 21
    still = Motion(np.arange(T) / 10.0, np.repeat(base[None], T, axis=0), js)
    path = np.zeros((T, 1, 3))
    path[:, 0, 0] = np.linspace(0.0, 5.0, T)
    travelling = Motion(np.arange(T) / 10.0, base[None] + path, js)
    size = (240, 240)
    r = render.SkeletonRenderer([still, travelling], size=size)
    heights = []
    for t in (0.0, 1.0, 2.0):
        frame = r.render(t)
        for panel in (frame[:, : size[0]], frame[:, size[0] :]):
            dots = np.array(_dots(panel))
            assert len(dots) >= 15  # the whole body in view (joints close together may merge)
            assert dots[:, 1].min() > 0.1 * size[0] and dots[:, 1].max() < 0.9 * size[0]
            heights.append(dots[:, 0].max() - dots[:, 0].min())
    # head to feet as many pixels in both panels at every moment: one scale, and a camera that follows
    assert max(heights) - min(heights) <= 2 and min(heights) > 0.4 * size[1]


def test_compare_frame_is_twice_as_wide():
    js = load_joint_set("openpose_mpi")
    m = _one_joint_frames(js, {n: (i * 10.0, i * 20.0) for i, n in enumerate(js.names)}, [])
    assert render.SkeletonRenderer([m, m], size=SMALL).render(0.0).shape == (SMALL[1], 2 * SMALL[0], 3)


# -- files -------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def moving_dot() -> Motion:
    """openpose_mpi at 20 fps for 2 s: RAnkle and LAnkle fixed at x = 0 and 39 (y = 0), Head at x = k
    in frame k (y = 20); nothing else valid, so no bone is drawn."""
    js = load_joint_set("openpose_mpi")
    T = 40
    positions = np.zeros((T, len(js), 2))
    positions[:, js.index("LAnkle"), 0] = 39.0
    positions[:, js.index("Head")] = np.stack([np.arange(T), np.full(T, 20.0)], axis=1)
    mask = np.zeros((T, len(js)), bool)
    mask[:, [js.index("Head"), js.index("RAnkle"), js.index("LAnkle")]] = True
    return Motion(np.arange(T) / 20.0, positions, js, position_mask=mask)


def _shown_frames(gif) -> list[float]:
    """The motion frame each GIF frame shows, from where the moving dot is between the fixed ones."""
    shown = []
    with Image.open(gif) as im:
        for i in range(im.n_frames):
            im.seek(i)
            dots = sorted(_dots(np.asarray(im.convert("RGB"))))  # by row: the two fixed dots, then the mover
            (_, a), (_, b) = sorted(dots[:2], key=lambda d: d[1])
            shown.append(39 * (dots[2][1] - a) / (b - a))
    return shown


def test_gif_frames_durations_and_start_end(tmp_path, moving_dot):
    out = tmp_path / "dot.gif"
    done = []
    result = render.render_animation(
        [render.RenderInput(moving_dot, "dot.jsonl")],
        out,
        start=0.5,
        end=1.5,
        fps=10,
        size=SMALL,
        progress=lambda k, n: done.append((k, n)),
    )
    assert result["frames"] == 10 and result["audio"] is None and result["size"] == SMALL
    assert done[-1] == (10, 10) and len(done) == 10
    with Image.open(out) as im:
        assert im.n_frames == 10 and im.size == SMALL
        durations = []
        for i in range(im.n_frames):
            im.seek(i)
            durations.append(im.info["duration"])
    assert durations == [100] * 10
    # output frame n at 0.5 + n / 10 s shows motion frame round(20 t) = 10 + 2n
    assert np.allclose(_shown_frames(out), 10 + 2 * np.arange(10), atol=0.3)


def test_gif_delays_add_up_at_30_fps(tmp_path, moving_dot):
    out = tmp_path / "dot.gif"
    render.render_animation([render.RenderInput(moving_dot, "dot")], out, end=0.5, fps=30, size=SMALL)
    with Image.open(out) as im:
        total = 0
        for i in range(im.n_frames):
            im.seek(i)
            total += im.info["duration"]
    assert im.n_frames == 15 and total == 500  # 15 frames of 1/30 s, as delays of 30 and 40 ms


def test_compare_shorter_motion_is_frozen(tmp_path, moving_dot):
    short = moving_dot.select(slice(0, 10))  # 0.5 s
    out = tmp_path / "both.gif"
    result = render.render_animation(
        [render.RenderInput(moving_dot, "long"), render.RenderInput(short, "short")],
        out,
        start=0.3,
        end=0.9,
        fps=10,
        size=SMALL,
    )
    assert result["ended"] == ["short"]
    with Image.open(out) as im:
        assert im.size == (2 * SMALL[0], SMALL[1])
        frames = []
        for i in range(im.n_frames):
            im.seek(i)
            frames.append(np.asarray(im.convert("RGB"))[:, SMALL[0] :])
    # the right panel shows frames 6, 8 then its last frame (9) while the left one moves on
    right_cols = [max(_dots(f), key=lambda d: d[0])[1] for f in frames]
    assert right_cols[0] < right_cols[1] < right_cols[2]
    assert right_cols[3] == pytest.approx(right_cols[5], abs=0.5)


@pytest.fixture(scope="module")
def aligned_file(tmp_path_factory) -> tuple:
    """An aligned 3-D recording of 4 s at 10 fps whose audio (8 kHz) is a tone of 200 (s + 1) Hz in second s."""
    js = load_joint_set("kinect_v2")
    pose = np.array([STANDING[n] for n in js.names])
    T, sr = 40, 8000
    sway = np.sin(np.arange(T) / 5)[:, None, None] * np.array([0.2, 0.0, 0.0])
    motion = Motion(np.arange(T) / 10.0, pose[None] + sway, js)
    t = np.arange(4 * sr) / sr
    audio = (0.5 * np.sin(2 * np.pi * 200 * (np.floor(t) + 1) * t)).astype(np.float32)
    path = tmp_path_factory.mktemp("aligned") / "take.h5"
    AlignedRecording(motion, audio, sr, 10.0, np.zeros((T, len(js)), bool)).save(path)
    return path, sr


def _decoded_audio(path, sr: int) -> np.ndarray:
    run = subprocess.run(
        [
            imageio_ffmpeg.get_ffmpeg_exe(),
            "-v",
            "error",
            "-i",
            str(path),
            "-f",
            "f32le",
            "-ac",
            "1",
            "-ar",
            str(sr),
            "-",
        ],
        capture_output=True,
        check=True,
    )
    return np.frombuffer(run.stdout, np.float32)


def test_mp4_has_h264_video_and_the_aligned_files_music(tmp_path, aligned_file):
    h5, sr = aligned_file
    out = tmp_path / "take.mp4"
    result = render.render_animation([render.load_input(h5)], out, start=1.0, end=3.0, fps=10, size=SMALL)
    assert result["frames"] == 20 and result["audio"] == str(h5)
    probe = _probe(out)
    assert re.search(r"Video: h264.*yuv420p.*160x120", probe) and "Audio: aac" in probe
    assert _duration(probe) == pytest.approx(2.0, abs=0.1)  # within a frame
    assert imageio_ffmpeg.count_frames_and_secs(str(out))[0] == 20
    sound = _decoded_audio(out, sr)
    assert sound.size / sr == pytest.approx(2.0, abs=0.1)
    # the sound starts at --start: second 1 of the file, its 400 Hz tone (not second 0's 200 Hz)
    head = sound[sr // 10 : sr // 2]
    peak_hz = np.argmax(np.abs(np.fft.rfft(head))) * sr / head.size
    assert peak_hz == pytest.approx(400, abs=5)


def test_cli_renders_the_sample_with_its_flac(tmp_path):
    out = tmp_path / "sample.mp4"
    args = ["render", str(SAMPLE_CSV), "--audio", str(SAMPLE_FLAC), "--start", "1", "--end", "2.5"]
    res = CliRunner().invoke(main, [*args, "--fps", "10", "--size", "160x120", "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert f"wrote {out}: 15 frames at 10 fps" in res.output and "sound from" in res.output
    probe = _probe(out)
    assert "Video: h264" in probe and re.search(r"Audio: aac.*44100 Hz", probe)
    assert _duration(probe) == pytest.approx(1.5, abs=0.1)


def test_cli_compare_2d_synth_is_twice_as_wide(tmp_path):
    made = CliRunner().invoke(main, ["synth", str(tmp_path), "--format", "openpose", "--duration", "8"])
    assert made.exit_code == 0, made.output
    folder = tmp_path / "synth_000_openpose"
    out = tmp_path / "op.gif"
    args = ["render", str(folder), "--compare", str(folder), "--video-fps", "30", "--end", "0.5", "--size", "96x64"]
    res = CliRunner().invoke(main, [*args, "-o", str(out)])
    assert res.exit_code == 0, res.output
    with Image.open(out) as im:
        assert im.size == (192, 64) and im.n_frames == 15  # the video's 30 fps, kept


# -- atomic writing and errors ---------------------------------------------------------------------


@pytest.mark.parametrize("suffix", [".mp4", ".gif"])
def test_failure_mid_way_leaves_nothing(tmp_path, moving_dot, monkeypatch, suffix):
    real = render.SkeletonRenderer.render
    calls = []

    def failing(self, t):
        calls.append(t)
        if len(calls) == 3:
            raise RuntimeError("drawing failed")
        return real(self, t)

    monkeypatch.setattr(render.SkeletonRenderer, "render", failing)
    with pytest.raises(RuntimeError, match="drawing failed"):
        render.render_animation([render.RenderInput(moving_dot, "dot")], tmp_path / f"x{suffix}", fps=10, size=SMALL)
    assert list(tmp_path.iterdir()) == []


def test_ffmpeg_failure_names_the_file_and_quotes_ffmpeg(tmp_path, moving_dot, monkeypatch):
    monkeypatch.setattr(render, "VIDEO_CODEC", "no_such_encoder")
    out = tmp_path / "x.mp4"
    with pytest.raises(KinectDataError) as info:
        render.render_animation([render.RenderInput(moving_dot, "dot")], out, end=0.3, fps=10, size=SMALL)
    message = str(info.value)
    assert message.startswith(f"{out}: ffmpeg failed") and "no_such_encoder" in message
    assert list(tmp_path.iterdir()) == []


def test_mp4_without_imageio_ffmpeg_says_what_to_install(tmp_path, moving_dot, monkeypatch):
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)  # import fails
    with pytest.raises(KinectDataError, match=r"pip install 'kinectdata\[video\]'.*\.gif"):
        render.render_animation([render.RenderInput(moving_dot, "dot")], tmp_path / "x.mp4", size=SMALL)


def test_motion_without_valid_joints_is_refused(tmp_path):
    js = load_joint_set("kinect_v2")
    empty = Motion(np.arange(3) / 30, np.full((3, len(js), 3), np.nan), js)
    with pytest.raises(KinectDataError, match="empty.csv: no valid joint position"):
        render.render_animation([render.RenderInput(empty, "empty.csv")], tmp_path / "x.gif")


@pytest.fixture(scope="module")
def sample_csv_small(tmp_path_factory) -> str:
    """The first 3 s of the sample recording, as canonical CSV."""
    from kinectdata.formats import read_motion

    m = read_motion(SAMPLE_CSV)
    path = tmp_path_factory.mktemp("small") / "small.csv"
    write_csv(m.select(m.times < 3.0), path, "canonical")
    return str(path)


@pytest.mark.parametrize(
    "extra, code, message",
    [
        (["-o", "{tmp}/x.avi"], 1, "x.avi: unknown animation type '.avi'; name the output .mp4 or .gif"),
        (["-o", "{tmp}/x.gif", "--start", "2", "--end", "1"], 1, "small.csv: --start 2 s is not before --end 1 s"),
        (["-o", "{tmp}/x.gif", "--start", "5"], 1, "small.csv: --start 5 s is at or after the end of the motion"),
        (["-o", "{tmp}/x.gif", "--audio", "{flac}"], 1, "x.gif: a GIF has no sound"),
        (["-o", "{tmp}/x.gif", "--fps", "60"], 1, "x.gif: a GIF plays at most 50 frames per second"),
        (["-o", "{tmp}/x.mp4", "--size", "161x120"], 1, "x.mp4: H.264 (yuv420p) needs an even width and height"),
        (["-o", "{tmp}/x.gif", "--size", "640"], 2, "'640' is not WIDTHxHEIGHT"),
        (["-o", "{tmp}/x.gif", "--compare", "{op}"], 1, "op.jsonl: a 2-D motion (openpose_mpi) cannot be drawn"),
        (["-o", "{tmp}/x.gif", "--compare", "{tmp}/missing.csv"], 1, "missing.csv: no such file or folder"),
        (["-o", "{tmp}/x.gif", "--person", "1"], 1, "small.csv: --person applies to none of these files"),
    ],
)
def test_cli_errors(tmp_path, sample_csv_small, extra, code, message):
    from kinectdata.formats.openpose_writer import write_openpose_jsonl

    js = load_joint_set("openpose_mpi")
    op = tmp_path / "op.jsonl"
    write_openpose_jsonl(Motion(np.arange(3) / 30, np.ones((3, len(js), 2)), js), op)
    fill = {"tmp": tmp_path, "flac": SAMPLE_FLAC, "op": op}
    args = ["render", sample_csv_small, "--video-fps", "30"] if "{op}" in extra else ["render", sample_csv_small]
    res = CliRunner().invoke(main, args + [a.format(**fill) for a in extra])
    assert res.exit_code == code, res.output
    assert message in res.output
    assert not any(p.suffix in (".avi", ".gif", ".mp4") or p.name.endswith(".partial") for p in tmp_path.iterdir())
