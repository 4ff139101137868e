"""Material constants: E, ν ↔ Lamé, plane strain / plane stress, thermal stress coefficient."""
from __future__ import annotations


def lame(material: dict) -> tuple[float, float]:
    """(λ, μ) of the 3D (plane strain) Hooke law from `E, nu` or `lambda, mu`."""
    if "lambda" in material:
        return float(material["lambda"]), float(material["mu"])
    E, nu = float(material["E"]), float(material["nu"])
    return E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))


def plane_lame(material: dict, plane: str) -> tuple[float, float]:
    """(λ, μ) entering the 2D stiffness: plane stress uses λ* = 2λμ/(λ+2μ)."""
    lam, mu = lame(material)
    if plane == "stress":
        lam = 2 * lam * mu / (lam + 2 * mu)
    return lam, mu


def thermal_beta(material: dict, plane: str) -> float:
    """β with τ = c:e − β(T−T0)I: (3λ+2μ)α in plane strain, Eα/(1−ν) in plane stress."""
    alpha = float(material.get("expansion", 0.0) or 0.0)
    lam, mu = lame(material)
    if plane == "strain":
        return (3 * lam + 2 * mu) * alpha
    E = mu * (3 * lam + 2 * mu) / (lam + mu)
    nu = lam / (2 * (lam + mu))
    return E * alpha / (1 - nu)
