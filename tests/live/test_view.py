"""The live view (kinectdata.live.view): what it serves, read by a plain HTTP client, and the page
loaded in headless Chromium, where frames must arrive and be drawn."""

from __future__ import annotations

import http.client
import json
import re
import shutil
import subprocess
import threading
import time

import numpy as np
import pytest
from helpers import skip_unless_installed

from kinectdata.core.errors import KinectDataError
from kinectdata.core.jointsets import load_joint_set
from kinectdata.live.sinks import LivePose
from kinectdata.live.view import ViewSink

KINECT = load_joint_set("kinect_v2")


def _pose(k: int, fps: float = 30.0, step: float = 0.01) -> LivePose:
    rng = np.random.default_rng(k)
    p = rng.normal(0, 0.3, (len(KINECT), 3)) + [step * k, 1.0, 2.5]  # travelling along x, ``step`` m a frame
    p[3] = np.nan  # the head not placed
    return LivePose(k, k / fps, p)


def _events(port: int, n: int, got: list) -> None:
    """Reads ``n`` server-sent events from /frames into ``got``."""
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
    conn.request("GET", "/frames")
    response = conn.getresponse()
    got.append(response.getheader("Content-Type"))
    while len(got) < n + 1:
        line = response.readline().decode()
        if line.startswith("data: "):
            got.append(json.loads(line[6:]))


def test_the_view_serves_its_page_skeleton_and_frames():
    sink = ViewSink("127.0.0.1:0", KINECT, 30.0, beats=np.array([0.05, 0.55]))
    try:
        port = int(sink.url.rsplit(":", 1)[1].strip("/"))
        conn = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
        conn.request("GET", "/")
        page = conn.getresponse()
        assert page.status == 200 and b"EventSource" in page.read()
        conn.request("GET", "/skeleton")
        skeleton = json.loads(conn.getresponse().read())
        assert skeleton["names"] == list(KINECT.names) and skeleton["dimensions"] == 3
        assert skeleton["sides"][KINECT.index("HandRight")] == "right" and len(skeleton["bones"]) == 24
        conn.request("GET", "/nowhere")
        assert conn.getresponse().status == 404
        got: list = []
        reader = threading.Thread(target=_events, args=(port, 3, got))
        reader.start()
        while not sink.viewers:  # the viewer is connected before the frames go
            time.sleep(0.01)
        for k in range(3):
            sink.send(_pose(k))
            sink.heard_latency(4.0 + k)
        reader.join(10)
        kind, *frames = got
        assert kind == "text/event-stream"
        assert [f["i"] for f in frames] == [0, 1, 2] and [f["t"] for f in frames] == [0.0, 0.0333, 0.0667]
        assert [f["lat"] for f in frames] == [None, 4.0, 5.0]  # the frame before's
        assert [f["beat"] for f in frames] == [-1, -1, 0]  # the first beat at 0.05 s
        expected = np.round(_pose(2).positions * 1000, 1)
        assert frames[2]["p"][3] is None
        np.testing.assert_allclose(frames[2]["p"][0], expected[0])
        assert sink.summary().endswith(": 3 frames sent, 1 viewer(s) at the end")
    finally:
        sink.close()
    with pytest.raises(KinectDataError, match="give the view's address as PORT or HOST:PORT"):
        ViewSink("127.0.0.1:port", KINECT, 30.0)


