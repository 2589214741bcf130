"""Applications over the library: :mod:`.quickstart` runs the whole data path on synthetic and
bundled sessions, for each pipeline."""
