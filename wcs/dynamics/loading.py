"""A dynamic study's loads and absorbing boundaries at one data set, as the stepping's hooks take
them (`wcs.dynamics.stepping.step_levels`: f(t) on the full DOFs, an extra damping matrix).

f(t) = f₀ + Σ_b (φ_b(t) − 1) f_b + Σ_s r_s(t) f_s: the data set's own load f₀ (body forces,
thermal stress, boundary loads at full value), each boundary load f_b scaled by its time
function φ_b (`wcs.dynamics.time_functions`), and each point source's nodal loads f_s times its
Ricker wavelet r_s — the seed's seismic volume forces [101, §2] (`wcs.dynamics.sources`).
The damping adds the seed's layer α ρ over the cells near its boundaries [101, (8)] and the
Lysmer–Kuhlemeyer dashpots (`wcs.dynamics.absorbing`). Every number is read at the data set
(the slots of `wcs.coefficients.ParameterMap` by dotted path), so an uncertain source point,
amplitude, frequency, layer or ramp acts.
"""
from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np
import scipy.sparse as sp

from ..errors import StudyError
from . import absorbing, sources, time_functions


def _at(scene_value, s, index, path):
    """The number at `path` of the data set's slots s (the scene's where it is not a slot)."""
    return float(s[index[path]]) if path in index else scene_value


def source_at(name: str, source: sources.Source, s, index) -> sources.Source:
    """The source with its numbers at the data set (StudyError at the source when its wavelet
    would not start from rest there)."""
    key = f"sources.{name}"
    ricker = source.wavelet.ricker
    data = {"point": [_at(v, s, index, f"{key}.point.{i}") for i, v in enumerate(source.point)],
            "wavelet": {"ricker": {k: _at(getattr(ricker, k), s, index, f"{key}.wavelet.ricker.{k}")
                                   for k in ("frequency", "delay")}}}
    if source.force is not None:
        data["force"] = [_at(v, s, index, f"{key}.force.{i}") for i, v in enumerate(source.force)]
    else:
        data["moment"] = [[_at(v, s, index, f"{key}.moment.{i}.{j}") for j, v in enumerate(row)]
                          for i, row in enumerate(source.moment)]
    try:
        return sources.Source.model_validate(data)
    except ValueError as e:
        raise StudyError(f"at this data set: {e}", path=f"scene.{key}") from None


def load_function(model, scene, c, s, index, heat=None) -> Callable[[float], np.ndarray] | None:
    """f(t) on the full DOFs of data set c (slots s by `index`), or None when nothing of the
    scene varies in time (the data set's own load, constant)."""
    timed = {b: load.time for b, load in scene.loads.items() if load.time is not None}
    if not timed and not scene.sources:
        return None
    f0 = model.mechanical_load(c, heat)
    parts = []
    for b, fn in timed.items():
        fb = c.pressure[b] * model.pressure_vectors[b] if b in model.pressure_vectors \
            else c.traction[b] @ model.traction_vectors[b]
        fn = _ramp_at(b, fn, s, index)
        parts.append((lambda t, fn=fn: float(time_functions.factor(fn, t)) - 1.0, fb))
    for name, source in scene.sources.items():
        here = source_at(name, source, s, index)
        fs = sources.source_vector(model.smesh, here, f"scene.sources.{name}")
        parts.append((lambda t, here=here: float(sources.wavelet(here, t)), fs))

    def load(t: float) -> np.ndarray:
        f = f0.copy()
        for scale, vector in parts:
            f += scale(t) * vector
        return f
    return load


def at_time_zero(c, scene, s, index):
    """The coefficients c with each timed boundary load at its factor at t = 0 (a ramp: 0), the
    loads the static initial state balances; c itself when no load has a time function. (A
    source's wavelet at t = 0 is below 1e-3 of its peak, `wcs.scene.spec.check_ricker`;
    the static state leaves it out.)"""
    timed = {b: load.time for b, load in scene.loads.items() if load.time is not None}
    if not timed:
        return c
    scale = {b: float(time_functions.factor(_ramp_at(b, fn, s, index), 0.0)) for b, fn in timed.items()}
    return dataclasses.replace(
        c, pressure={b: p * scale.get(b, 1.0) for b, p in c.pressure.items()},
        traction={b: np.asarray(t) * scale.get(b, 1.0) for b, t in c.traction.items()})


def _ramp_at(b, fn, s, index):
    """A load's time function with its ramp at the data set."""
    if fn.ramp is None:
        return fn
    return time_functions.TimeFunction(ramp=_at(fn.ramp, s, index, f"loads.{b}.time.ramp"))


def damping_matrix(model, scene, c, rho, s, index) -> sp.csr_matrix | None:
    """The absorbing boundaries' damping on the full DOFs at data set c (ρ per region), or None."""
    spec = scene.absorbing
    if spec is None:
        return None
    sm = model.smesh
    region = sm.cell_region
    C = None
    if spec.layer is not None:
        layer = absorbing.Layer(boundaries=spec.layer.boundaries,
                                thickness=_at(spec.layer.thickness, s, index, "absorbing.layer.thickness"),
                                damping=_at(spec.layer.damping, s, index, "absorbing.layer.damping"))
        C = absorbing.layer_damping(sm, layer, rho[region], "scene.absorbing.layer")
    if spec.dashpots:
        D = absorbing.dashpots(sm, spec.dashpots, rho[region], c.lam[region], c.mu[region],
                               "scene.absorbing.dashpots")
        C = D if C is None else C + D
    return sp.csr_matrix(C)


def damping_cells(model, scene, c, rho, s, index) -> tuple[absorbing.AbsorbingCells, np.ndarray] | None:
    """`damping_matrix` as cell pieces with their per-region coefficients (`AbsorbingCells`,
    `absorbing_coefficients`): what a subdomain takes of it (`dd`); None without absorbing boundaries."""
    spec = scene.absorbing
    if spec is None:
        return None
    sm = model.smesh
    layer, alpha = np.zeros(0, dtype=np.int64), 0.0
    if spec.layer is not None:
        facets = absorbing.named_facets(sm, spec.layer.boundaries, "scene.absorbing.layer.boundaries")
        layer = absorbing.layer_cells(sm.mesh, facets, _at(spec.layer.thickness, s, index, "absorbing.layer.thickness"))
        alpha = _at(spec.layer.damping, s, index, "absorbing.layer.damping")
    facets = (absorbing.named_facets(sm, spec.dashpots, "scene.absorbing.dashpots") if spec.dashpots
              else np.zeros(0, dtype=np.int64))
    return (absorbing.AbsorbingCells(sm.mesh, layer, facets),
            absorbing.absorbing_coefficients(alpha, rho, c.lam, c.mu))


def check_sources(ev, x) -> None:
    """Each source located in the mesh (`wcs.dynamics.sources.source_vector`, StudyError naming
    it) at data vector x and at every corner of the box of its uncertain point coordinates."""
    import itertools
    scene, pmap = ev.study.scene, ev.map
    box = {e.path: (e.lower, e.upper) for e in ev.study.uncertain}
    for name, source in scene.sources.items():
        keys = [f"sources.{name}.point.{i}" for i in range(len(source.point))]
        ranges = [box.get(k, (None,)) for k in keys]
        for corner in itertools.product(*ranges):
            s = pmap.slots(x).copy()
            for k, value in zip(keys, corner):
                if value is not None:
                    s[pmap.index[k]] = value
            here = source_at(name, source, s, pmap.index)
            sources.source_vector(ev.model.smesh, here, f"scene.sources.{name}")
