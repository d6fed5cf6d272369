"""The render-noise figures against closed forms: Gaussian render errors of a known size relative
to the shot noise read back as that ratio at the median, the 90th percentile and on edges; the
dim pixels' power ratio and the firefly count read fireflies on dark surfaces beside a bright
region whose large errors dominate the whole frame's power."""
import numpy as np
import pytest

from workbench.experiments.render_noise import edge_pixels, noise_ratios


def test_edge_pixels_of_a_square_are_its_border_and_the_ring_around_it():
    ids = np.zeros((8, 8), np.int32)
    ids[2:6, 2:6] = 7
    edge = edge_pixels(ids)
    inside = np.zeros((8, 8), bool)
    inside[2:6, 2:6] = True
    ring = np.zeros((8, 8), bool)
    ring[1:7, 2:6] = ring[2:6, 1:7] = True
    assert np.array_equal(edge, ring & ~(np.pad(np.ones((2, 2), bool), 3)))   # the square's centre 2×2 is not
    assert edge[inside].sum() == 12 and edge[~inside].sum() == 16 and not edge[0].any()


@pytest.mark.parametrize("ratio", [0.2, 0.5])
def test_gaussian_render_errors_read_back_as_their_ratio_to_the_shot_noise(ratio):
    rng = np.random.default_rng(3)
    h, w, t = 400, 500, 2e-3
    reference = rng.uniform(5e4, 5e5, size=(h, w))                 # e⁻/s: 100–1000 e⁻ at t
    n = reference * t
    edges = np.zeros((h, w), bool)
    edges[:, ::10] = True
    sigma = ratio * np.sqrt(n) * np.where(edges, 2.0, 1.0)           # edges twice as noisy
    rate = (n + sigma * rng.standard_normal((h, w))) / t
    out = noise_ratios(rate, reference, t, edges)
    assert out["median_ratio"] == pytest.approx(ratio * 1.1, rel=0.05)          # 90 % at 1×, 10 % at 2×
    assert out["edge_ratio"] == pytest.approx(2 * ratio, rel=0.04)
    assert abs(out["edge_bias"]) < 4 * 2 * ratio / np.sqrt(n[edges].sum())     # 4 σ of the mean error
    biased = noise_ratios(reference * np.where(edges, 1.01, 1.0), reference, t, edges)
    assert biased["edge_bias"] == pytest.approx(0.01) and biased["median_ratio"] == 0.0
    assert out["power_ratio"] == pytest.approx(ratio * np.sqrt(0.9 + 0.1 * 4), rel=0.03)
    assert out["p90_ratio"] > out["median_ratio"] and out["edge_pixels"] == edges.sum()


def test_the_clipped_power_ratio_reads_the_images_as_the_sensor_records_them():
    """A pixel saturated in both images (a lamp face) carries no render noise into the data however
    large its error before clipping; below the full well the clipped ratio is the power ratio."""
    rng = np.random.default_rng(5)
    t, full_well = 1e-3, 20000.0
    reference = rng.uniform(1e5, 1e7, size=(200, 300))                  # 100–10,000 e⁻ at t
    rate = reference + 0.4 * np.sqrt(reference / t) * rng.standard_normal(reference.shape)
    plain = noise_ratios(rate, reference, t, full_well_e=full_well)
    assert plain["power_ratio_clipped"] == pytest.approx(plain["power_ratio"], rel=1e-9)
    assert plain["power_ratio"] == pytest.approx(0.4, rel=0.03)
    lamp = reference.copy(), rate.copy()
    lamp[0][:2, :2], lamp[1][:2, :2] = 5e8, 5e9                           # 0.5 and 5 million e⁻: both clip
    lamp[0][5, 5], lamp[1][5, 5] = 5e5, 5e9                               # 500 e⁻ against a clipped firefly
    out = noise_ratios(lamp[1], lamp[0], t, full_well_e=full_well)
    assert out["power_ratio"] > 100 * plain["power_ratio"]
    n = lamp[0] * t
    firefly = (full_well - 500.0) ** 2
    want = np.sqrt((plain["power_ratio"] ** 2 * np.sum(reference * t) - np.sum(((rate - reference) * t)[:2, :2] ** 2)
                    - ((rate - reference) * t)[5, 5] ** 2 + firefly) / n.sum())
    assert out["power_ratio_clipped"] == pytest.approx(want, rel=1e-6)
    with pytest.raises(Exception, match="full_well_e"):
        noise_ratios(rate, reference, t, full_well_e=0.0)


def test_dim_power_and_fireflies_read_the_dark_surfaces_beside_a_bright_exit():
    """A bright tenth of the frame (an exit, 100× the signal) with render errors at 3× its shot
    noise, the rest at ⅓ with 5 fireflies of 40× the shot noise: the whole frame's power ratio is
    the exit's; the dim one is √((⅓)² + 5·40²/M) over the M dim pixels, and the count is 5 (the
    exit's errors beyond 5× its shot noise, a pixel-area sampling error at a bright edge, are not)."""
    rng = np.random.default_rng(7)
    h, w, t = 200, 300, 1e-3
    reference = np.full((h, w), 4e5)                                  # 400 e⁻ at t
    reference[:20] = 4e7                                              # the exit: 40,000 e⁻
    reference *= rng.uniform(0.999, 1.001, size=(h, w))               # distinct values for the percentile
    n = reference * t
    ratio = np.where(reference > 1e7, 3.0, 1 / 3)
    e = ratio * np.sqrt(n) * rng.standard_normal((h, w))
    e = np.where(ratio < 1, np.clip(e, -4.5 * np.sqrt(n), 4.5 * np.sqrt(n)), e)   # no chance fireflies in the dim part
    fireflies = [(50, 10), (80, 200), (120, 33), (150, 299), (199, 0)]
    for y, x in fireflies:
        e[y, x] = 40 * np.sqrt(n[y, x])
    out = noise_ratios((n + e) / t, reference, t)
    dim = np.ones((h, w), bool)
    dim[:20] = False
    want = np.sqrt(np.sum(e[dim] ** 2) / np.sum(n[dim]))
    assert out["power_ratio_dim"] == pytest.approx(want, rel=1e-9)
    assert out["power_ratio_dim"] == pytest.approx(np.sqrt((1 / 3) ** 2 + 5 * 40 ** 2 / dim.sum()), rel=0.05)
    assert out["power_ratio"] > 2.5 * out["power_ratio_dim"]          # the exit's errors carry the whole frame
    assert out["firefly_pixels"] == 5                                   # the exit's large errors are not counted
    assert np.sum(np.abs(e[:20]) > 5 * np.sqrt(n[:20])) > 100
    flat = noise_ratios(np.full((4, 4), 2e5), np.full((4, 4), 1e5), 1e-2)   # a flat frame is all dim
    assert flat["power_ratio_dim"] == pytest.approx(flat["power_ratio"]) and flat["firefly_pixels"] == 16
