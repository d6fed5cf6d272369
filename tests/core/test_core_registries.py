"""Every method choice is one Registry: the parameter that picks a method allows exactly the
registered names, and dispatch refuses an unknown name with a ParameterError naming that parameter."""
from __future__ import annotations

from typing import get_args

import numpy as np
import pytest

from workbench.errors import ParameterError
from workbench.registry import Registry


def _choices():
    """(registry, params model, field, names the field allows besides the registry's)."""
    import workbench.optics.formation  # noqa: F401  (registers the optics levels)
    from workbench.isp.illuminant import ILLUMINANT_CORRECTIONS
    from workbench.isp.params import ISPParams
    from workbench.optics.params import OpticsParams
    from workbench.optics.types import OPTICS_MODELS
    from workbench.scene.charts import CHARTS
    from workbench.scene.params import SceneParams
    from workbench.sensor.auto_exposure import AUTO_EXPOSURE_METHODS
    from workbench.sensor.params import SensorParams
    from workbench.sensor.signal import REGRID_METHODS
    return [(OPTICS_MODELS, OpticsParams, "model", set()),
            (AUTO_EXPOSURE_METHODS, SensorParams, "auto_exposure_method", set()),
            (REGRID_METHODS, SensorParams, "regrid_method", set()),
            (ILLUMINANT_CORRECTIONS, ISPParams, "illuminant_correction", set()),
            (CHARTS, SceneParams, "kind", {"city"})]       # the city is rendered, not a chart


def test_registry_dispatches_lists_and_refuses():
    reg: Registry = Registry("section.method", "test method")

    @reg.register("double")
    def double(x):
        return 2 * x
    reg.register("square")(lambda x: x * x)
    assert reg["double"](3) == 6 and reg["square"](3) == 9
    assert reg.names == ("double", "square") and list(reg) == ["double", "square"] and len(reg) == 2
    assert "double" in reg and "cube" not in reg and 3 not in reg and reg.get("cube") is None
    with pytest.raises(ParameterError) as info:
        reg["cube"]
    assert info.value.field == "section.method" and info.value.given == "cube"
    assert "double, square" in str(info.value)
    with pytest.raises(ParameterError):
        reg.check(None)
    with pytest.raises(ValueError, match="already registered"):
        reg.register("double")(lambda x: x + x)


@pytest.mark.parametrize("index", range(5))
def test_params_allow_exactly_the_registered_names(index):
    registry, model, field, extra = _choices()[index]
    allowed = set(get_args(model.model_fields[field].annotation))
    assert allowed == set(registry.names) | extra, (model.__name__, field)


def test_demosaic_parameter_validates_against_the_registry():
    from workbench.isp.demosaic import DEMOSAIC_METHODS
    from workbench.isp.params import ISPParams
    for name in DEMOSAIC_METHODS.names:
        assert ISPParams(demosaic=name.upper()).demosaic == name
    with pytest.raises(ValueError, match="isp.demosaic: unknown demosaic method; allowed: bilinear"):
        ISPParams(demosaic="nearest")


def test_dispatch_refuses_unknown_names_naming_the_parameter():
    from workbench.isp.demosaic import demosaic
    from workbench.isp.illuminant import illuminant_gains
    from workbench.optics.types import OPTICS_MODELS
    from workbench.sensor.auto_exposure import auto_exposure
    from workbench.sensor.params import SensorParams
    from workbench.sensor.signal import resample_matrix
    calls = {"isp.demosaic": lambda: demosaic(np.zeros((4, 4)), np.array([[0, 1], [1, 2]]), ["R", "G", "B"], "nope"),
             "isp.illuminant_correction": lambda: illuminant_gains(np.ones((2, 2, 3)), np.eye(3), "nope", np.ones(3)),
             "optics.model": lambda: OPTICS_MODELS["nope"],
             "sensor.auto_exposure_method": lambda: auto_exposure(np.ones((4, 4)), SensorParams(), method="nope"),
             "sensor.regrid_method": lambda: resample_matrix(8, 1e-6, 4, 2e-6, "nope")}
    for field, call in calls.items():
        with pytest.raises(ParameterError) as info:
            call()
        assert info.value.field == field
