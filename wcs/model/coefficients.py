"""The coefficients of a data set and the parameter map x → coefficients.

The model's operators are affine combinations of fixed pieces (`wcs.model.model`); what a data
set changes is one flat coefficient vector c (`Coefficients`, laid out by `FIELDS`).
`ParameterMap` compiles, once per study, how the data vector x reaches c:

1. the scene's numbers s (one slot per addressable number: `materials.steel.E`,
   `loads.top.pressure`, ...) take x (and any other addressed value) by assignment;
2. c = A s for everything affine in the data — conductivities, loads, body forces and
   specific weights, support values, temperatures, heat sources, friction data — with A
   one sparse matrix;
3. the moduli on top: per material (E, ν) or (λ, μ), and α, give the λ, μ of the 2D
   stiffness (λ* = 2λμ/(λ + 2μ) in plane stress) and β (`wcs.model.materials`); in 3D the λ, μ and
   β = (3λ + 2μ)α of the full Hooke law, the ones plane strain keeps;
4. a Lipschitz slip-limit profile: g per contact node interpolated linearly in arc length
   from the profile's points (the seed's Tresca data g ∈ U_ad, a Lipschitz set); on a 3D
   contact surface bilinearly from a grid over the face (`wcs.contact.frame`).

The Jacobian ∂c/∂x is exact: A, the interpolation weights and the derivatives of the
material formulas. Nothing is copied per evaluation.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..contact.frame import grid_weights, hat_weights, surface_grid
from .dynamic_numbers import dynamic_numbers, load_numbers
from .materials import lame, plane_lame, thermal_beta

FIELDS = ("lam", "mu", "beta", "kappa", "source", "body_force", "pressure", "traction",
          "support_values", "temperature_values", "reference", "slip", "coulomb")

_MATERIAL_KEYS = ("E", "nu", "lambda", "mu", "conductivity", "expansion", "density_weight")


@dataclass
class Coefficients:
    """The numbers of one data set, laid out like the model's pieces."""
    lam: np.ndarray            # (nregions,) λ entering the 2D stiffness (λ* in plane stress)
    mu: np.ndarray             # (nregions,)
    beta: np.ndarray           # (nregions,) thermal stress coefficient
    kappa: np.ndarray          # (nregions,) conductivity (thermal scenes)
    source: np.ndarray         # (nregions,) heat source W
    body_force: np.ndarray     # (nregions, d)
    pressure: dict             # boundary -> p
    traction: dict             # boundary -> (tx, ty) or (tx, ty, tz)
    support_values: np.ndarray # values of the elastic constraints, model order
    temperature_values: np.ndarray
    reference: float
    slip: np.ndarray = field(default_factory=lambda: np.zeros(0))      # Tresca slip limit per contact node
    coulomb: np.ndarray = field(default_factory=lambda: np.zeros(0))   # Coulomb coefficient per contact node


def flatten(c: Coefficients) -> tuple[np.ndarray, dict[str, slice]]:
    """The coefficients as one vector and the slice of each field (dicts by sorted name)."""
    parts, slices, k = [], {}, 0
    for name in FIELDS:
        v = getattr(c, name)
        if isinstance(v, dict):
            v = np.concatenate([np.atleast_1d(np.asarray(v[b], float)) for b in sorted(v)]) if v else np.zeros(0)
        v = np.atleast_1d(np.asarray(v, float)).ravel()
        parts.append(v)
        slices[name] = slice(k, k + v.size)
        k += v.size
    return np.concatenate(parts), slices


def scene_numbers(scene):
    """(dotted path, value) of every number of the scene a data set can change, in a fixed
    order: materials, loads, body forces, supports, contacts, thermal data."""
    for m, mat in scene.materials.items():
        for key in _MATERIAL_KEYS:
            value = getattr(mat, "lam" if key == "lambda" else key)
            if value is not None:
                yield f"materials.{m}.{key}", value
        yield from dynamic_numbers(m, mat)
    for b, load in scene.loads.items():
        if load.pressure is not None:
            yield f"loads.{b}.pressure", load.pressure
        else:
            for i, v in enumerate(load.traction):
                yield f"loads.{b}.traction.{i}", v
    for t, force in scene.body_forces.items():
        for i, v in enumerate(force):
            yield f"body_forces.{t}.{i}", v
    for b, sup in scene.supports.items():
        if sup.u is not None:
            for i, v in enumerate(sup.u):
                if v is not None:
                    yield f"supports.{b}.u.{i}", v
        else:
            yield f"supports.{b}.normal", sup.normal
    for name, contact in scene.contacts.items():
        friction = contact.friction
        for key in ("slip_limit", "coefficient"):
            if friction is not None and getattr(friction, key) is not None:
                yield f"contacts.{name}.friction.{key}", getattr(friction, key)
    thermal = scene.thermal
    if thermal is not None:
        yield "thermal.reference", thermal.reference
        for b, v in thermal.temperature.items():
            yield f"thermal.temperature.{b}", v
        for t, v in thermal.sources.items():
            yield f"thermal.sources.{t}", v
    yield from load_numbers(scene)


