"""Measurements of a simulated camera, as pure functions over pipeline results: how sharp (e-SFR
system MTF), how noisy (SNR against signal), how accurate in colour (ΔE2000 per Macbeth patch),
and per-frame read-outs (exposure, gain, signal per channel, clipping, SNR at the road users).
Used by `workbench metrics`, `workbench compare`, `workbench study`, the window and the experiments.

    esfr.py     ISO 12233 slanted-edge SFR: MTF curve, MTF50, MTF at Nyquist
    noise.py    SNR and noise against signal on uniform patches, in e⁻ and DN
    colour.py   ΔE2000 of the Macbeth patches after the ISP (colour-science)
    frame.py    a frame's read-outs, and all of them for one pipeline result (camera_metrics)
"""
