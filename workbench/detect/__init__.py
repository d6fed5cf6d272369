"""Object detectors on simulated camera images (the reference paper's second half).

    representations.py  raw / linear / sRGB network inputs with fixed scaling, CFA-aware augmentation
    models/             DETECTORS registry: 'mobile', 'resnet18', or a user's own torch.nn.Module
    centernet.py        "objects as points": target encoding, loss and peak decoding (stride 4)
    evaluate.py         VOC all-point AP@0.5 per class and mAP; COCO 101-point cross-check

Torch is imported only by the modules that need it (models, centernet): representations and
evaluate run without it.
"""