class ParameterMap:
    """x → Coefficients for one model and one study's uncertain data, with ∂c/∂x.

    `model` gives the layout (regions and their materials, load, support and temperature
    names, the contact zone); `scene` (a `Scene`) the nominal numbers; `uncertain` the study's
    entries (`path`, `points`, and `lipschitz` for a slip-limit profile) in parameter order."""

    def __init__(self, model, scene, uncertain=()):
        self.plane = "strain" if model.dim == 3 else model.plane   # 3D: plane strain's (the full) Hooke law
        self.dim = d = model.dim
        numbers = list(scene_numbers(scene))
        self.index = {path: k for k, (path, _) in enumerate(numbers)}
        self.nominal = np.array([float(v) for _, v in numbers])
        nr = len(model.region_material)
        self.pressure_names = list(model.pressure_vectors)
        self.traction_names = list(model.traction_vectors)
        temperature_keys = getattr(model, "temperature_keys", [])
        zone = model.zone
        m = 0 if zone is None else zone.gap.size
        sizes = {"lam": nr, "mu": nr, "beta": nr, "kappa": nr, "source": nr, "body_force": d * nr,
                 "pressure": len(self.pressure_names), "traction": d * len(self.traction_names),
                 "support_values": len(model.support_keys), "temperature_values": len(temperature_keys),
                 "reference": 1, "slip": m, "coulomb": m}
        self.slices, k = {}, 0
        for name in FIELDS:
            self.slices[name] = slice(k, k + sizes[name])
            k += sizes[name]
        self.size = k

        # the parameters: a slot each, or a profile (interpolated onto the contact's nodes)
        self.param_slots, self.profiles, start = [], [], 0
        profiled = set()
        for entry in uncertain:
            if entry.lipschitz is not None:
                contact = entry.path.split(".")[1]
                rows = np.flatnonzero(zone.contact_of_node == zone.names.index(contact))
                if entry.grid is not None:       # on a 3D contact surface: bilinear on its own grid
                    arc, weights = None, grid_weights(surface_grid(zone.coords[rows])[0], entry.grid)
                else:
                    arc = zone.arc[rows]
                    weights = hat_weights(arc, entry.points)
                self.profiles.append((slice(start, start + entry.points), rows, arc, weights))
                profiled.add(contact)
                start += entry.points
            else:
                self.param_slots.append((start, self.index[entry.path]))
                start += 1
        self.nparam = start

        # c = A s: the affine part (rows in `FIELDS` order, columns the slots)
        rows, cols, vals = [], [], []

        def add(field_name: str, offset: int, path: str, value: float = 1.0) -> None:
            if path in self.index:
                rows.append(self.slices[field_name].start + offset)
                cols.append(self.index[path])
                vals.append(value)

        targets = model.targets
        for j, mat in enumerate(model.region_material):
            add("kappa", j, f"materials.{mat}.conductivity")
            add("body_force", d * j + d - 1, f"materials.{mat}.density_weight", -1.0)   # along −y (2D), −z (3D)
        for t, force in scene.body_forces.items():
            for j in targets[t]:
                for i in range(len(force)):
                    add("body_force", d * j + i, f"body_forces.{t}.{i}")
        for t in scene.thermal.sources if scene.thermal else {}:
            for j in targets[t]:
                add("source", j, f"thermal.sources.{t}")
        for k, b in enumerate(sorted(self.pressure_names)):
            add("pressure", k, f"loads.{b}.pressure")
        for k, b in enumerate(sorted(self.traction_names)):
            for i in range(d):
                add("traction", d * k + i, f"loads.{b}.traction.{i}")
        for k, (b, key) in enumerate(model.support_keys):
            add("support_values", k, f"supports.{b}.normal" if key == "normal" else f"supports.{b}.{key}")
        for k, b in enumerate(temperature_keys):
            add("temperature_values", k, f"thermal.temperature.{b}")
        add("reference", 0, "thermal.reference")
        for k, name in enumerate([] if zone is None else zone.names):
            for r in np.flatnonzero(zone.contact_of_node == k):
                if name not in profiled:
                    add("slip", r, f"contacts.{name}.friction.slip_limit")
                add("coulomb", r, f"contacts.{name}.friction.coefficient")
        self.A = sp.csr_matrix((vals, (rows, cols)), shape=(self.size, len(numbers)))

        # the moduli: per material its slots, and the regions it fills
        self.materials = []
        for mat in dict.fromkeys(model.region_material):
            keys = ("lambda", "mu") if f"materials.{mat}.lambda" in self.index else ("E", "nu")
            slots = [self.index[f"materials.{mat}.{key}"] for key in keys]
            alpha = self.index.get(f"materials.{mat}.expansion")
            regions = np.array([j for j, name in enumerate(model.region_material) if name == mat])
            self.materials.append((keys, slots, alpha, regions))

    def slots(self, x=(), others=None) -> np.ndarray:
        """The scene's numbers at data vector x (and `others`: {dotted path: value})."""
        s = self.nominal.copy()
        x = np.asarray(x, dtype=float)
        for k, slot in self.param_slots:
            s[slot] = x[k]
        for path, value in (others or {}).items():
            s[self.index[path]] = float(value)
        return s

    def flat(self, x=(), others=None) -> np.ndarray:
        """The flat coefficient vector (`flatten` order) at data vector x."""
        s = self.slots(x, others)
        c = self.A @ s
        sl = self.slices
        for keys, slots, alpha, regions in self.materials:
            material = dict(zip(keys, s[slots]))
            if alpha is not None:
                material["expansion"] = s[alpha]
            lam, mu = plane_lame(material, self.plane)
            c[sl["lam"].start + regions] = lam
            c[sl["mu"].start + regions] = mu
            c[sl["beta"].start + regions] = thermal_beta(material, self.plane)
        x = np.asarray(x, dtype=float)
        for chunk, rows, arc, weights in self.profiles:
            c[sl["slip"].start + rows] = (weights @ x[chunk] if arc is None else
                                          np.interp(arc, np.linspace(0, 1, chunk.stop - chunk.start), x[chunk]))
        return c

    def coefficients(self, x=(), others=None) -> Coefficients:
        """The model's coefficients at data vector x (and `others`: {dotted path: value})."""
        return self.unflatten(self.flat(x, others))

    def unflatten(self, c: np.ndarray) -> Coefficients:
        sl = self.slices
        pressure = dict(zip(sorted(self.pressure_names), c[sl["pressure"]]))
        traction = dict(zip(sorted(self.traction_names), c[sl["traction"]].reshape(-1, self.dim)))
        return Coefficients(
            lam=c[sl["lam"]], mu=c[sl["mu"]], beta=c[sl["beta"]], kappa=c[sl["kappa"]],
            source=c[sl["source"]], body_force=c[sl["body_force"]].reshape(-1, self.dim),
            pressure={b: float(pressure[b]) for b in self.pressure_names},
            traction={b: traction[b].copy() for b in self.traction_names},
            support_values=c[sl["support_values"]], temperature_values=c[sl["temperature_values"]],
            reference=float(c[sl["reference"]][0]), slip=c[sl["slip"]], coulomb=c[sl["coulomb"]])

    def jacobian(self, x=(), others=None) -> np.ndarray:
        """∂c/∂x (ncoef, nparam), exact: the affine part, the material formulas' derivatives,
        the profiles' interpolation weights."""
        s = self.slots(x, others)
        D = self.A.tolil()                       # ∂c/∂s
        sl = self.slices
        for keys, slots, alpha, regions in self.materials:
            dlam, dmu, dbeta = _material_derivatives(keys, s[slots], 0.0 if alpha is None else s[alpha],
                                                     self.plane)
            for j in regions:
                for col, a, b, g in zip(slots, dlam, dmu, dbeta):
                    D[sl["lam"].start + j, col] = a
                    D[sl["mu"].start + j, col] = b
                    D[sl["beta"].start + j, col] = g
                if alpha is not None:
                    D[sl["beta"].start + j, alpha] = dbeta[2]
        S = np.zeros((s.size, self.nparam))       # ∂s/∂x
        for k, slot in self.param_slots:
            S[slot, k] = 1.0
        J = D.tocsr() @ S
        for chunk, rows, _, weights in self.profiles:
            J[sl["slip"].start + rows, chunk] = weights
        return J


