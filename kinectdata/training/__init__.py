"""Training and evaluating the reference models on kinectdata datasets (needs torch).

Modules: :mod:`.metrics` (SMAPE, masked MSE), :mod:`.run` (configuration, run folders,
checkpoints), :mod:`.train` (the training loop), :mod:`.evaluate` (the paper's metrics and
figures), :mod:`.generate` (audio -> motion, streaming), :mod:`.sweep` (the paper's tables).
"""
