"""Datasets for training: recordings in, HDF5 shards and a manifest out (see :mod:`.build`).

Modules, in the order the data flows: :mod:`.layout` (the names in a dataset folder),
:mod:`.collection` (session folders), :mod:`.pipelines` (the named presets), :mod:`.inputs` (what to build from, splits),
:mod:`.prepare` (one recording: alignment, targets, streamed features), :mod:`.shards` (the
shard layout, writer and validator), :mod:`.build` (the recipe), :mod:`.inspect` (reports) and
:mod:`.windows` (a PyTorch dataset of training windows; needs torch).
"""
