"""``kinectdata live`` without hardware: a song played at real-time pace on a virtual clock (and a
fake input device), an in-process OSC receiver that parses every message with python-osc, the
recording read back; the poses against ``generate``'s and the latency against its definition."""

from __future__ import annotations

import json
import re
import socket
import threading

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import REPO

pytest.importorskip("torch")
pytest.importorskip("pythonosc")

from pythonosc.osc_bundle import OscBundle  # noqa: E402

from kinectdata.align.aligned import AlignedRecording  # noqa: E402
from kinectdata.cli import main  # noqa: E402
from kinectdata.core.errors import KinectDataError, SchemaError  # noqa: E402
from kinectdata.formats import read_motion  # noqa: E402
from kinectdata.inference.generate import generate  # noqa: E402
from kinectdata.live import sources  # noqa: E402
from kinectdata.live.clock import VirtualClock  # noqa: E402
from kinectdata.live.session import LiveDancer, run_live  # noqa: E402
from kinectdata.live.sinks import OscSink, RecordSink  # noqa: E402

SONG = REPO / "sample_data" / "synth_001.flac"


class Receiver:
    """A UDP port on localhost keeping every datagram, as an OSC receiver would get them."""

    def __init__(self):
        self.socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.socket.bind(("127.0.0.1", 0))
        self.port = self.socket.getsockname()[1]
        self.datagrams: list[bytes] = []
        self.thread = threading.Thread(target=self._listen)
        self.thread.start()

    def _listen(self) -> None:
        self.socket.settimeout(30.0)  # the sender may take its time to start; then a pause ends the stream
        while True:
            try:
                self.datagrams.append(self.socket.recv(65536))
            except TimeoutError:
                return
            self.socket.settimeout(0.5)

    def frames(self) -> list[OscBundle]:
        self.thread.join()
        self.socket.close()
        return [OscBundle(d) for d in self.datagrams]


def test_a_song_played_live_is_danced_as_generate_dances_it_and_every_frame_arrives(trained_run, tmp_path):
    run, _ = trained_run
    clock = VirtualClock(100.0)
    dancer = LiveDancer(run, "torch")
    source = sources.FileSource(SONG, dancer.sample_rate, 80, clock)
    receiver = Receiver()
    record = RecordSink(tmp_path / "live.h5", dancer.joint_set, dancer.fps, dancer.sample_rate, source.name)
    osc = OscSink(f"127.0.0.1:{receiver.port}", dancer.joint_set)
    stats = run_live(dancer, source, [osc, record], clock, record=record)
    osc.close()
    record.write(str(run))
    expected, _ = generate(run, SONG)

    # every frame arrived, in order, each message where the address space says, values as generate's
    bundles = receiver.frames()
    assert len(bundles) == expected.n_frames == stats.frames
    names = expected.joint_set.names
    for k, bundle in enumerate(bundles):
        messages = list(bundle)
        assert messages[0].address == "/kinectdata/frame"
        assert messages[0].params[0] == k and messages[0].params[1] == pytest.approx(k / 30, abs=1e-6)
        got = {m.address: m.params for m in messages[1:]}
        for j, name in enumerate(names):
            position = got.get(f"/kinectdata/joint/{name}/position")
            assert (position is None) == (not expected.position_mask[k, j]), (k, name)
            if position is not None:
                np.testing.assert_allclose(position, expected.positions[k, j], atol=1e-6)
            rotation = got.get(f"/kinectdata/joint/{name}/rotation")
            if rotation is not None:
                assert np.linalg.norm(rotation) == pytest.approx(1.0, abs=1e-5)
                q = expected.orientations[k, j]
                assert min(np.abs(np.subtract(rotation, q)).max(), np.abs(np.add(rotation, q)).max()) < 1e-6
        assert any("rotation" in a for a in got)

    # the recording: what was heard (the song) and danced (generate's poses), read back as any aligned file
    back = AlignedRecording.load(tmp_path / "live.h5")
    np.testing.assert_allclose(back.motion.positions, expected.positions, atol=1e-6, equal_nan=True)
    assert back.audio.size == sources.AudioReader(SONG, 16000).n_samples and back.sample_rate == 16000

    # latency on a virtual clock is the wait for the block holding the frame's last sample, exactly
    ends = np.minimum(np.round(np.arange(stats.frames) * 16000 / 30).astype(int) + dancer.features.span[1],
                      back.audio.size)  # fmt: skip
    waited = (np.minimum(np.ceil(ends / 80) * 80, back.audio.size) - ends) / 16000 * 1000
    assert stats.latency_ms[: len(waited) - 5] == pytest.approx(waited[:-5].tolist(), abs=1e-6)
    s = stats.summary()
    assert s["frames_dropped"] == 0 and s["input_overruns"] == 0 and s["frames_late"] == 0
    assert s["latency_p99_ms"] <= 5.0 + 1e-6  # never more than an 80-sample block


