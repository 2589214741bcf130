"""kinectdata report: page structure, embedded PNGs, warnings against independent counts, loading
in headless Chromium, bad input."""

from __future__ import annotations

import base64
import html
import io
import json
import re
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import h5py
import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from conftest import REPO
from helpers import skip_unless_installed

from kinectdata.cli import main
from kinectdata.core.errors import KinectDataError
from kinectdata.dataset.build import build_dataset
from kinectdata.dataset.prepare import BuildConfig
from kinectdata.features.stft import PRESETS
from kinectdata.targets.specs import load_target_spec
from kinectdata.viz.plots import block_extremes
from kinectdata.viz.report import masked_spans, write_report

HAND_LEFT, SPINE_BASE = 7, 0  # Kinect v2 JointType indices (the CSV's jointType column)
TRUTH_OFFSET_001 = json.loads((REPO / "sample_data" / "synth_001.truth.json").read_text())["offset_s"]


class _Page(HTMLParser):
    """The parts of a report page the tests look at."""

    def __init__(self) -> None:
        super().__init__()
        self.ids: list[str] = []
        self.recordings: list[str] = []
        self.images: list[dict[str, str]] = []
        self.warnings: list[dict[str, str]] = []
        self.tags: set[str] = set()
        self.split_rows: list[list[str]] = []
        self._warning: dict[str, str] | None = None
        self._in_splits = False
        self._cell: list[str] | None = None
        self._row: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        self.tags.add(tag)
        if "id" in a:
            self.ids.append(a["id"])
        if tag == "section" and a.get("class") == "recording":
            self.recordings.append(a["id"])
        if tag == "img":
            self.images.append(a)
        if tag == "li" and "data-kind" in a:
            self._warning = a | {"text": ""}
        if tag == "table" and a.get("id") == "splits":
            self._in_splits = True
        if self._in_splits and tag == "tr":
            self._row = []
        if self._in_splits and tag == "td":
            self._cell = []

    def handle_endtag(self, tag):
        if tag == "li" and self._warning is not None:
            self.warnings.append(self._warning)
            self._warning = None
        if tag == "td" and self._cell is not None:
            self._row.append("".join(self._cell))
            self._cell = None
        if tag == "tr" and self._row:
            self.split_rows.append(self._row)
            self._row = None
        if tag == "table":
            self._in_splits = False

    def handle_data(self, data):
        if self._warning is not None:
            self._warning["text"] += data
        if self._cell is not None:
            self._cell.append(data)


def _parse(path: Path) -> _Page:
    page = _Page()
    page.feed(path.read_text(encoding="utf-8"))
    return page


def _config() -> BuildConfig:
    return BuildConfig(features=PRESETS["yalta2016"].to_dict(), target=load_target_spec("yalta65").to_dict())


@pytest.fixture(scope="module")
def report(sample_dataset, tmp_path_factory) -> Path:
    return write_report(sample_dataset, tmp_path_factory.mktemp("report") / "report.html")


def _untrack(csv_in: Path, csv_out: Path, joint: int, start_ms: float, end_ms: float) -> None:
    """Copy a DumpKinectSkeleton CSV with ``joint`` not tracked (state 0) from start_ms to end_ms."""
    lines = csv_in.read_text().splitlines()
    out = lines[:1]
    for line in lines[1:]:
        fields = line.split(",")
        if int(fields[1]) == joint and start_ms <= float(fields[0]) < end_ms:
            fields[-1] = "0"
        out.append(",".join(fields))
    csv_out.write_text("\n".join(out) + "\n")


