"""Reference models (need torch: ``pip install kinectdata[train]``).

- :mod:`.kind`: :class:`~.kind.ModelKind`, what a model declares so that training, evaluation,
  generation, export and the sweep stay one loop each;
- :mod:`.registry`: the models by name (``register_model``), and the model of a dataset;
- :mod:`.bundled`: the two bundled models' kinds and settings;
- :mod:`.yalta`: the DCNN + deep LSTM of Yalta et al. (2016), for training and streaming;
- :mod:`.cdhc`: the CDHC encoder-decoder of Lee et al. (2018, "Listen to Dance");
- :mod:`.losses`: training losses;
- :mod:`.run`: run folders (configuration, checkpoints, the trained network).
"""
