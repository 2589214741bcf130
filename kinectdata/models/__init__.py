"""Reference models (need torch: ``pip install kinectdata[train]``).

- :mod:`.yalta`: the DCNN + deep LSTM of Yalta et al. (2016), for training and streaming;
- :mod:`.export`: its streaming form as a self-describing TorchScript or ONNX file.
"""