def test_duration_a_receiver_that_is_not_there_and_the_command(trained_run, tmp_path):
    """--duration stops early (the frames whose audio was heard, the recording of that much); with
    nobody listening the frames still go out and the session goes on; the command prints its verdicts."""
    run, _ = trained_run
    closed = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    closed.bind(("127.0.0.1", 0))
    port = closed.getsockname()[1]
    closed.close()  # a port nobody listens on
    clock = VirtualClock()
    dancer = LiveDancer(run, "torch")
    osc = OscSink(f"127.0.0.1:{port}", dancer.joint_set)
    stats = run_live(dancer, sources.FileSource(SONG, 16000, 160, clock), [osc], clock, duration=3.0)
    assert stats.ended == "3 s heard" and stats.heard_s == 3.0
    assert stats.frames == stats.expected_frames == int(np.searchsorted(
        np.round(np.arange(90) * 16000 / 30) + dancer.features.span[1], 48000, side="right"))  # fmt: skip
    assert osc.sent == stats.frames and osc.failed == 0  # UDP: sent all the same, nothing waits for a receiver

    receiver = Receiver()
    out = tmp_path / "live.h5"
    result = CliRunner().invoke(
        main, ["live", "--run", str(run), "--input", str(SONG), "--osc", f"127.0.0.1:{receiver.port}",
               "--record", str(out), "--duration", "1", "--stats", str(tmp_path / "s.json")],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "latency, a frame's audio heard -> its pose sent: median" in result.output and "(goal 10: " in result.output
    summary = json.loads((tmp_path / "s.json").read_text())["summary"]
    assert summary["frames_sent"] == len(receiver.frames()) == AlignedRecording.load(out).n_frames
    info = CliRunner().invoke(main, ["info", str(out)])
    assert info.exit_code == 0 and "kinect_v2" in info.output


class FakeInputStream:
    """sounddevice.InputStream's part that live uses: a thread calls back with blocks of a song."""

    song = None
    overflow_at = None

    def __init__(self, device, channels, samplerate, blocksize, dtype, callback):
        self.block, self.callback = blocksize, callback
        self.thread = threading.Thread(target=self._play)

    def start(self):
        self.thread.start()

    def _play(self):
        class Status:
            input_overflow = False

        for i, first in enumerate(range(0, self.song.size - self.block, self.block)):
            status = Status()
            status.input_overflow = i == self.overflow_at
            self.callback(self.song[first : first + self.block, None], self.block, None, status)

    def stop(self):
        self.thread.join()

    def close(self):
        pass


class FakeSounddevice:
    class PortAudioError(Exception):
        pass

    InputStream = FakeInputStream


def test_a_device_that_delivers_then_stops_is_one_line_and_keeps_what_was_danced(trained_run, monkeypatch, tmp_path):
    run, _ = trained_run
    song = sources.AudioReader(SONG, 16000)
    FakeInputStream.song = np.concatenate(list(song.blocks()))[: 16000 * 2]
    FakeInputStream.overflow_at = 7
    monkeypatch.setattr(sources, "_sounddevice", lambda: FakeSounddevice)
    monkeypatch.setattr(sources, "DEVICE_SILENCE_S", 0.3)
    out = tmp_path / "mic.h5"
    result = CliRunner().invoke(main, ["live", "--run", str(run), "--record", str(out), "--engine", "torch"])
    assert result.exit_code == 1, result.output
    assert result.output.strip().splitlines()[-1] == (
        "Error: the default input device delivered no audio for 0.3 s: was it unplugged?"
    )
    assert "input overruns: 1" in result.output
    kept = AlignedRecording.load(out)
    assert 1.9 < kept.audio.size / 16000 <= 2.0 and kept.n_frames > 50

    class Broken(FakeSounddevice):
        class InputStream:
            def __init__(self, **kwargs):
                raise FakeSounddevice.PortAudioError("Error querying device -1")

    monkeypatch.setattr(sources, "_sounddevice", lambda: Broken)
    result = CliRunner().invoke(main, ["live", "--run", str(run), "--input", "7", "--record", str(tmp_path / "x.h5")])
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert "the input device 7 cannot be opened at 16000 Hz (Error querying device -1)" in result.output
    assert not (tmp_path / "x.h5").exists()


def test_what_cannot_dance_live_says_why(tmp_path):
    with pytest.raises(KinectDataError, match="give a receiver as HOST:PORT"):
        from kinectdata.live.sinks import parse_address

        parse_address("localhost")
    result = CliRunner().invoke(main, ["live", "--run", str(tmp_path / "nowhere"), "--input", str(SONG)])
    assert result.exit_code != 0 and "Traceback" not in result.output


def test_vmc_bones_turn_their_rest_directions_onto_the_dancers_bones():
    """An independent check of the solved rotations: the chain of local rotations, composed from the
    root, turns each bone's T-pose direction onto the bone's direction in the frame (Unity's axes:
    x mirrored), for random poses of a Kinect v2 body seen from any side."""
    from scipy.spatial.transform import Rotation

    from kinectdata.core.jointsets import load_joint_set
    from kinectdata.live.vmc import HUMAN_BODY_BONES, TO_UNITY, VmcRig

    kinect = load_joint_set("kinect_v2")
    rig = VmcRig(kinect)
    rng = np.random.default_rng(4)
    take = read_motion(REPO / "sample_data" / "synth_001.csv")
    for k in rng.integers(0, take.n_frames, 6):
        turned = Rotation.from_euler("y", rng.uniform(0, 360), degrees=True).apply(take.positions[k].reshape(-1, 3))
        positions = turned.reshape(len(kinect), 3)
        root, facing, bones = rig.solve(positions)
        p = positions * TO_UNITY
        np.testing.assert_allclose(root, p[kinect.index("SpineBase")])
        globals_ = {}
        for name, offset, q in bones:
            bone = next(b for b in rig.bones if b.name == name)
            assert name in HUMAN_BODY_BONES and np.linalg.norm(q) == pytest.approx(1.0)
            parent = globals_.get(bone.parent, Rotation.from_quat(facing))
            own = parent * Rotation.from_quat(q)
            globals_[name] = own
            d = p[bone.aim] - p[bone.joint]
            np.testing.assert_allclose(own.apply(bone.rest), d / np.linalg.norm(d), atol=1e-6)
            if bone.parent is not None:  # the local position is where the bone starts, in its parent's frame
                start = next(b.joint for b in rig.bones if b.name == bone.parent)
                np.testing.assert_allclose(parent.apply(offset), p[bone.joint] - p[start], atol=1e-9)
        assert len(bones) == len(rig.bones)


def test_vmc_frames_reach_a_receiver_and_a_set_without_a_humanoid_is_one_line(trained_run, tmp_path):
    run, _ = trained_run
    receiver = Receiver()
    result = CliRunner().invoke(
        main, ["live", "--run", str(run), "--input", str(SONG), "--vmc", f"127.0.0.1:{receiver.port}",
               "--duration", "1", "--engine", "torch", "--view", "127.0.0.1:0"],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    assert re.search(r"live view: open http://127\.0\.0\.1:\d+/ in a browser", result.output)
    assert re.search(r"view http://127\.0\.0\.1:\d+/: 29 frames sent", result.output)
    bundles = receiver.frames()
    assert len(bundles) == 29
    messages = list(bundles[3])
    assert [m.address for m in messages[:2]] == ["/VMC/Ext/Root/Pos", "/VMC/Ext/Bone/Pos"]
    assert messages[0].params[0] == "root" and messages[1].params[0] == "Hips"
    assert messages[-2].address == "/VMC/Ext/OK" and messages[-1].address == "/VMC/Ext/T"
    assert messages[-1].params[0] == pytest.approx(3 / 30, abs=1e-6)
    sent = {m.params[0] for m in messages if m.address == "/VMC/Ext/Bone/Pos"}
    assert {"Hips", "Spine", "LeftUpperArm", "RightLowerLeg"} <= sent and "LeftFoot" not in sent  # yalta65: no feet
    for m in messages[:-2]:
        assert np.linalg.norm(m.params[4:8]) == pytest.approx(1.0, abs=1e-5)

    from kinectdata.core.jointsets import load_joint_set
    from kinectdata.live.vmc import VmcSink

    derived = VmcSink("127.0.0.1:39539", load_joint_set("nite"))
    assert derived.rig.bones[0].name == "Hips"  # derived from the set's names
    derived.close()
    with pytest.raises(KinectDataError, match="openpose_mpi is 2-D"):
        VmcSink("127.0.0.1:39539", load_joint_set("openpose_mpi"))
    with pytest.raises(SchemaError, match="nowhere.json: no such VMC mapping file"):
        VmcSink("127.0.0.1:39539", load_joint_set("kinect_v2"), tmp_path / "nowhere.json")
    bad = tmp_path / "map.json"
    bad.write_text(json.dumps({"joint_set": "kinect_v2", "left_hip": "HipLeft", "right_hip": "HipRight",
                               "bones": [{"bone": "Pelvis", "parent": None, "joint": "SpineBase", "aim": "SpineMid",
                                          "rest": [0, 1, 0]}]}))  # fmt: skip
    with pytest.raises(SchemaError, match=r"map.json: bones\[0\]: 'Pelvis' is not a Unity humanoid bone"):
        VmcSink("127.0.0.1:39539", load_joint_set("kinect_v2"), bad)
