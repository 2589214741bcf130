"""What a model learns to output per frame, and how it is scaled.

- :mod:`.specs`: target specs (shipped ``schemas/targets`` files): which joints, which values
  (positions, quaternions, 2-D poses, limb lengths), extraction from an aligned recording;
- :mod:`.normalization`: per-dataset normalisation into +-0.9 (``maxabs``) or none, and its
  inverse;
- :mod:`.skeleton`: the rest skeleton (bone offsets) that rebuilds whole poses from targets;
- :mod:`.hemispheres`: one quaternion hemisphere per joint across a dataset.
"""