@pytest.fixture(scope="module")
def gap_dataset(tmp_path_factory) -> tuple[Path, Path]:
    """(dataset, its sources folder): synth_003 train; synth_001 val with HandLeft lost from 10 to 11 s
    (motion clock) and its true offset given; synth_002 test with SpineBase lost from 4 to 16 s."""
    src = tmp_path_factory.mktemp("gap_sources") / "src"
    src.mkdir()
    samples = REPO / "sample_data"
    for name in ("synth_001", "synth_002", "synth_003"):
        shutil.copy(samples / f"{name}.flac", src)
    shutil.copy(samples / "synth_003.csv", src)
    _untrack(samples / "synth_001.csv", src / "synth_001.csv", HAND_LEFT, 10_000, 11_000)
    _untrack(samples / "synth_002.csv", src / "synth_002.csv", SPINE_BASE, 4_000, 16_000)
    listing = {
        "recordings": [
            {"recording": "synth_003.csv", "audio": "synth_003.flac", "split": "train"},
            {"recording": "synth_001.csv", "audio": "synth_001.flac", "split": "val", "offset": TRUTH_OFFSET_001},
            {"recording": "synth_002.csv", "audio": "synth_002.flac", "split": "test"},
        ]
    }
    (src / "recordings.yaml").write_text(yaml.safe_dump(listing))
    out = tmp_path_factory.mktemp("gap_dataset") / "dataset"
    build_dataset(src / "recordings.yaml", out, _config())
    return out, src


def test_page_has_summary_warnings_splits_and_a_section_per_recording(report, sample_dataset):
    page = _parse(report)
    assert {"summary", "warnings", "splits", "contents"} <= set(page.ids)
    manifest = json.loads((sample_dataset / "manifest.json").read_text())
    assert page.recordings == [f"rec-{r['recording']}" for r in manifest["recordings"]]  # in shard order
    assert sorted(page.recordings) == ["rec-synth_001", "rec-synth_002", "rec-synth_003"]
    assert not page.tags & {"script", "link", "iframe", "object"}  # self-contained: nothing to fetch or run
    rows = {}
    for shard in sorted(sample_dataset.glob("*.h5")):
        with h5py.File(shard, "r") as f:
            split = f.attrs["split"]
            rows[split] = rows.get(split, 0) + f["current"].shape[0]
    table = {r[0]: r for r in page.split_rows}
    assert {s: (int(table[s][1]), int(table[s][2])) for s in table} == {s: (1, n) for s, n in rows.items()}


def test_every_image_is_an_embedded_png_that_decodes(report):
    from PIL import Image

    page = _parse(report)
    assert len(page.images) == 4 * 3  # tracking, offset curve, features, targets per recording (sources present)
    for img in page.images:
        prefix = "data:image/png;base64,"
        assert img["src"].startswith(prefix) and img.get("alt")
        with Image.open(io.BytesIO(base64.b64decode(img["src"][len(prefix) :], validate=True))) as im:
            im.load()
            assert im.format == "PNG" and im.width > 100 and im.height > 100


def test_clipping_warnings_match_an_independent_count(report, sample_dataset):
    expected, per_split = {}, {}
    for shard in sorted(sample_dataset.glob("*.h5")):
        with h5py.File(shard, "r") as f:
            current, mask = f["current"][()], f["mask"][()]
            names = [n.decode() if isinstance(n, bytes) else n for n in f["recordings/name"][()]]
            for name, start, length in zip(names, f["recordings/start"][()], f["recordings/length"][()]):
                rows = slice(start, start + length)
                expected[name] = int(((np.abs(current[rows]) > 0.9) & mask[rows]).sum())
            per_split[f.attrs["split"]] = int(((np.abs(current) > 0.9) & mask).sum())
    assert expected["synth_003"] == 0 and expected["synth_001"] > 0 and expected["synth_002"] > 0
    page = _parse(report)
    clipping = {w["data-recording"]: int(w["data-count"]) for w in page.warnings if w["data-kind"] == "clipping"}
    assert clipping == {name: n for name, n in expected.items() if n}
    assert {r[0]: int(r[-1]) for r in page.split_rows} == per_split


