"""Skeleton animations: motions drawn frame by frame on matplotlib's Agg canvas, written as MP4
(H.264 with the music as AAC, by the ffmpeg binary imageio-ffmpeg bundles) or GIF (Pillow, no sound).

What is drawn, one panel of ``size`` pixels per motion, side by side:

- 3-D joint sets (metres): an orthographic camera raised :data:`VIEW_ELEVATION_DEG` and turned
  :data:`VIEW_AZIMUTH_DEG` from straight ahead, looking the way the sensor looks (Kinect camera
  space: along +z, with x to the sensor's left and y up). A dancer facing the sensor is seen from
  the front as the sensor saw them, not mirrored: their right hand on the viewer's left. The up axis
  is y, or ``metadata["gravity_axis"]`` when a format gives it (HTR). The camera frames the body,
  not the floor it crosses: it follows the body's centre across the floor, smoothed over
  :data:`FOLLOW_S` (:func:`camera_path`; it stays put for a dancer who keeps near one spot), and its
  window is as wide as the farthest joint from where it looks, in any frame (:func:`body_window`),
  one scale on the three axes. The floor is a grid at the lowest valid joint height of the whole
  motion, fixed to the floor, so that it slides by as the dancer travels. Motions compared side by side share one
  window and one grid: a body is drawn the same size in every panel.
- 2-D joint sets (pixels, or 0..1 for generated motion): image axes with y down, one scale on both
  axes, limits from the whole motion's valid joints.
- Bones from the joint set's parents (the person's right side red, left side blue, from the joint
  names), joints as black dots. Masked joints, and bones touching them, are not drawn.
- The file name above, the time and the frame shown below.

Timing: a motion lasts from its first frame (time 0 of the clip) to one median frame interval after
its last (:func:`motion_span`). Output frame k is at ``start + k / fps`` seconds and shows each
motion's nearest frame (no interpolation). In a comparison, the shorter motion stays frozen on its
last frame, captioned "ended", until the longer one ends.
"""

from __future__ import annotations

import subprocess
import tempfile
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np

from kinectdata.core.atomic import atomic_output
from kinectdata.core.errors import KinectDataError
from kinectdata.core.jointsets import joint_side
from kinectdata.core.motion import Motion

DEFAULT_SIZE = (640, 480)
"""Pixels (width, height) of one panel."""
MAX_DEFAULT_FPS = 30.0
"""Frames per second: the default output rate is the motion's, at most this."""
MAX_GIF_FPS = 50.0
"""GIF delays are whole hundredths of a second and players slow down frames shorter than 0.02 s."""
VIEW_ELEVATION_DEG = 20.0
"""Degrees the 3-D camera is raised above the horizontal."""
VIEW_AZIMUTH_DEG = -65.0
"""matplotlib azimuth of the 3-D camera, degrees: -90 looks straight along the sensor's axis."""
FOLLOW_S = 1.0
"""Seconds over which the 3-D camera's centre is smoothed as it follows a travelling dancer."""
VIDEO_CODEC = "libx264"
AUDIO_CODEC = "aac"
ALIGNED_SUFFIXES = (".h5", ".hdf5")
OUTPUT_SUFFIXES = (".mp4", ".gif")
STDERR_LINES = 8
"""Lines of ffmpeg's error output quoted when it fails."""

_DPI = 100
_COLOURS = {"right": "#d62728", "left": "#1f77b4", "centre": "#555555"}
_TEXT_COLOUR = "0.3"  # lighter than the black joint dots, which tests find by colour


@dataclass(eq=False)
class RenderInput:
    """A motion to draw, with the music that came with it (aligned files).

    Attributes:
        motion: its first frame is time 0 of the clip.
        source: the file it came from, named in errors.
        audio: [S] float32 mono samples, sample 0 at the motion's first frame; None if the file has none.
        sample_rate: Hz of ``audio``.
    """

    motion: Motion
    source: str
    audio: np.ndarray | None = None
    sample_rate: int | None = None

    @property
    def label(self) -> str:
        """The panel's title: the file name."""
        return Path(self.source).name


