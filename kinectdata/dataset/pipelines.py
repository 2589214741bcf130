"""The two published pipelines as named presets of a dataset build.

A pipeline names the feature preset (:data:`kinectdata.features.PRESETS`), the target spec
(``schemas/targets``) and the target normalisation that together make a dataset one of the
bundled models trains on; any of the three can still be overridden:

- ``yalta2016`` (Yalta et al. 2016, the DCNN + deep LSTM): 1x129x5 STFT inputs, the 65-value
  ``yalta65`` target (3-D positions and quaternions of a Kinect v2 skeleton), ``maxabs`` into
  -0.9..0.9;
- ``listen-to-dance`` (Lee et al. 2018, the CDHC encoder-decoder): 80-band log-mel inputs in
  0..1, the 44-value ``listen_to_dance`` target (OpenPose MPI x, y min-max scaled per recording
  into 0..1, plus 14 limb lengths), no further normalisation (the network's sigmoid output
  covers 0..1).
"""

from __future__ import annotations

PIPELINES: dict[str, dict[str, str]] = {
    "yalta2016": {"features": "yalta2016", "target": "yalta65", "normalisation": "maxabs", "model": "yalta"},
    "listen-to-dance": {
        "features": "listen_to_dance",
        "target": "listen_to_dance",
        "normalisation": "none",
        "model": "cdhc",
    },
}