def test_sources_give_interpolation_and_the_offset_re_estimated(report, sample_dataset):
    text = html.unescape(report.read_text(encoding="utf-8"))
    assert text.count("Interpolated values: from the sources") == 3
    manifest = json.loads((sample_dataset / "manifest.json").read_text())
    for record in manifest["recordings"]:
        offset = record["offset"]
        assert f"Re-estimated on the source recording's and audio's clocks: {offset['seconds']:+.4f} s" in text


def test_long_gaps_given_offsets_masked_data_and_moved_sources(gap_dataset, tmp_path):
    dataset, src = gap_dataset
    moved = src.with_name("src_moved")
    src.rename(moved)  # the sources are gone: the page must say so and still hold everything else
    try:
        out = tmp_path / "gaps.html"
        result = CliRunner().invoke(main, ["report", str(dataset), "-o", str(out)])
    finally:
        moved.rename(src)
    assert result.exit_code == 0, result.output
    page = _parse(out)
    kinds = {(w["data-kind"], w["data-recording"]) for w in page.warnings}
    assert ("long-gap", "synth_001") in kinds and ("offset", "synth_001") in kinds
    assert ("long-gap", "synth_002") in kinds and ("masked", "synth_002") in kinds
    assert not {k for k in kinds if k[1] == "synth_003"}
    assert ("masked", "synth_001") not in kinds and ("offset", "synth_002") not in kinds
    gap = next(w["text"] for w in page.warnings if w["data-kind"] == "long-gap" and w["data-recording"] == "synth_001")
    start, end = map(float, re.search(r"(\d+\.\d+)-(\d+\.\d+) s \(HandLeft\)", gap).groups())
    # dataset clock = motion clock + offset (the audio starts after the motion: output time 0 is audio time 0)
    assert start == pytest.approx(10.0 + TRUTH_OFFSET_001, abs=0.07)
    assert end == pytest.approx(11.0 + TRUTH_OFFSET_001, abs=0.07)
    masked = next(w["text"] for w in page.warnings if w["data-kind"] == "masked")
    share = float(re.search(r"(\d+\.\d)% of its target values", masked).group(1))
    assert share == pytest.approx(100 * 7 / 65 * 12.0 / 21.3, abs=0.6)  # 7 SpineBase components for 12 s of ~21.3 s
    assert "given, not estimated" in next(w["text"] for w in page.warnings if w["data-kind"] == "offset")
    assert (
        out.read_text(encoding="utf-8").count("is not there any more (moved or deleted)") == 2 * 3
    )  # tracking, offset
    assert len(page.images) == 3 * 3  # no offset curves without the sources


