"""The numbers a dynamic study adds to a material, addressable by dotted path like the others
(`materials.<m>.density`, `materials.<m>.viscosity.ratio`, `...viscosity.E`, `...viscosity.nu`)."""
from __future__ import annotations

from wcs.scene.spec import DENSITY, POISSON, VISCOSITY_RATIO, VISCOUS_MODULUS

DYNAMIC_ADDRESSES = {
    "materials.<m>.density": DENSITY,
    "materials.<m>.viscosity.ratio": VISCOSITY_RATIO,
    "materials.<m>.viscosity.E": VISCOUS_MODULUS,
    "materials.<m>.viscosity.nu": POISSON,
}

DYNAMIC_UNITS = {
    "materials.<m>.density": "kg m-3",
    "materials.<m>.viscosity.ratio": "s",
    "materials.<m>.viscosity.E": "Pa s",
    "materials.<m>.viscosity.nu": "1",
}


def dynamic_numbers(name: str, material):
    """(dotted path, value) of a material's density and viscosity, where it gives them."""
    if material.density is not None:
        yield f"materials.{name}.density", material.density
    viscosity = material.viscosity
    for key in ("ratio", "E", "nu"):
        if viscosity is not None and getattr(viscosity, key) is not None:
            yield f"materials.{name}.viscosity.{key}", getattr(viscosity, key)
