"""Domain decomposition contact solver of the seed [21, §4–7] (Schur complements, PCG1, PCG2).

`solve_dd(model, scene, Kr, rhs, u0, options)` solves the model's reduced contact
problem; `solve_heat_dd(model, coefficients, options)` the thermal step.
"""
from .solver import DDOutcome, DDResult, solve_dd, solve_heat_dd

__all__ = ["solve_dd", "solve_heat_dd", "DDResult", "DDOutcome"]
