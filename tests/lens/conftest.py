"""Independent paraxial / real-ray oracles for lens tests: optiland and rayoptics models of a Lens."""
import numpy as np
import pytest

from workbench.optics.lens import LINE_D_NM, paraxial, sensor_distance_mm


def optiland_model(lens):
    from optiland import optic
    from optiland.materials import IdealMaterial
    o = optic.Optic()
    o.surfaces.add(index=0, thickness=np.inf)
    for i, s in enumerate(lens.surfaces):
        t = s.thickness_mm if i < len(lens.surfaces) - 1 else sensor_distance_mm(lens)
        m = "air" if s.material.is_air else IdealMaterial(n=s.material.nd)
        o.surfaces.add(index=i + 1, radius=s.radius_mm, thickness=t, material=m, is_stop=s.is_stop)
    o.surfaces.add(index=len(lens.surfaces) + 1)
    o.set_aperture("EPD", paraxial(lens).epd_mm)
    o.fields.set_type("angle")
    o.fields.add(y=0)
    o.wavelengths.add(LINE_D_NM * 1e-3, is_primary=True)
    return o


def rayoptics_fod(lens):
    from rayoptics.optical.opticalmodel import OpticalModel
    from rayoptics.raytr.opticalspec import FieldSpec, PupilSpec, WvlSpec
    opm = OpticalModel()
    sm, osp = opm["seq_model"], opm["optical_spec"]
    osp["pupil"] = PupilSpec(osp, key=["object", "epd"], value=paraxial(lens).epd_mm)
    osp["fov"] = FieldSpec(osp, key=["object", "angle"], flds=[0.0])
    osp["wvls"] = WvlSpec([(LINE_D_NM, 1.0)], ref_wl=0)
    opm.radius_mode = True  # else the first column is read as curvature
    sm.gaps[0].thi = 1e10
    for i, s in enumerate(lens.surfaces):
        t = s.thickness_mm if i < len(lens.surfaces) - 1 else sensor_distance_mm(lens)
        r = 0.0 if s.curvature_per_mm == 0 else s.radius_mm
        sm.add_surface([r, t] if s.material.is_air else [r, t, s.material.nd, 64.0])
        if s.is_stop:
            sm.set_stop()
    opm.update_model()
    return opm["analysis_results"]["parax_data"].fod


@pytest.fixture(scope="session")
def oracles():
    return {"optiland": optiland_model, "rayoptics": rayoptics_fod}
