"""Training the reference models on kinectdata datasets (needs torch).

Modules: :mod:`.config` (settings and each model's defaults), :mod:`.train` (the training loop),
:mod:`.distributed` (several processes under torchrun), :mod:`.figures` (loss curves),
:mod:`.sweep` (the paper's tables).
"""
