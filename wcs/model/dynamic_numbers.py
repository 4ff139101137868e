"""The numbers a dynamic study adds, addressable by dotted path like the others: a material's
(`materials.<m>.density`, `materials.<m>.viscosity.ratio`, `...viscosity.E`, `...viscosity.nu`),
a source's (`sources.<s>.force.<i>`, `sources.<s>.point.<i>`, `sources.<s>.wavelet.ricker.frequency`,
...), the absorbing layer's and a load's time ramp (the address tables of the
scene's dynamic keys, `wcs.scene.spec`)."""
from __future__ import annotations

from wcs.scene.spec import (ABSORBING_ADDRESSES, DENSITY, POISSON, SOURCE_ADDRESSES, TIME_ADDRESSES, VISCOSITY_RATIO,
                            VISCOUS_MODULUS)

DYNAMIC_ADDRESSES = {
    "materials.<m>.density": DENSITY,
    "materials.<m>.viscosity.ratio": VISCOSITY_RATIO,
    "materials.<m>.viscosity.E": VISCOUS_MODULUS,
    "materials.<m>.viscosity.nu": POISSON,
    **SOURCE_ADDRESSES,
    **ABSORBING_ADDRESSES,
    **TIME_ADDRESSES,
}

DYNAMIC_UNITS = {
    "materials.<m>.density": "kg m-3",
    "materials.<m>.viscosity.ratio": "s",
    "materials.<m>.viscosity.E": "Pa s",
    "materials.<m>.viscosity.nu": "1",
    "sources.<s>.point.<i>": "m",
    "sources.<s>.force.<i>": "N m-1 (2D), N (3D)",
    "sources.<s>.moment.<i>.<j>": "N m m-1 (2D), N m (3D)",
    "sources.<s>.wavelet.ricker.frequency": "Hz",
    "sources.<s>.wavelet.ricker.delay": "s",
    "absorbing.layer.thickness": "m",
    "absorbing.layer.damping": "s-1",
    "loads.<boundary>.time.ramp": "s",
}


def dynamic_numbers(name: str, material):
    """(dotted path, value) of a material's density and viscosity, where it gives them."""
    if material.density is not None:
        yield f"materials.{name}.density", material.density
    viscosity = material.viscosity
    for key in ("ratio", "E", "nu"):
        if viscosity is not None and getattr(viscosity, key) is not None:
            yield f"materials.{name}.viscosity.{key}", getattr(viscosity, key)


def load_numbers(scene):
    """(dotted path, value) of the scene's dynamic loads: the time ramps of loads, the sources'
    points, forces or moment tensors and wavelets, the absorbing layer's thickness and damping."""
    for b, load in scene.loads.items():
        if load.time is not None and load.time.ramp is not None:
            yield f"loads.{b}.time.ramp", load.time.ramp
    for name, src in scene.sources.items():
        for i, v in enumerate(src.point):
            yield f"sources.{name}.point.{i}", v
        for i, v in enumerate(src.force or ()):
            yield f"sources.{name}.force.{i}", v
        for i, row in enumerate(src.moment or ()):
            for j, v in enumerate(row):
                yield f"sources.{name}.moment.{i}.{j}", v
        yield f"sources.{name}.wavelet.ricker.frequency", src.wavelet.ricker.frequency
        yield f"sources.{name}.wavelet.ricker.delay", src.wavelet.ricker.delay
    layer = scene.absorbing.layer if scene.absorbing is not None else None
    if layer is not None:
        yield "absorbing.layer.thickness", layer.thickness
        yield "absorbing.layer.damping", layer.damping
