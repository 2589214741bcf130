"""A live view in the browser: a local web page that draws each frame of a dance as it is made.

:class:`ViewSink` is a sink like the OSC ones: it serves, on a local address,

- ``/``: the page (``view.html`` beside this module: a canvas, no library, nothing fetched from
  elsewhere), which draws the skeleton with a camera that follows the body, the right side red and
  the left blue, and beside it the frame's time, its latency and the music's beat;
- ``/skeleton``: the joint set as JSON (names, bones, sides, dimensions, frames per second);
- ``/frames``: the frames as server-sent events, one JSON object each: ``i`` (frame number),
  ``t`` (seconds), ``p`` (positions [J][D] in millimetres, or the 2-D target's units times 1000;
  null for a joint not placed), ``lat`` (the latency of the frame before, ms; null when not
  measured), ``beat`` (the number of the music's last beat at ``t``, -1 before the first; null
  when the beats are not known, as for a microphone).

A viewer that falls behind loses frames, never the dancer: each viewer has a queue of two seconds
of frames, and a full queue drops its oldest. The server runs in daemon threads of the process.
"""

from __future__ import annotations

import json
import queue
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import numpy as np

from kinectdata.core.errors import KinectDataError
from kinectdata.core.jointsets import JointSet, joint_side
from kinectdata.live.sinks import LivePose

PAGE = Path(__file__).with_name("view.html")


def parse_view_address(text: str) -> tuple[str, int]:
    """``PORT`` or ``HOST:PORT`` (port 0: any free one) -> (host, port); KinectDataError otherwise."""
    host, _, port = text.rpartition(":")
    host = host or "127.0.0.1"
    if not port.isdigit() or not 0 <= int(port) < 65536:
        raise KinectDataError(f"{text!r}: give the view's address as PORT or HOST:PORT (e.g. 8765)")
    return host, int(port)


class ViewSink:
    """Serves the live view at ``address`` (``HOST:PORT`` or ``PORT``; module docstring) and sends
    each pose to its viewers. ``beats``: the music's beat times in seconds, when known (a file);
    ``up``: the vertical axis of 3-D positions (0, 1, 2: x, y, z; a recording's ``gravity_axis``)."""

    label = "view"
    wants_beats = True  # run_live tracks a file's beats once, for the metre and for this

    def __init__(self, address: str, joint_set: JointSet, fps: float, beats: np.ndarray | None = None, up: int = 1):
        host, port = parse_view_address(address)
        self.joint_set, self.fps = joint_set, float(fps)
        self.beats = None if beats is None else np.asarray(beats, np.float64)
        self.latency_ms: float | None = None
        self.sent = 0
        self.closed = False
        self.viewers: list[queue.Queue] = []
        self.lock = threading.Lock()
        self.skeleton = json.dumps(
            {
                "joint_set": joint_set.name,
                "names": list(joint_set.names),
                "bones": [list(b) for b in joint_set.bones()],
                "sides": [joint_side(n) for n in joint_set.names],
                "dimensions": joint_set.dimensions,
                "up": int(up),
                "fps": self.fps,
            }
        ).encode()
        self.page = PAGE.read_bytes()
        try:
            self.server = ThreadingHTTPServer((host, port), _handler(self))
        except OSError as exc:
            raise KinectDataError(f"{address}: cannot serve the view there ({exc.strerror or exc})") from None
        self.server.daemon_threads = True
        self.thread = threading.Thread(target=self.server.serve_forever, daemon=True)
        self.thread.start()

    @property
    def url(self) -> str:
        host, port = self.server.server_address[:2]
        return f"http://{host}:{port}/"

    def heard_latency(self, ms: float) -> None:
        """The latency of the frame just sent (shown with the next one)."""
        self.latency_ms = float(ms)

    def send(self, pose: LivePose) -> None:
        p = np.round(np.asarray(pose.positions, np.float64) * 1000.0, 1)
        beat = None
        if self.beats is not None:
            beat = int(np.searchsorted(self.beats, pose.time_s, side="right")) - 1
        frame = {
            "i": int(pose.index),
            "t": round(float(pose.time_s), 4),
            "p": [None if not np.isfinite(row).all() else row.tolist() for row in p],
            "lat": None if self.latency_ms is None else round(self.latency_ms, 2),
            "beat": beat,
        }
        message = b"data: " + json.dumps(frame, separators=(",", ":")).encode() + b"\n\n"
        with self.lock:
            viewers = list(self.viewers)
        for viewer in viewers:
            _put_newest(viewer, message)
        self.sent += 1

    def summary(self) -> str:
        return f"view {self.url}: {self.sent} frames sent, {len(self.viewers)} viewer(s) at the end"

    def close(self) -> None:
        """End every viewer's stream and stop serving."""
        try:
            with self.lock:
                self.closed = True
                for viewer in self.viewers:
                    _put_newest(viewer, None)  # ends the stream, even for a viewer that fell behind
        finally:
            self.server.shutdown()
            self.server.server_close()


