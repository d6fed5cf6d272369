"""Spectral reflectances of the city's materials, 350–1000 nm, from smooth analytic shapes.

Every curve is a sum of sigmoids (absorption edges) and gaussians (bands) whose positions and
levels follow published facts about the material; none comes from RGB upsampling, because RGB
upsampling invents the near infrared that RCCC / clear sensors without an IR-cut filter see.
Facts used (levels approximate, chosen inside the quoted ranges):

- Asphalt: dark and nearly flat, 0.05 (fresh) to ~0.12 (aged), rising slowly with λ
  (Herold et al. 2004, urban spectral library, Santa Barbara; USGS splib07 'asphalt').
- Concrete: ~0.25 in the blue rising to ~0.35–0.4 in the red, flat ~0.4 in the NIR (Herold 2004).
- Brick: iron-oxide edge near 560–600 nm (blue ~0.08, red ~0.35), ferric band near 870 nm
  (USGS splib07 'red brick'; hematite absorption features).
- Vegetation: chlorophyll a/b absorption in blue and red (~0.04 at 450 and 670 nm), green peak
  ~0.12 at 550 nm, red edge at ~700–720 nm, NIR plateau ~0.45–0.55 from leaf mesophyll
  scattering, water band at 970 nm (Jacquemoud & Ustin, PROSPECT; USGS splib07 'grass', 'oak').
- Car paints: most pigments are transparent or reflective in the NIR (TiO2 white ~0.8 flat;
  organic reds ~0.6–0.7 above 620 nm; phthalocyanine blue and green low in the red, rising past
  ~700 nm to ~0.5), while carbon-black paint stays ~0.05 everywhere (solar-reflective coatings
  literature, e.g. Levinson et al. 2005, 'Methods of creating solar-reflective nonwhite
  surfaces'). Metallic silver ~0.5–0.6, slightly rising (aluminium flake; interband dip ~825 nm).
- Lane paint: TiO2 white ~0.75 with TiO2's absorption edge below ~400 nm; yellow (chrome-free
  organic yellow) low blue, edge ~500 nm to ~0.65, high in the NIR.
- Skin: melanin absorption falling as ~λ^-3.5 (Jacques 2013), oxy-haemoglobin bands at 542 and
  577 nm and the Soret band at 415 nm, NIR plateau ~0.55–0.65 (light) / ~0.35–0.45 (dark),
  water band at 970 nm (Anderson & Parrish 1981).
- Textiles: most textile dyes are NIR-transparent, so dyed cotton rises to ~0.5–0.7 past 700 nm
  (indigo denim: ~0.05 at 600–650 nm, ~0.5 at 800 nm) (NIR false-colour and camouflage
  literature); carbon-pigmented black stays low. The clothing palette follows the same rule:
  reactive, vat and disperse dyes on cotton and polyester (navy, burgundy, beige, yellow, pink …)
  keep their visible shape and turn NIR-bright (~0.5–0.75) past ~700–760 nm, as camouflage-
  textile studies report for undyed-in-the-NIR fabrics; only carbon-black pigment stays dark.
- High-visibility yellow and orange (EN ISO 20471 background materials, luminance factor ≥ 0.70
  and ≥ 0.40 *with* fluorescence): reflective-only approximations, a sharp edge at ~495 nm
  (yellow-green) or ~575 nm (orange) to ~0.85–0.9, NIR ~0.8; the fluorescent boost (re-emission
  of blue light as green/orange) is not modelled, so they are a little darker than real vests.
- Leather shoes: tanned leather (vegetable or chrome) is brown, low in the blue (~0.04), ~0.25
  in the red and NIR-bright (~0.45); black leather finishes are carbon-pigmented and stay
  ~0.05–0.08. White sneakers: TiO2-pigmented synthetics like white paint.
- Hair: eumelanin absorption falls with wavelength, so hair reflectance rises into the NIR;
  dark ~0.04 → 0.2, brown ~0.06 → 0.4, blonde (less eumelanin) ~0.12 → 0.55, gray ~0.25 → 0.45
  (eumelanin absorption falling steeply with λ, as for skin: Jacques 2013).
- Licence plates: retroreflective sheeting over aluminium, seen here diffusely: white ~0.8 with
  TiO2's edge below ~400 nm, yellow low in the blue with an edge near 500 nm; both stay bright
  in the NIR (ANPR cameras read plates at ~850 nm because the background reflects there and the
  carbon-black characters do not; the characters are not modelled).
- Glass seen diffusely (tinted windows, dark interiors): ~0.06–0.08 flat; tyre rubber ~0.04.
- Variants blended in by the procedural surfaces (scene/city/surfaces.py): aged asphalt ~0.09
  rising to ~0.14 (oxidised binder, exposed aggregate; Herold et al. 2004 find aged roads up to
  twice as bright as fresh ones); cement–lime mortar, lighter than concrete (~0.3 → 0.45);
  over-fired (clinker) brick, darker with the same iron-oxide edge; urban grime (soot + mineral
  dust: black carbon is near-flat and dark, dust rises toward the red), ~0.05 → 0.10.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from workbench.errors import InvalidValueError
from workbench.scene.city.types import Material
from workbench.spectra import wavelength_grid

MATERIAL_WAVELENGTHS_NM = wavelength_grid(350.0, 1000.0, 5.0)


def _sig(wl: np.ndarray, center_nm: float, width_nm: float) -> np.ndarray:
    return 1.0 / (1.0 + np.exp(-(wl - center_nm) / width_nm))


def _gauss(wl: np.ndarray, center_nm: float, sigma_nm: float) -> np.ndarray:
    return np.exp(-0.5 * ((wl - center_nm) / sigma_nm) ** 2)


def _edge(wl, low, high, center_nm, width_nm):
    """Absorption edge: `low` below center_nm, `high` above it."""
    return low + (high - low) * _sig(wl, center_nm, width_nm)


def _uv_falloff(wl, center_nm=380.0, width_nm=12.0):
    """Most binders and pigments absorb in the near UV: factor falling to ~0.5 below ~380 nm."""
    return 0.5 + 0.5 * _sig(wl, center_nm, width_nm)


def _paint(wl, vis, nir_level, nir_edge_nm=720.0, nir_width_nm=25.0):
    """A coloured paint: visible shape `vis`, then a rise to nir_level past nir_edge_nm."""
    s = _sig(wl, nir_edge_nm, nir_width_nm)
    return (vis * (1 - s) + nir_level * s) * _uv_falloff(wl)


def _skin(wl, melanin, nir_level):
    mel = np.exp(-melanin * (wl / 500.0) ** -3.5)
    blood = 1 - 0.3 * _gauss(wl, 542, 12) - 0.3 * _gauss(wl, 577, 10) - 0.4 * _gauss(wl, 415, 18)
    blood = blood - 0.1 * (1 - _sig(wl, 600, 12))   # haemoglobin absorbs below ~600 nm
    water = 1 - 0.12 * _gauss(wl, 970, 25)
    return nir_level * mel * np.clip(blood, 0.2, 1.0) * water


def _vegetation(wl, green_peak, nir_level, edge_nm=715.0):
    vis = 0.04 + (green_peak - 0.04) * _gauss(wl, 552, 28) - 0.015 * _gauss(wl, 672, 15)
    s = _sig(wl, edge_nm, 11.0)
    water = 1 - 0.10 * _gauss(wl, 970, 25)
    return (vis * (1 - s) + nir_level * s) * water


def _builders(wl: np.ndarray) -> dict[str, np.ndarray]:
    flat = np.ones_like(wl)
    ramp = (wl - 350.0) / 650.0
    return {
        # road, ground, walls
        "asphalt": 0.06 + 0.035 * ramp,
        "asphalt_aged": 0.09 + 0.05 * ramp,
        "mortar": _edge(wl, 0.30, 0.45, 500, 60) * _uv_falloff(wl),
        "brick_dark": (_edge(wl, 0.05, 0.22, 595, 25) + 0.04 * _sig(wl, 760, 40)
                       - 0.03 * _gauss(wl, 870, 40)) * _uv_falloff(wl),
        "grime": 0.05 + 0.05 * _sig(wl, 600, 120),
        "concrete": _edge(wl, 0.22, 0.38, 520, 60) * _uv_falloff(wl),
        "concrete_dark": _edge(wl, 0.14, 0.24, 520, 60) * _uv_falloff(wl),
        "brick": (_edge(wl, 0.08, 0.36, 585, 22) + 0.06 * _sig(wl, 760, 40)
                  - 0.05 * _gauss(wl, 870, 40)) * _uv_falloff(wl),
        "sandstone": (_edge(wl, 0.20, 0.48, 510, 45) - 0.03 * _gauss(wl, 900, 50)) * _uv_falloff(wl),
        "plaster_white": _edge(wl, 0.55, 0.78, 400, 10) - 0.03 * ramp,
        "glass_dark": 0.07 + 0.01 * _gauss(wl, 530, 60) - 0.01 * ramp,
        "soil": _edge(wl, 0.08, 0.32, 620, 120),
        "grass": _vegetation(wl, 0.10, 0.45),
        "leaves": _vegetation(wl, 0.12, 0.50),
        "bark": _edge(wl, 0.06, 0.30, 700, 60),
        # car and vehicle paints
        "paint_white": _edge(wl, 0.30, 0.82, 405, 10) - 0.04 * ramp,
        "paint_black": 0.045 + 0.005 * ramp,
        "paint_gray": (0.22 + 0.02 * ramp) * _uv_falloff(wl),
        "paint_silver": (0.50 + 0.08 * ramp - 0.05 * _gauss(wl, 825, 40)) * _uv_falloff(wl),
        "paint_red": _paint(wl, _edge(wl, 0.05, 0.70, 600, 12), 0.68, 760, 40),
        "paint_blue": _paint(wl, 0.05 + 0.28 * _gauss(wl, 460, 35) + 0.02 * _gauss(wl, 540, 30),
                             0.55, 730, 18),
        "paint_green": _paint(wl, 0.05 + 0.22 * _gauss(wl, 525, 35), 0.55, 715, 18),
        "paint_yellow": _paint(wl, _edge(wl, 0.07, 0.72, 505, 14), 0.74, 760, 40),
        "paint_orange": _paint(wl, _edge(wl, 0.06, 0.70, 570, 14), 0.72, 760, 40),
        # licence plates
        "plate_white": _edge(wl, 0.30, 0.82, 400, 10) - 0.03 * ramp,
        "plate_yellow": _edge(wl, 0.08, 0.72, 505, 13) * _uv_falloff(wl) + 0.06 * _sig(wl, 740, 30),
        # lane paint
        "lane_white": _edge(wl, 0.12, 0.75, 400, 10) - 0.05 * ramp,
        "lane_yellow": _edge(wl, 0.08, 0.64, 505, 13) * _uv_falloff(wl) + 0.03 * _sig(wl, 740, 30),
        # metals, rubber, plastic, light lenses
        "metal_galvanized": (0.42 + 0.06 * ramp - 0.04 * _gauss(wl, 825, 40)) * flat,
        "metal_dark": 0.12 + 0.03 * ramp,
        "rubber": 0.035 + 0.01 * ramp,
        "plastic_black": 0.05 + 0.03 * _sig(wl, 750, 40),
        "lens_red": _paint(wl, _edge(wl, 0.04, 0.55, 610, 10), 0.60, 760, 40),
        "lens_clear": _edge(wl, 0.40, 0.60, 420, 20),
        "mailbox_blue": _paint(wl, 0.04 + 0.18 * _gauss(wl, 465, 35), 0.45, 730, 18),
        "wood": _edge(wl, 0.10, 0.50, 600, 60) * _uv_falloff(wl),
        # people
        "skin_light": _skin(wl, 0.75, 0.66),
        "skin_medium": _skin(wl, 1.30, 0.58),
        "skin_dark": _skin(wl, 1.90, 0.50),
        "hair_dark": 0.04 + 0.16 * _sig(wl, 760, 90),
        "cloth_black": 0.04 + 0.36 * _sig(wl, 730, 25),
        "cloth_white": _edge(wl, 0.35, 0.80, 420, 12) - 0.05 * ramp,
        "cloth_gray": 0.25 + 0.30 * _sig(wl, 720, 30),
        "cloth_denim": _paint(wl, 0.06 + 0.12 * _gauss(wl, 470, 45), 0.50, 715, 22),
        "cloth_red": _paint(wl, _edge(wl, 0.05, 0.55, 600, 13), 0.62, 740, 30),
        "cloth_green": _paint(wl, 0.06 + 0.16 * _gauss(wl, 530, 35), 0.55, 705, 18),
        "cloth_khaki": _paint(wl, _edge(wl, 0.10, 0.38, 560, 40), 0.55, 720, 30),
        "cloth_carbon": 0.035 + 0.01 * ramp,
        # clothing palette of the detailed pedestrians (dyed textiles NIR-bright, see above)
        "cloth_navy": _paint(wl, 0.04 + 0.07 * _gauss(wl, 460, 40), 0.50, 715, 22),
        "cloth_blue": _paint(wl, 0.06 + 0.32 * _gauss(wl, 465, 35), 0.55, 720, 20),
        "cloth_burgundy": _paint(wl, _edge(wl, 0.04, 0.28, 630, 15), 0.58, 740, 30),
        "cloth_beige": _paint(wl, _edge(wl, 0.25, 0.55, 540, 50), 0.65, 740, 40),
        "cloth_brown": _paint(wl, _edge(wl, 0.05, 0.22, 600, 45), 0.55, 740, 35),
        "cloth_yellow": _paint(wl, _edge(wl, 0.08, 0.68, 510, 14), 0.70, 760, 40),
        "cloth_pink": _paint(wl, _edge(wl, 0.38, 0.72, 590, 18) - 0.12 * _gauss(wl, 530, 30), 0.75, 760, 40),
        "cloth_hivis_yellow": _paint(wl, _edge(wl, 0.06, 0.90, 495, 14) - 0.12 * _sig(wl, 610, 20),
                                     0.80, 760, 40),
        "cloth_hivis_orange": _paint(wl, _edge(wl, 0.05, 0.85, 575, 14), 0.80, 760, 40),
        "leather_brown": _paint(wl, _edge(wl, 0.04, 0.25, 610, 50), 0.45, 760, 60),
        "leather_black": 0.045 + 0.03 * _sig(wl, 750, 50),
        "shoe_white": _edge(wl, 0.30, 0.75, 415, 12) - 0.05 * ramp,
        "hair_brown": 0.05 + 0.35 * _sig(wl, 720, 110),
        "hair_blonde": 0.10 + 0.45 * _sig(wl, 600, 90),
        "hair_gray": _edge(wl, 0.25, 0.45, 550, 120),
    }


# Global car colour shares (Axalta 2021 colour popularity report: white ~35 %, black ~19 %,
# gray ~17 %, silver ~10 %, blue ~8 %, red ~6 %, others ~5 %), normalised.
CAR_PAINTS: dict[str, float] = {"paint_white": 0.35, "paint_black": 0.19, "paint_gray": 0.17,
                                "paint_silver": 0.10, "paint_blue": 0.08, "paint_red": 0.06,
                                "paint_green": 0.025, "paint_yellow": 0.025}
BUS_PAINTS = ("paint_yellow", "paint_blue", "paint_white", "paint_red")
FACADES = ("brick", "concrete", "concrete_dark", "sandstone", "plaster_white")
SKINS = ("skin_light", "skin_medium", "skin_dark")
CLOTHES = ("cloth_black", "cloth_white", "cloth_gray", "cloth_denim", "cloth_red", "cloth_green",
           "cloth_khaki", "cloth_carbon")
# Palettes of the detailed pedestrians (workbench/scene/city/people.py).
TOPS = ("cloth_black", "cloth_white", "cloth_gray", "cloth_navy", "cloth_red", "cloth_green",
        "cloth_beige", "cloth_blue", "cloth_burgundy", "cloth_carbon", "cloth_yellow", "cloth_pink",
        "cloth_khaki", "cloth_denim", "cloth_hivis_yellow", "cloth_brown", "cloth_hivis_orange")
BOTTOMS = ("cloth_denim", "cloth_black", "cloth_navy", "cloth_khaki", "cloth_gray", "cloth_carbon",
           "cloth_beige", "cloth_brown")
SHOES = ("leather_brown", "leather_black", "shoe_white", "plastic_black", "cloth_gray")
HAIRS = ("hair_dark", "hair_brown", "hair_blonde", "hair_gray")


def reflectance(name: str, wavelengths_nm: np.ndarray | None = None) -> np.ndarray:
    """Reflectance (0…1) of a named material on wavelengths_nm (default 350–1000 nm in 5 nm
    steps), linearly interpolated; end values are held outside 350–1000 nm."""
    table = _table()
    if name not in table:
        raise InvalidValueError(f"unknown material '{name}'; known: {', '.join(sorted(table))}")
    if wavelengths_nm is None:
        return table[name].copy()
    return np.interp(np.asarray(wavelengths_nm, float), MATERIAL_WAVELENGTHS_NM, table[name])


@lru_cache(maxsize=1)
def _table() -> dict[str, np.ndarray]:
    table = {}
    for name, r in _builders(MATERIAL_WAVELENGTHS_NM).items():
        if np.any(~np.isfinite(r)) or r.min() < 0.0 or r.max() > 1.0:
            raise RuntimeError(f"material '{name}' is unphysical: range {r.min():.3f}–{r.max():.3f}")
        r.setflags(write=False)
        table[name] = r
    return table


def material_names() -> tuple[str, ...]:
    """All material names, sorted."""
    return tuple(sorted(_table()))


def city_materials() -> dict[str, Material]:
    """Every material as a `Material` on MATERIAL_WAVELENGTHS_NM (fresh arrays)."""
    return {n: Material(n, MATERIAL_WAVELENGTHS_NM.copy(), r.copy()) for n, r in _table().items()}