def test_the_page_draws_the_frames_in_headless_chromium(tmp_path):
    chromium = shutil.which("chromium")
    skip_unless_installed(None if chromium else "apt-get install chromium", "Debian's chromium")
    sink = ViewSink("127.0.0.1:0", KINECT, 30.0, beats=np.arange(0.0, 20.0, 0.5))
    stop = threading.Event()

    def dance():  # 30 frames a second until the browser is done
        k = 0
        while not stop.is_set():
            sink.send(_pose(k, step=0.05))  # 1.5 m/s across the floor
            sink.heard_latency(3.5)
            k += 1
            time.sleep(1 / 30)

    dancer = threading.Thread(target=dance, daemon=True)
    dancer.start()
    try:
        result = subprocess.run(
            [chromium, "--headless", "--disable-gpu", "--no-sandbox", f"--user-data-dir={tmp_path / 'profile'}",
             "--virtual-time-budget=2000", "--dump-dom", sink.url + "?frames=45"],
            capture_output=True, text=True, timeout=120,
        )  # fmt: skip
    finally:
        stop.set()
        dancer.join(5)
        sink.close()
    found = re.search(
        r'<p id="stats" data-frames="(\d+)" data-drawn="(\d+)" data-bones="(\d+)" data-outside="(\d+)">', result.stdout
    )
    assert found, f"the page did not load: {result.stderr[-2000:]}"
    frames, drawn, bones, outside = (int(v) for v in found.groups())
    assert outside == 0  # the camera keeps a dancer crossing the floor at 1.5 m/s in view
    # the page stops listening after 45 frames (?frames=45), so that the browser finishes loading it
    assert frames == 45, (frames, result.stderr[-1000:])
    assert drawn == frames and bones == 24 - 1  # every frame drawn; the neck-head bone left out


def test_a_recording_plays_at_its_own_pace_and_render_serves_it():
    from click.testing import CliRunner
    from conftest import REPO

    from kinectdata.cli import main
    from kinectdata.core.motion import Motion
    from kinectdata.live.view import play_motion

    class Sink:
        def __init__(self):
            self.sent = []

        def send(self, pose):
            self.sent.append((pose.index, pose.time_s, now[0]))

    now = [100.0]
    sink = Sink()
    times = np.array([0.0, 0.04, 0.08, 0.12, 0.16])  # 25 fps, played from 0.05 s to 0.15 s
    mask = np.ones((5, len(KINECT)), bool)
    mask[2, 0] = False
    motion = Motion(times, np.zeros((5, len(KINECT), 3)), KINECT, position_mask=mask)
    said = play_motion(motion, sink, start=0.05, end=0.15, clock=lambda: now[0],
                       sleep=lambda s: now.__setitem__(0, now[0] + s))  # fmt: skip
    assert said == "played 2 frames (0.05 to 0.12 s)"
    assert [(k, t) for k, t, _ in sink.sent] == [(2, 0.08), (3, 0.12)]
    np.testing.assert_allclose([at - 100.0 for *_, at in sink.sent], [0.03, 0.07])  # each at its time from start
    result = CliRunner().invoke(
        main, ["render", str(REPO / "sample_data" / "synth_001.csv"), "--view", "127.0.0.1:0", "--end", "0.3"]
    )
    assert result.exit_code == 0, result.output
    assert re.search(r"live view: open http://127\.0\.0\.1:\d+/ in a browser; playing synth_001\.csv", result.output)
    assert re.search(r"played (\d+) frames \(0 to 0\.\d+ s\); view .*: \1 frames sent", result.output)
    result = CliRunner().invoke(main, ["render", str(REPO / "sample_data" / "synth_001.csv")])
    assert result.exit_code != 0 and "give -o OUT" in result.output


def test_a_viewer_that_stops_reading_costs_the_dancer_nothing():
    import socket

    sink = ViewSink("127.0.0.1:0", KINECT, 30.0)
    port = int(sink.url.rsplit(":", 1)[1].strip("/"))
    stalled = socket.create_connection(("127.0.0.1", port))
    stalled.sendall(b"GET /frames HTTP/1.1\r\nHost: x\r\n\r\n")  # and never reads
    while not sink.viewers:
        time.sleep(0.01)
    started = time.monotonic()
    for k in range(3000):
        sink.send(_pose(k))
    assert time.monotonic() - started < 5  # sending never waited for the viewer
    assert sink.viewers[0].qsize() <= 60  # at most two seconds of frames wait, the oldest let go
    sink.close()  # a full queue still gets its end
    assert not sink.thread.is_alive()
    stalled.close()
