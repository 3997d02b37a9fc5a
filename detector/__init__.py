"""FlexiNet 2D detector (thesis 000): model, anchors, losses, NMS, augmentation (mosaic and the
two Mixup variants of 004), training and inference on any KITTI-format dataset."""

import kitti  # noqa: F401  (first: pins the CPU kernels before numpy or torch loads)
