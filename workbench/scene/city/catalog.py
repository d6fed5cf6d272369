"""The asset catalogue: every class's variants at each detail level, and the cached builder.

'simple' assets are scene.city.assets'; 'detailed' ones come from scene.city.people and
scene.city.vehicles (classes without a detailed builder use their simple one at every level).
"""
from __future__ import annotations

from functools import lru_cache

from workbench.errors import InvalidValueError
from workbench.scene.city import people, vehicles
from workbench.scene.city.assets import (BENCH_VARIANTS, BUS_SPECS, CAR_SPECS, LAMP_VARIANTS, MAILBOX_VARIANTS,
                                         PERSON_SPECS, TREE_VARIANTS, TRUCK_SPECS, Asset, _bench, _bus, _car,
                                         _lamp, _mailbox, _person, _tree, _truck)


def _variants() -> dict[str, dict[str, tuple]]:
    return {
        "car": {s.name: (_car, s) for s in CAR_SPECS},
        "pedestrian": {s.name: (_person, s) for s in PERSON_SPECS},
        "bus": {s.name: (_bus, s) for s in BUS_SPECS},
        "truck": {s.name: (_truck, s) for s in TRUCK_SPECS},
        "tree": {v[0]: (_tree, *v) for v in TREE_VARIANTS},
        "lamp": {v[0]: (_lamp, *v) for v in LAMP_VARIANTS},
        "bench": {v[0]: (_bench, *v) for v in BENCH_VARIANTS},
        "mailbox": {v[0]: (_mailbox, *v) for v in MAILBOX_VARIANTS},
    }


VARIANTS = _variants()
DETAIL_LEVELS = ("simple", "detailed")
# Detailed builders by class: {class: {variant: (builder, *args)}}; a class not listed here is
# built by its simple builder at every detail level.
DETAILED_BUILDERS: dict[str, dict[str, tuple]] = {"pedestrian": people.DETAILED_PEDESTRIANS,
                                                  **vehicles.detailed_builders()}


def _table(class_name: str, detail: str) -> dict[str, tuple]:
    if detail not in DETAIL_LEVELS:
        raise InvalidValueError(f"asset detail '{detail}' is not one of {', '.join(DETAIL_LEVELS)}")
    if class_name not in VARIANTS:
        raise InvalidValueError(f"no assets of class '{class_name}'; classes: {', '.join(VARIANTS)}")
    if detail == "detailed" and class_name in DETAILED_BUILDERS:
        return DETAILED_BUILDERS[class_name]
    return VARIANTS[class_name]


def variant_names(class_name: str, detail: str = "simple") -> tuple[str, ...]:
    """Names of the variants of one asset class (e.g. 'car') at a detail level."""
    return tuple(_table(class_name, detail))


@lru_cache(maxsize=None)
def build_asset(class_name: str, variant: str, detail: str = "simple") -> Asset:
    """The (cached) asset of a class and variant at a detail level, in local coordinates."""
    table = _table(class_name, detail)
    if variant not in table:
        raise InvalidValueError(f"unknown {class_name} variant '{variant}' at detail '{detail}'; known: "
                         f"{', '.join(table)}")
    fn, *args = table[variant]
    return fn(*args)

