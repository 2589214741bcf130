"""Running a trained model (needs torch): music in, motion out.

- :mod:`.engines`: the network behind one stepping interface, in PyTorch or ONNX Runtime;
- :mod:`.generate`: dance from any song, streamed frame by frame, written as CSV or OpenPose JSON;
- :mod:`.export`: a trained run as a self-describing TorchScript or ONNX file for robots.
"""