def load_input(path: str | Path, *, with_audio: bool = True, **reader_options: Any) -> RenderInput:
    """Read a recording (any format :func:`~kinectdata.formats.read_motion` reads, with
    ``reader_options``) or an aligned ``.h5`` (its motion and, with ``with_audio``, its audio;
    reader options do not apply to it and are ignored)."""
    from kinectdata.align.aligned import AlignedRecording
    from kinectdata.formats import read_motion

    path = Path(path)
    if path.suffix.lower() in ALIGNED_SUFFIXES:
        rec = AlignedRecording.load(path, audio=with_audio)
        return RenderInput(rec.motion, str(path), rec.audio if with_audio else None, rec.sample_rate)
    return RenderInput(read_motion(path, **reader_options), str(path))


def load_inputs(
    paths: Sequence[str | Path], *, with_audio: bool = True, format: str | None = None, **reader_options: Any
) -> list[RenderInput]:
    """Read the motions to draw side by side with :func:`load_input`.

    ``format`` applies to the first path; every other reader option (``schema``, ``body``,
    ``person``, ``video_fps``) to each recording whose reader takes it, so that one ``video_fps``
    serves an OpenPose file compared with a CSV file. An option no recording takes is an error.
    """
    from kinectdata.formats.registry import detect_format, readers

    given = {k: v for k, v in reader_options.items() if v is not None}
    unused = set(given)
    inputs = []
    for i, path in enumerate(paths):
        if Path(path).suffix.lower() in ALIGNED_SUFFIXES:
            unused |= {"format"} if i == 0 and format is not None else set()
            inputs.append(load_input(path, with_audio=with_audio))
            continue
        name = (format if i == 0 else None) or detect_format(path)
        reader = readers().get(name)  # None: read_motion names the unknown format
        takes = {k: v for k, v in given.items() if reader is None or k in reader.options}
        unused -= takes.keys()
        inputs.append(load_input(path, with_audio=with_audio, format=name, **takes))
    if unused:
        options = ", ".join("--" + k.replace("_", "-") for k in sorted(unused))
        raise KinectDataError(f"{' and '.join(str(p) for p in paths)}: {options} applies to none of these files")
    return inputs


# -- geometry and timing ---------------------------------------------------------------------------


def up_axis(motion: Motion) -> int:
    """Index (0, 1, 2) of the vertical axis of a 3-D motion: ``metadata["gravity_axis"]`` (X, Y or
    Z) when given, else 1 (y, as in Kinect camera space)."""
    axis = str(motion.metadata.get("gravity_axis") or "Y").strip().upper()
    return {"X": 0, "Y": 1, "Z": 2}.get(axis, 1)


def view_coordinates(positions: np.ndarray, up: int = 1) -> np.ndarray:
    """[..., 3] positions -> [..., 3] (right, depth, up) as seen by a viewer looking along +depth.

    The axes are permuted cyclically so that ``up`` comes last and the one after it is the depth,
    and the remaining axis is negated (a rotation: nothing is mirrored). For Kinect camera space
    (``up=1``) this is (-x, z, y): the sensor's left, +x, is the viewer's left.
    """
    depth, across = (up + 1) % 3, (up + 2) % 3
    return np.stack([-positions[..., across], positions[..., depth], positions[..., up]], axis=-1)


def motion_span(motion: Motion) -> float:
    """Seconds a motion lasts: from its first frame to one median frame interval after its last
    (1 / :data:`MAX_DEFAULT_FPS` for a single frame)."""
    if motion.n_frames < 2:
        return 1.0 / MAX_DEFAULT_FPS
    return float(motion.times[-1] - motion.times[0] + np.median(np.diff(motion.times)))


def frame_times(start: float, end: float, fps: float) -> np.ndarray:
    """[N] seconds ``start + k / fps`` of the output frames covering [start, end): N = ceil((end - start) * fps)."""
    n = int(np.ceil((end - start) * fps - 1e-9))
    return start + np.arange(max(n, 0)) / fps


