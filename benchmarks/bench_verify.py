"""What verified reads cost: checking a dataset folder before training or scoring it.

A 10-minute session is synthesised and built; then ``verify_dataset`` runs with and without the
shards' SHA-256 (the check ``train-baseline``, ``evaluate`` and ``sweep`` make before they start;
``--no-checksums`` skips the hashing), against the floor of reading the shards' bytes once, and
one shard checked in a child process started for it alone (what every shard cost before one child
served them all). Each is timed warm (files in the page cache, the checking child running), best
of 3.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from .summary import record


def _best(fn, repeats: int = 3) -> float:
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def _read_all(paths: list[Path]) -> None:
    for path in paths:
        with open(path, "rb") as f:
            while f.read(1 << 20):
                pass


def main() -> None:
    from kinectdata.core.hashing import file_sha256
    from kinectdata.dataset.build import build_dataset
    from kinectdata.dataset.isolation import check_once
    from kinectdata.dataset.prepare import BuildConfig
    from kinectdata.dataset.verify import verify_dataset
    from kinectdata.features.stft import PRESETS
    from kinectdata.targets.specs import load_target_spec

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        subprocess.run(
            [sys.executable, "-m", "kinectdata", "synth", str(tmp), "--seed", "5", "--duration", "600", "--name", "v"],
            check=True,
            stdout=subprocess.DEVNULL,
        )
        config = BuildConfig(
            PRESETS["yalta2016"].to_dict(), load_target_spec("yalta65").to_dict(), split_ratios=(1, 0, 0)
        )
        out = tmp / "dataset"
        build = _best(lambda: build_dataset(tmp, out, config) and None, repeats=1)
        shards = [out / s["file"] for s in json.loads((out / "manifest.json").read_text())["shards"]]
        megabytes = sum(p.stat().st_size for p in shards) / 1e6
        read = _best(lambda: _read_all(shards))
        full = _best(lambda: verify_dataset(out))
        quick = _best(lambda: verify_dataset(out, checksums=False))
        hashing = _best(lambda: [file_sha256(p) for p in shards])
        own_child = _best(lambda: check_once(shards[0], 120.0))  # the cost per shard before the shared child
    print(f"  a 10 min session's dataset: {megabytes:.0f} MB in {len(shards)} shard(s), built in {build:.1f} s")
    print(f"  {'check':<34} {'s':>7} {'x reading the bytes':>20} {'x the build':>12}")
    for label, seconds in (("read the shards' bytes (floor)", read), ("verify with checksums", full),
                           ("verify --no-checksums", quick)):  # fmt: skip
        print(f"  {label:<34} {seconds:7.3f} {seconds / read:20.2f} {seconds / build:12.3f}")
    print(f"  {'SHA-256 of the shards alone':<34} {hashing:7.3f} {hashing / read:20.2f} {hashing / build:12.3f}")
    print(
        f"  the checksums cost {hashing / megabytes * 1e3:.1f} s per GB; the rest is the layout check, "
        f"{quick / len(shards):.3f} s per shard, read in one child process that checks shard after shard (safe "
        f"from libhdf5 crashes); a child started for one shard takes {own_child:.3f} s "
        f"({own_child / (quick / len(shards)):.0f}x), paid once per process"
    )
    record("verify", "check before training: checksums", f"{hashing / megabytes * 1e3:.1f} s per GB")
    record("verify", "check before training: layout, per shard", f"{quick / len(shards):.3f} s")
    record("verify", "whole check of a 10 min session's dataset", f"{full / build:.1%} of its build")


if __name__ == "__main__":
    main()
