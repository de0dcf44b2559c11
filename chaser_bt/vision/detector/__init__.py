"""The on-board detector (paper section 3.1): a small YOLO-style torch network (model), its loss,
training (train), evaluation (evaluate), augmentations (augment) and inference (inference.Detector).

Nothing is imported here, so that the light modules (augment, evaluate) load without torch.
"""
