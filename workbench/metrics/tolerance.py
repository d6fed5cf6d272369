"""When two measurements of camera designs differ: by more than TOLERANCE_SIGMAS standard
deviations of their difference (each design's measured uncertainty), for `compare`'s verdict
and the ε-dominance of a study's Pareto front."""
from __future__ import annotations

import math

TOLERANCE_SIGMAS = 2.0
TOLERANCE_RULE = (f"'better' only where the difference exceeds ±x = {TOLERANCE_SIGMAS:g}·√(σ_A² + σ_B²), σ each "
                  "design's measured uncertainty (the standard deviation over repeated sensor noise draws of its "
                  "charts; for the noise-equivalent exposure and the low-light SNR at least the standard error of "
                  "the sensitivity the exposure series gives; mAP: test-set bootstrap); design parameters (read "
                  "noise, full well, dynamic range) are exact")


def difference_tolerance(sigma_a: float | None, sigma_b: float | None) -> float:
    """±x within which two measurements are the same (TOLERANCE_SIGMAS; an unmeasured σ counts 0)."""
    return TOLERANCE_SIGMAS * math.hypot(sigma_a or 0.0, sigma_b or 0.0)


def epsilon_dominates(q: tuple, p: tuple, higher: tuple[bool, ...]) -> bool:
    """Whether design q ε-dominates p: q is better by more than ε on one metric and worse by no
    more than ε on any; q and p are ((value, σ), …) per metric, ε = difference_tolerance(σ_q, σ_p)."""
    margins = [(1 if up else -1) * (vq - vp) for (vq, _), (vp, _), up in zip(q, p, higher)]
    eps = [difference_tolerance(sq, sp) for (_, sq), (_, sp) in zip(q, p)]
    return all(m >= -e for m, e in zip(margins, eps)) and any(m > e for m, e in zip(margins, eps))
