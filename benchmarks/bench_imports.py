"""Import times, each in a fresh interpreter (median of 5): ``import kinectdata`` (the lazy API), the
training windows (``from kinectdata.dataset import WindowDataset``, paid again by every DataLoader
worker) against the floor of importing torch and h5py themselves, and the CLI entry point. The
windows' cost above the floor is what kinectdata adds; the count of kinectdata modules loaded shows
that no reader comes along.
"""

from __future__ import annotations

import json
import statistics
import subprocess
import sys

from .summary import record

CASES = {
    "import kinectdata": "import kinectdata",
    "torch + h5py (the floor of the windows)": "import torch, h5py",
    "from kinectdata.dataset import WindowDataset": "from kinectdata.dataset import WindowDataset",
    "the CLI (kinectdata.cli)": "import kinectdata.cli",
}

PROBE = """
import json, sys, time
t = time.perf_counter()
exec({code!r})
elapsed = time.perf_counter() - t
mods = [m for m in sys.modules if m == "kinectdata" or m.startswith("kinectdata.")]
print(json.dumps({{"s": elapsed, "modules": len(mods), "pandas": "pandas" in sys.modules,
                  "readers": any(m.startswith("kinectdata.formats") for m in mods)}}))
"""


def measure(code: str, repeats: int = 5) -> dict:
    runs = []
    for _ in range(repeats):
        out = subprocess.run(
            [sys.executable, "-c", PROBE.format(code=code)], capture_output=True, text=True, check=True
        )
        runs.append(json.loads(out.stdout))
    return {**runs[-1], "s": statistics.median(r["s"] for r in runs)}


def main() -> None:
    results = {name: measure(code) for name, code in CASES.items()}
    floor = results["torch + h5py (the floor of the windows)"]["s"]
    for name, r in results.items():
        extra = f", {r['modules']} kinectdata modules, pandas {'yes' if r['pandas'] else 'no'}, readers "
        extra += "yes" if r["readers"] else "no"
        print(f"  {name:<48} {r['s'] * 1000:7.0f} ms ({r['s'] / floor:.2f}x torch + h5py){extra}")
    windows = results["from kinectdata.dataset import WindowDataset"]
    record("imports", "import kinectdata", f"{results['import kinectdata']['s'] * 1000:.0f} ms")
    record(
        "imports",
        "WindowDataset (vs torch + h5py alone)",
        f"{windows['s'] * 1000:.0f} ms ({windows['s'] / floor:.2f}x)",
    )