def _put_newest(viewer: queue.Queue, item) -> None:
    """Put ``item`` in a viewer's queue; a full queue (a viewer that fell behind) loses its oldest."""
    while True:
        try:
            viewer.put_nowait(item)
            return
        except queue.Full:
            try:
                viewer.get_nowait()
            except queue.Empty:
                pass


def _handler(sink: ViewSink):
    class Handler(BaseHTTPRequestHandler):
        timeout = 10  # seconds a write to a viewer that stopped reading may block before it is dropped

        def log_message(self, *args) -> None:  # the session's output stays the session's
            pass

        def _reply(self, body: bytes, kind: str) -> None:
            self.send_response(200)
            self.send_header("Content-Type", kind)
            self.send_header("Content-Length", str(len(body)))
            self.send_header("Cache-Control", "no-store")
            self.end_headers()
            self.wfile.write(body)

        def do_GET(self) -> None:  # noqa: N802 (http.server's name)
            path = self.path.split("?", 1)[0]
            if path in ("/", "/index.html"):
                self._reply(sink.page, "text/html; charset=utf-8")
            elif path == "/skeleton":
                self._reply(sink.skeleton, "application/json")
            elif path == "/frames":
                self._stream()
            else:
                self.send_error(404)

        def _stream(self) -> None:
            viewer: queue.Queue = queue.Queue(maxsize=max(2, int(2 * sink.fps)))
            with sink.lock:
                if sink.closed:  # came after the end: an empty stream
                    _put_newest(viewer, None)
                sink.viewers.append(viewer)
            try:
                self.send_response(200)
                self.send_header("Content-Type", "text/event-stream")
                self.send_header("Cache-Control", "no-store")
                self.end_headers()
                while True:
                    message = viewer.get()
                    if message is None:
                        break
                    self.wfile.write(message)
                    self.wfile.flush()
            except OSError:  # the viewer closed the page, or stopped reading (the timeout)
                pass
            finally:
                with sink.lock:
                    sink.viewers.remove(viewer)

    return Handler


def play_motion(motion, sink: ViewSink, *, start: float = 0.0, end: float | None = None, clock=None, sleep=None) -> str:
    """Send ``motion``'s frames from ``start`` to ``end`` (seconds from its first frame) to ``sink``,
    each at its own time from now (``clock``/``sleep``: :func:`time.monotonic` and :func:`time.sleep`);
    masked joints not placed. Returns what was played, in words."""
    import time as _time

    clock, sleep = clock or _time.monotonic, sleep or _time.sleep
    times = motion.times - motion.times[0]
    chosen = np.flatnonzero((times >= start) & (times < (np.inf if end is None else end)))
    positions = np.where(motion.position_mask[..., None], motion.positions, np.nan)
    began = clock()
    for k in chosen:
        wait = began + (times[k] - start) - clock()
        if wait > 0:
            sleep(wait)
        sink.send(LivePose(int(k), float(times[k]), positions[k]))
    return f"played {chosen.size} frames ({start:g} to {times[chosen[-1]] if chosen.size else start:.2f} s)"