def test_report_loads_in_headless_chromium_with_every_image(report, tmp_path):
    chromium = shutil.which("chromium")
    skip_unless_installed(None if chromium else "apt-get install chromium", "Debian's chromium")
    probe = (
        "<script>window.addEventListener('load', () => { const p = document.createElement('pre'); p.id = 'probe';"
        " p.textContent = JSON.stringify({images: [...document.images].map(i => i.complete && i.naturalWidth > 0),"
        " fetched: performance.getEntriesByType('resource').length,"
        " sections: document.querySelectorAll('section.recording').length,"
        " warnings: document.querySelectorAll('#warnings li').length}); document.body.appendChild(p); });</script>"
    )
    page = tmp_path / "probed.html"
    page.write_text(report.read_text(encoding="utf-8").replace("</body>", probe + "</body>"), encoding="utf-8")
    result = subprocess.run(
        [
            chromium,
            "--headless",
            "--disable-gpu",
            "--no-sandbox",
            f"--user-data-dir={tmp_path / 'profile'}",
            "--virtual-time-budget=10000",
            "--dump-dom",
            page.as_uri(),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    found = re.search(r'<pre id="probe">(.*?)</pre>', result.stdout, re.S)
    assert found, f"the page did not load: {result.stderr[-2000:]}"
    seen = json.loads(found.group(1).replace("&quot;", '"'))
    expected = _parse(report)
    assert seen["images"] == [True] * len(expected.images)
    assert seen["fetched"] == 0
    assert seen["sections"] == 3 and seen["warnings"] == len(expected.warnings)


def test_masked_spans_of_a_hand_made_mask():
    mask = np.ones((20, 3), bool)
    mask[2:5, 0] = False  # 3 frames: 0.1 s at 30 fps
    mask[10:20, 0] = False  # 10 frames to the end
    mask[0:7, 2] = False  # from the start
    fps = 30.0
    assert masked_spans(mask, fps) == [(0.0, 7 / fps, 2), (2 / fps, 5 / fps, 0), (10 / fps, 20 / fps, 0)]
    assert masked_spans(mask, fps, longer_than=0.2) == [(0.0, 7 / fps, 2), (10 / fps, 20 / fps, 0)]
    assert masked_spans(np.ones((5, 2), bool), fps) == []


def test_block_extremes_keep_a_single_sample_dip():
    values = np.ones(10_001)
    values[4_321] = 0.25
    index, kept = block_extremes(values, 100, "min")
    assert len(index) <= 100 and 4_321 in index and kept.min() == 0.25
    size = -(-values.size // 100)
    assert [values[i : i + size].min() for i in range(0, values.size, size)] == list(kept)
    index, kept = block_extremes(values, 20_000)
    assert np.array_equal(index, np.arange(values.size)) and np.array_equal(kept, values)


def test_bad_input_names_the_path_and_writes_nothing(sample_dataset, tmp_path):
    out = tmp_path / "out" / "report.html"
    empty = tmp_path / "empty"
    empty.mkdir()
    damaged = tmp_path / "damaged"
    damaged.mkdir()
    (damaged / "manifest.json").write_text('{"format": "kinectdata.dataset", "shards": [')
    invalid = tmp_path / "invalid"
    invalid.mkdir()
    (invalid / "manifest.json").write_text('{"format": "kinectdata.dataset"}')
    no_shards = tmp_path / "no_shards"
    no_shards.mkdir()
    shutil.copy(sample_dataset / "manifest.json", no_shards)
    cases = [
        (tmp_path / "missing", "missing"),
        (empty, "no manifest.json"),
        (damaged, str(damaged / "manifest.json")),
        (invalid, str(invalid / "manifest.json")),
        (no_shards, str(no_shards / "train-00000.h5")),
    ]
    for dataset, named in cases:
        with pytest.raises(KinectDataError, match=re.escape(named)) as caught:
            write_report(dataset, out)
        assert str(dataset) in str(caught.value)
        assert not out.parent.exists() or not list(out.parent.iterdir())
    kept = tmp_path / "kept.html"
    kept.write_text("an earlier report")
    with pytest.raises(KinectDataError, match=re.escape(str(no_shards))):
        write_report(no_shards, kept)
    assert kept.read_text() == "an earlier report" and not list(tmp_path.glob(".*.partial"))
    with pytest.raises(KinectDataError, match="HTML"):
        write_report(sample_dataset, tmp_path / "report.png")
    result = CliRunner().invoke(main, ["report", str(empty), "-o", str(out)])
    assert result.exit_code == 1 and "no manifest.json" in result.output and not out.exists()


def test_an_aligned_input_gives_its_own_interpolation_flags_and_a_residual_offset_near_zero(tmp_path):
    from kinectdata.align.recipe import align_files

    folder = tmp_path / "aligned"
    samples = REPO / "sample_data"
    align_files(samples / "synth_003.csv", samples / "synth_003.flac", folder / "synth_003.h5")
    dataset = tmp_path / "dataset"
    build_dataset(folder, dataset, _config())
    text = html.unescape(write_report(dataset, tmp_path / "aligned.html").read_text(encoding="utf-8"))
    assert "Interpolated values: from the sources" in text
    residual = re.search(r"Re-estimated on the aligned file's own clocks \(0 s once aligned\): ([-+]\d+\.\d+) s", text)
    assert abs(float(residual.group(1))) < 0.05  # the file is aligned: its audio and motion agree at 0 s
