"""The paper's experiments on simulated cameras: ISP stage and exposure bias (detection mAP)."""
