"""Experiments over the simulation: the exposure-bias (EV) sweep, the ISP-stage and exposure
detection experiments, and the reading and charting of their result folders."""
