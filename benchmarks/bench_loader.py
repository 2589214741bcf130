"""Training data loading: :class:`~kinectdata.dataset.windows.WindowDataset` through a PyTorch
DataLoader, on a dataset built from the three sample sessions (yalta2016: [150, 1, 129, 5] audio
windows, 65-value poses), batches of 50 windows of 150 frames with stride 10, shuffled; frames per
second delivered with 0 and 2 worker processes (the training loop's own work excluded).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from torch.utils.data import DataLoader

from kinectdata.dataset.build import build_dataset
from kinectdata.dataset.prepare import BuildConfig
from kinectdata.dataset.windows import WindowDataset
from kinectdata.features import PRESETS
from kinectdata.targets.specs import load_target_spec

from .summary import record

SAMPLES = Path(__file__).parent.parent / "sample_data"


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        features, target = PRESETS["yalta2016"].to_dict(), load_target_spec("yalta65").to_dict()
        config = BuildConfig(features=features, target=target, split_ratios=(1, 0, 0))
        build_dataset(SAMPLES, Path(tmp) / "ds", config)
        windows = WindowDataset(Path(tmp) / "ds", "train", 150, 10)
        for workers in (0, 2):
            loader = DataLoader(windows, batch_size=50, shuffle=True, num_workers=workers)
            for _ in loader:  # warm-up: open files, start workers
                break
            start = time.perf_counter()
            frames = sum(batch["pose"].shape[0] * batch["pose"].shape[1] for batch in loader)
            rate = frames / (time.perf_counter() - start)
            print(f"  {len(windows)} windows of 150 frames, batches of 50, {workers} workers: {rate:,.0f} frames/s")
            record("loading", f"WindowDataset + DataLoader, {workers} workers", f"{rate:,.0f} frames/s")
    windows.close()


if __name__ == "__main__":
    main()