def nearest_frames(times: np.ndarray, t: np.ndarray, span: float) -> tuple[np.ndarray, np.ndarray]:
    """The frame to show at each output time.

    Args:
        times: [T] seconds of the motion's frames, increasing, ``times[0] == 0``.
        t: [N] seconds of the output frames.
        span: seconds the motion lasts (:func:`motion_span`).

    Returns:
        [N] int index of the frame nearest to each ``t`` (ties: the earlier), and [N] bool, True
        where ``t >= span`` (the motion has ended; the index is then its last frame).
    """
    t = np.asarray(t, dtype=np.float64)
    after = np.clip(np.searchsorted(times, t), 0, len(times) - 1)
    before = np.maximum(after - 1, 0)
    index = np.where(np.abs(t - times[before]) <= np.abs(times[after] - t), before, after)
    return index, t >= span


def _limits(points: np.ndarray, margin: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper [D] bounds of [N, D] points, widened by ``margin`` of the largest extent;
    every extent at least a fifth of the largest (1 unit if the points coincide)."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    largest = float(np.max(hi - lo)) or 1.0
    centre, half = (lo + hi) / 2, np.maximum(hi - lo, 0.2 * largest) / 2 + margin * largest
    return centre - half, centre + half


# -- drawing --------------------------------------------------------------------------------------


class _Panel:
    """One motion in a column ``[x0, x0 + width]`` (figure fractions) of the figure."""

    def __init__(self, figure, x0: float, width: float, motion: Motion, label: str) -> None:
        from matplotlib.colors import to_rgba_array

        self.motion = motion
        self.times = motion.times - motion.times[0]
        self.span = motion_span(motion)
        self.bones = np.array(motion.joint_set.bones(), dtype=np.intp).reshape(-1, 2)
        names = motion.joint_set.names
        self.bone_colours = to_rgba_array([_COLOURS[joint_side(names[c])] for _, c in self.bones]).reshape(-1, 4)
        self.figure, self.x0, self.width = figure, x0, width
        self.scale = max(0.6, min(1.0, width * figure.bbox.width / 640, figure.bbox.height / 480))  # small panels
        self.font = 8.0 * self.scale  # points
        self.line = 1.4 * self.font * figure.dpi / 72 / figure.bbox.height  # a text line, figure fraction
        figure.text(x0 + width / 2, 0.98, label, ha="center", va="top", fontsize=1.25 * self.font, color=_TEXT_COLOUR)
        for i, side in enumerate(("right", "left")):
            y = 0.98 - i * self.line
            figure.text(
                x0 + 0.98 * width, y, f"{side} side", ha="right", va="top", fontsize=self.font, color=_COLOURS[side]
            )
        self.caption = self.text_line(0, "")

    def text_line(self, line: int, text: str):
        """A text at the bottom left of the panel, ``line`` lines up."""
        x, y = self.x0 + 0.02 * self.width, 0.015 + line * self.line
        return self.figure.text(x, y, text, fontsize=self.font, family="monospace", color=_TEXT_COLOUR)

    def show(self, t: float) -> None:
        """Set the artists to the frame nearest to clip time ``t`` (seconds)."""
        index, ended = nearest_frames(self.times, np.array([t]), self.span)
        k = int(index[0])
        valid = self.motion.position_mask[k]
        self._draw(k, valid, valid[self.bones[:, 0]] & valid[self.bones[:, 1]])
        state = f"ended at {self.span:.2f} s (frozen)" if ended[0] else f"frame {k} of {self.motion.n_frames}"
        self.caption.set_text(f"t = {t:.3f} s  {state}")

    def _draw(self, k: int, valid: np.ndarray, bone_valid: np.ndarray) -> None:
        raise NotImplementedError


def body_window(motion: Motion) -> tuple[float, float]:
    """(half width, height) in metres of the window a 3-D camera needs to frame ``motion``'s body in
    every frame from where it stands (:func:`camera_path`): the largest horizontal distance of a
    valid joint from the camera's centre, and the highest valid joint above the motion's floor."""
    return _camera(motion)[1:]


def camera_path(motion: Motion) -> np.ndarray:
    """[T, 2] where the 3-D camera is centred, horizontally, in each frame (view coordinates): the
    middle of the body's path when the body keeps within its reach of it, else the body's centre (the
    mean of its valid joints) smoothed over :data:`FOLLOW_S`."""
    return _camera(motion)[0]


def _camera(motion: Motion) -> tuple[np.ndarray, float, float]:
    from scipy.ndimage import uniform_filter1d

    from kinectdata.core.motion import frame_clock

    points = view_coordinates(motion.positions, up_axis(motion))
    mask = motion.position_mask
    centre = _centres(points, mask)
    reach = float(np.where(mask, np.linalg.norm(points[..., :2] - centre[:, None, :], axis=-1), 0.0).max()) or 0.5
    travel = centre.max(axis=0) - centre.min(axis=0)
    if np.all(travel <= 0.5 * reach) or motion.n_frames < 2:  # keeps near one spot: a camera that stays put
        path = np.broadcast_to((centre.max(axis=0) + centre.min(axis=0)) / 2, centre.shape)
    else:
        frames = max(1, int(round(FOLLOW_S / frame_clock(motion.times)[0])))
        path = uniform_filter1d(centre, frames, axis=0, mode="nearest")
    half = float(np.where(mask, np.linalg.norm(points[..., :2] - path[:, None, :], axis=-1), 0.0).max()) or 0.5
    floor = float(points[..., 2][mask].min())
    return path, half, float(points[..., 2][mask].max() - floor) or 1.0


def _centres(points: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """[T, 2] the horizontal mean of each frame's valid joints (the last seen where none is)."""
    count = mask.sum(axis=1, keepdims=True)
    centre = np.where(mask[..., None], points[..., :2], 0.0).sum(axis=1) / np.maximum(count, 1)
    seen = count[:, 0] > 0
    last = np.maximum.accumulate(np.where(seen, np.arange(len(seen)), 0))
    first = int(np.argmax(seen))
    return centre[np.where(seen[last], last, first)]


class _Panel3D(_Panel):
    """An orthographic camera that follows the body over a floor grid (see the module docstring);
    ``window``: the (half width, height) in metres it frames, shared by compared motions."""

    def __init__(self, figure, x0: float, width: float, motion: Motion, label: str,
                 window: tuple[float, float] | None = None) -> None:  # fmt: skip
        from matplotlib.ticker import MaxNLocator
        from mpl_toolkits.mplot3d.art3d import Line3DCollection

        super().__init__(figure, x0, width, motion, label)
        self.points = view_coordinates(motion.positions, up_axis(motion))  # [T, J, 3]
        mask = motion.position_mask
        self.centres, own_half, own_height = _camera(motion)
        half, height = window or (own_half, own_height)
        self.half = half * 1.05  # a margin round the farthest joint
        self.floor = float(self.points[..., 2][mask].min())
        self.top = self.floor + max(height * 1.05, 2 * self.half * 0.2)
        self.step = float(np.diff(MaxNLocator(nbins=6).tick_values(0, 2 * self.half))[0])
        self.ax = ax = figure.add_axes((x0, 0.07, width, 0.86), projection="3d")
        ax.set_proj_type("ortho")
        ax.view_init(elev=VIEW_ELEVATION_DEG, azim=VIEW_AZIMUTH_DEG)
        ax.set_axis_off()
        ax.computed_zorder = False  # dots over bones over floor, whatever their depth
        lo, hi = self._window(0)
        self.grid = Line3DCollection([[lo, hi]], colors="0.82", linewidths=0.8, zorder=1)
        ax.add_collection3d(self.grid)
        self.lines = Line3DCollection([[lo, hi]], linewidths=2.5 * self.scale, zorder=2)
        ax.add_collection3d(self.lines)
        (self.dots,) = ax.plot(*np.stack([lo, hi], axis=1), "o", color="k", markersize=4 * self.scale, zorder=3)
        ax.set_box_aspect(hi - lo, zoom=1.25)
        self._place(0)
        self.text_line(1, f"floor grid {self.step:g} m")

    def _window(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        c = self.centres[k]
        return (np.array([c[0] - self.half, c[1] - self.half, self.floor]),
                np.array([c[0] + self.half, c[1] + self.half, self.top]))  # fmt: skip

    def _place(self, k: int) -> None:
        """The camera's window and the floor grid's lines (fixed to the floor) for frame ``k``."""
        lo, hi = self._window(k)
        across = np.arange(np.ceil(lo[0] / self.step), np.floor(hi[0] / self.step) + 1) * self.step
        along = np.arange(np.ceil(lo[1] / self.step), np.floor(hi[1] / self.step) + 1) * self.step
        grid = [[(x, lo[1], self.floor), (x, hi[1], self.floor)] for x in across]
        grid += [[(lo[0], y, self.floor), (hi[0], y, self.floor)] for y in along]
        self.grid.set_segments(grid)
        self.ax.set_xlim(lo[0], hi[0])
        self.ax.set_ylim(lo[1], hi[1])
        self.ax.set_zlim(lo[2], hi[2])

    def _draw(self, k: int, valid: np.ndarray, bone_valid: np.ndarray) -> None:
        p = self.points[k]
        self._place(k)
        self.lines.set_segments(p[self.bones[bone_valid]])
        self.lines.set_color(self.bone_colours[bone_valid])
        self.lines.set_visible(bool(bone_valid.any()))
        self.dots.set_data_3d(*p[valid].T)


class _Panel2D(_Panel):
    """Image axes, y down (see the module docstring)."""

    def __init__(self, figure, x0: float, width: float, motion: Motion, label: str) -> None:
        from matplotlib.collections import LineCollection

        super().__init__(figure, x0, width, motion, label)
        box = (x0 + 0.12 * width, 0.14, 0.84 * width, 0.78)
        ax = figure.add_axes(box)
        lo, hi = _limits(motion.positions[motion.position_mask])
        # widen one range so that a unit is as long on both axes in the box's pixels
        box_w, box_h = box[2] * figure.bbox.width, box[3] * figure.bbox.height
        per_pixel = max((hi[0] - lo[0]) / box_w, (hi[1] - lo[1]) / box_h)  # data units
        centre, half = (lo + hi) / 2, per_pixel * np.array([box_w, box_h]) / 2
        lo, hi = centre - half, centre + half
        self.lines = LineCollection(np.zeros((1, 2, 2)), linewidths=2.5 * self.scale, zorder=2)
        ax.add_collection(self.lines, autolim=False)
        (self.dots,) = ax.plot([], [], "o", color="k", markersize=4 * self.scale, zorder=3)
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(hi[1], lo[1])  # image axes: y grows downwards
        ax.set_aspect("equal", adjustable="box")
        ax.tick_params(labelsize=self.font * 7 / 8, colors=_TEXT_COLOUR)
        for spine in ax.spines.values():
            spine.set_color(_TEXT_COLOUR)
        ax.set_xlabel("x", fontsize=self.font, color=_TEXT_COLOUR)
        ax.set_ylabel("y (down)", fontsize=self.font, color=_TEXT_COLOUR)

    def _draw(self, k: int, valid: np.ndarray, bone_valid: np.ndarray) -> None:
        p = self.motion.positions[k]
        self.lines.set_segments(p[self.bones[bone_valid]])
        self.lines.set_color(self.bone_colours[bone_valid])
        self.dots.set_data(*p[valid].T)


class SkeletonRenderer:
    """Motions side by side on one reused Agg figure, a panel of ``size`` (width, height) pixels each.

    Each panel's window, floor and the camera's path are worked out from the whole motion when the
    renderer is made (one window for all the 3-D motions); :meth:`render` then moves the camera,
    the bones and the dots.
    """

    def __init__(
        self, motions: Sequence[Motion], labels: Sequence[str] | None = None, size: tuple[int, int] = DEFAULT_SIZE
    ) -> None:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        width, height = size
        labels = list(labels) if labels is not None else [""] * len(motions)
        self.size = (width * len(motions), height)
        self.figure = Figure(figsize=(self.size[0] / _DPI, height / _DPI), dpi=_DPI, facecolor="white")
        FigureCanvasAgg(self.figure)
        share = 1.0 / len(motions)
        windows = [body_window(m) for m in motions if m.joint_set.dimensions == 3]
        window = tuple(np.max(windows, axis=0)) if windows else None  # one scale for every 3-D panel
        self.panels = [
            _Panel3D(self.figure, i * share, share, m, label, window)
            if m.joint_set.dimensions == 3
            else _Panel2D(self.figure, i * share, share, m, label)
            for i, (m, label) in enumerate(zip(motions, labels))
        ]

    def render(self, t: float) -> np.ndarray:
        """The frame at clip time ``t`` (seconds) as [height, width, 3] uint8 RGB."""
        for panel in self.panels:
            panel.show(t)
        self.figure.canvas.draw()
        return np.ascontiguousarray(np.asarray(self.figure.canvas.buffer_rgba())[:, :, :3])


def render_frame(motion: Motion, t: float, size: tuple[int, int] = DEFAULT_SIZE) -> np.ndarray:
    """One frame of ``motion`` at ``t`` seconds after its first frame, as [height, width, 3] uint8 RGB."""
    return SkeletonRenderer([motion], size=size).render(t)


# -- writing --------------------------------------------------------------------------------------


def ffmpeg_executable(out: str | Path) -> str:
    """Path of imageio-ffmpeg's ffmpeg binary; KinectDataError naming ``out`` if there is none."""
    try:
        import imageio_ffmpeg
    except ImportError:
        raise KinectDataError(
            f"{out}: writing MP4 needs imageio-ffmpeg: pip install 'kinectdata[video]' (or write a .gif, without sound)"
        ) from None
    try:
        return imageio_ffmpeg.get_ffmpeg_exe()
    except RuntimeError as exc:
        raise KinectDataError(f"{out}: imageio-ffmpeg finds no ffmpeg binary ({exc})") from exc


def write_mp4(
    frames: Iterable[np.ndarray],
    path: str | Path,
    fps: float,
    size: tuple[int, int],
    audio: np.ndarray | None = None,
    sample_rate: int | None = None,
) -> int:
    """Encode [height, width, 3] uint8 RGB frames as H.264 (yuv420p) MP4 at ``fps`` frames per second,
    with ``audio`` ([S] float32 mono at ``sample_rate`` Hz) as AAC if given, atomically: if
    anything fails, no file is left. ``size`` is (width, height), both even. Returns the frame count."""
    path = Path(path)
    width, height = size
    if width % 2 or height % 2:
        raise KinectDataError(f"{path}: H.264 (yuv420p) needs an even width and height, not {width}x{height}")
    command = [ffmpeg_executable(path), "-y", "-hide_banner", "-loglevel", "error", "-f", "rawvideo"]
    command += ["-pix_fmt", "rgb24", "-s", f"{width}x{height}", "-framerate", str(Fraction(fps).limit_denominator())]
    command += ["-i", "-"]
    with tempfile.TemporaryDirectory(prefix="kinectdata-render-") as work, atomic_output(path) as tmp:
        if audio is not None:
            import soundfile

            wav = Path(work) / "audio.wav"
            soundfile.write(wav, np.asarray(audio, dtype=np.float32), int(sample_rate), subtype="FLOAT")
            command += ["-i", str(wav), "-map", "0:v:0", "-map", "1:a:0", "-c:a", AUDIO_CODEC, "-b:a", "160k"]
        command += ["-c:v", VIDEO_CODEC, "-pix_fmt", "yuv420p", "-movflags", "+faststart", "-f", "mp4", str(tmp)]
        log_path = Path(work) / "ffmpeg.log"
        with open(log_path, "wb") as log:
            count, status = _pipe_frames(command, frames, log, (height, width, 3), path)
        if status != 0:
            lines = log_path.read_text(errors="replace").strip().splitlines()[-STDERR_LINES:]
            raise KinectDataError(f"{path}: ffmpeg failed (exit status {status}): " + " | ".join(lines))
    return count


def _pipe_frames(command: list[str], frames: Iterable[np.ndarray], log, shape: tuple, path: Path) -> tuple[int, int]:
    """Run ffmpeg, write the frames to its standard input; (frames written, exit status). ffmpeg is
    killed if writing stops on an error."""
    process = subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=log)
    count = 0
    try:
        for frame in frames:
            if frame.shape != shape or frame.dtype != np.uint8:
                raise KinectDataError(f"{path}: frame {count} is {frame.shape} {frame.dtype}, not {shape} uint8")
            process.stdin.write(frame.tobytes())
            count += 1
    except BrokenPipeError:  # ffmpeg stopped reading: its exit status and log say why
        pass
    except BaseException:
        process.kill()
        raise
    finally:
        try:
            process.stdin.close()
        except BrokenPipeError:
            pass
        process.wait()
    return count, process.returncode


def write_gif(frames: Iterable[np.ndarray], path: str | Path, fps: float) -> int:
    """Write [height, width, 3] uint8 RGB frames as a looping GIF (Pillow), atomically. Frame delays
    are whole hundredths of a second, chosen so that frame k starts at round(100 k / fps) / 100 s;
    ``fps`` at most :data:`MAX_GIF_FPS`. Every frame is held in memory (width x height bytes each)
    until the file is written. Returns the frame count."""
    from PIL import Image

    path = Path(path)
    if fps > MAX_GIF_FPS:
        raise KinectDataError(
            f"{path}: a GIF plays at most {MAX_GIF_FPS:g} frames per second, not {fps:g}; lower --fps"
        )
    with atomic_output(path) as tmp:  # first: an output that cannot be written fails before the drawing
        images = [Image.fromarray(frame).quantize(colors=64) for frame in frames]
        if not images:
            raise KinectDataError(f"{path}: no frames to write")
        starts_cs = np.round(np.arange(len(images) + 1) * 100.0 / fps)
        durations_ms = (np.diff(starts_cs) * 10).astype(int).tolist()
        images[0].save(tmp, format="GIF", save_all=True, append_images=images[1:], duration=durations_ms, loop=0)
    return len(images)


def animation_kind(out: str | Path) -> str:
    """``.mp4`` or ``.gif`` from the output's name, checked before anything is drawn: another
    suffix, or an MP4 without an ffmpeg binary, is a KinectDataError naming ``out``."""
    out = Path(out)
    kind = out.suffix.lower()
    if kind not in OUTPUT_SUFFIXES:
        raise KinectDataError(f"{out}: unknown animation type {out.suffix!r}; name the output .mp4 or .gif")
    if kind == ".mp4":
        ffmpeg_executable(out)
    return kind


def write_animation(
    kind: str,
    frames: Iterable[np.ndarray],
    out: str | Path,
    fps: float,
    size: tuple[int, int],
    sound: tuple[np.ndarray, int] | None = None,
) -> int:
    """Write the frames as ``kind`` (:func:`animation_kind`): a GIF, or an MP4 with ``sound``
    ((samples, sample rate), or None); the frame count."""
    if kind == ".gif":
        return write_gif(frames, out, fps)
    return write_mp4(frames, out, fps, size, *(sound or (None, None)))


def render_animation(
    inputs: Sequence[RenderInput],
    out: str | Path,
    *,
    start: float = 0.0,
    end: float | None = None,
    fps: float | None = None,
    audio: str | Path | None = None,
    size: tuple[int, int] = DEFAULT_SIZE,
    progress: Callable[[int, int], None] | None = None,
) -> dict[str, Any]:
    """Write the animation of one motion, or several side by side on one time axis, to ``out``.

    Args:
        inputs: the motions (:func:`load_input`), drawn left to right; all 2-D or all 3-D.
        out: ``.mp4`` (needs imageio-ffmpeg) or ``.gif`` (no sound).
        start, end: seconds of the clip (0 at each motion's first frame); ``end`` defaults to, and
            is cut at, the end of the longest motion (:func:`motion_span`).
        fps: output frames per second; default the first motion's rate, at most :data:`MAX_DEFAULT_FPS`.
        audio: MP4 only: an audio file whose sample 0 is at the motions' time 0, cut to the clip;
            default the first input's own audio (an aligned file's).
        size: (width, height) pixels of each panel.
        progress: called with (frames done, frames in all) after each frame.

    Returns:
        ``frames``, ``fps``, ``start`` and ``end`` (s), ``size`` (width, height of the whole
        frame), ``audio`` (the source of the sound, or None) and ``ended`` (sources of the motions
        shown frozen on their last frame before the clip ends).
    """
    out = Path(out)
    kind = animation_kind(out)
    if kind == ".gif" and audio is not None:
        raise KinectDataError(f"{out}: a GIF has no sound; write an .mp4 to hear {audio}")
    width, height = size
    if min(width, height) < 32:
        raise KinectDataError(f"{out}: panels of {width}x{height} pixels are too small to draw in (at least 32x32)")
    _check_motions(inputs)
    spans = [motion_span(i.motion) for i in inputs]
    sources = " and ".join(i.source for i in inputs)
    if end is not None and start >= end:
        raise KinectDataError(f"{sources}: --start {start:g} s is not before --end {end:g} s")
    end = max(spans) if end is None else min(end, max(spans))
    if start >= end:
        raise KinectDataError(f"{sources}: --start {start:g} s is at or after the end of the motion ({end:.3f} s)")
    if fps is None:
        first = inputs[0].motion
        fps = min(first.timing()["fps"], MAX_DEFAULT_FPS) if first.n_frames > 1 else MAX_DEFAULT_FPS
    times = frame_times(start, end, fps)
    sound, sound_source = (None, None) if kind == ".gif" else _sound(inputs, audio, start, len(times) / fps)
    renderer = SkeletonRenderer([i.motion for i in inputs], [i.label for i in inputs], size)

    def frames() -> Iterator[np.ndarray]:
        for k, t in enumerate(times):
            yield renderer.render(t)
            if progress is not None:
                progress(k + 1, len(times))

    count = write_animation(kind, frames(), out, fps, renderer.size, sound)
    return {
        "frames": count,
        "fps": float(fps),
        "start": float(start),
        "end": float(start + count / fps),
        "size": renderer.size,
        "audio": sound_source,
        "ended": [i.source for i, span in zip(inputs, spans) if span < end],
    }


def _check_motions(inputs: Sequence[RenderInput]) -> None:
    if not inputs:
        raise KinectDataError("no motion to render")
    for i in inputs:
        if i.motion.n_frames == 0 or not i.motion.position_mask.any():
            raise KinectDataError(f"{i.source}: no valid joint position in any frame; nothing to draw")
    first = inputs[0]
    for other in inputs[1:]:
        d, e = first.motion.joint_set.dimensions, other.motion.joint_set.dimensions
        if d != e:
            raise KinectDataError(
                f"{other.source}: a {e}-D motion ({other.motion.joint_set.name}) cannot be drawn beside the "
                f"{d}-D motion of {first.source}: compare 2-D with 2-D, 3-D with 3-D"
            )


def _sound(
    inputs: Sequence[RenderInput], audio: str | Path | None, start: float, duration: float
) -> tuple[tuple[np.ndarray, int] | None, str | None]:
    """((samples [S] float32, sample rate Hz) of the clip from ``start`` lasting ``duration`` s, or
    None, and the source of the sound): the ``audio`` file, else the first input with audio."""
    from kinectdata.align.audio import AudioReader, load_audio

    if audio is not None:
        rate = AudioReader(audio).source_rate
        samples, source = load_audio(audio, rate).samples, str(audio)
    else:
        with_audio = [i for i in inputs if i.audio is not None and i.audio.size]
        if not with_audio:
            return None, None
        samples, rate, source = with_audio[0].audio, int(with_audio[0].sample_rate), with_audio[0].source
    first = int(round(start * rate))
    clip = samples[first : first + int(round(duration * rate))]
    if clip.size == 0:
        raise KinectDataError(f"{source}: the audio ends at {samples.size / rate:.3f} s, before --start {start:g} s")
    return (clip, rate), source
