"""Applications over the library: :mod:`.quickstart` runs the whole data path on synthetic and
bundled sessions, for each pipeline; :mod:`.real_dance` the same on a real corpus;
:mod:`.split_generation` generates a dance for every recording of a dataset split."""
