"""Scoring generated motion against the real dance and the music.

- :mod:`.metrics`: plain numpy metrics (SMAPE, motion energy);
- :mod:`.rhythm`: the rhythm analysis (autocorrelation against the beat period, Beat Align
  Score, beat F-measure) on arrays;
- :mod:`.rhythm_eval`: that analysis per recording of a dataset, with its beats;
- :mod:`.evaluate`: a trained run on a dataset's test split (SMAPE with and without reset, the
  silence test, forward times, rhythm) and :mod:`.figures`, its figures.
"""
