"""Poses and music on one exact timeline: frame k at k / fps s, audio at 16 kHz mono.

- :mod:`.audio`: reading, mixing to mono and resampling audio (soundfile, soxr), streamed;
- :mod:`.envelopes`: onset and energy envelopes the offset search compares;
- :mod:`.offset`: the audio-to-motion offset from a sync clap or by cross-correlation;
- :mod:`.timeline`: resampling motion onto the frame grid (linear, slerp), gaps;
- :mod:`.recipe`: :func:`~.recipe.align` and :func:`~.recipe.align_files`, the align recipe;
- :mod:`.aligned`: the aligned HDF5 file and :class:`~.aligned.AlignedRecording`;
- :mod:`.take`: aligning a take folder from ``kinectdata capture`` by its clock stamps.
"""