def _material_derivatives(keys, pair, alpha: float, plane: str):
    """∂(λ_2D, μ, β)/∂(pair, α) of one material; `pair` is (E, ν) or (λ, μ) (`keys` says).
    λ = Eν/((1+ν)(1−2ν)), μ = E/(2(1+ν)); plane stress λ* = 2λμ/(λ+2μ);
    β = (3λ+2μ)α (plane strain), 2μ(3λ+2μ)α/(λ+2μ) = Eα/(1−ν) (plane stress)."""
    if keys == ("E", "nu"):
        E, nu = pair
        lam, mu = lame({"E": E, "nu": nu})
        d = (1 + nu) * (1 - 2 * nu)
        L = np.array([[nu / d, E * (1 + 2 * nu**2) / d**2],            # ∂(λ, μ)/∂(E, ν)
                      [1 / (2 * (1 + nu)), -E / (2 * (1 + nu) ** 2)]])
    else:
        lam, mu = pair
        L = np.eye(2)
    q = lam + 2 * mu
    if plane == "stress":
        P = np.array([[4 * mu**2 / q**2, 2 * lam**2 / q**2], [0.0, 1.0]])  # ∂(λ*, μ)/∂(λ, μ)
        dbeta = alpha * np.array([8 * mu**2, 6 * lam**2 + 8 * lam * mu + 8 * mu**2]) / q**2
        beta = 2 * mu * (3 * lam + 2 * mu) / q
    else:
        P = np.eye(2)
        dbeta = alpha * np.array([3.0, 2.0])
        beta = 3 * lam + 2 * mu
    dlam, dmu = P @ L
    return dlam, dmu, np.r_[dbeta @ L, beta]
