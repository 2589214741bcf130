"""Reference models (need torch: ``pip install kinectdata[train]``).

- :mod:`.yalta`: the DCNN + deep LSTM of Yalta et al. (2016), for training and streaming;
- :mod:`.cdhc`: the CDHC encoder-decoder of Lee et al. (2018, "Listen to Dance");
- :mod:`.registry`: the models by name behind one interface;
- :mod:`.losses`: training losses;
- :mod:`.run`: run folders (configuration, checkpoints, the trained network).
"""
