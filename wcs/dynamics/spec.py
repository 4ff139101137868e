"""The `dynamics:` block of a study and the checks that tie it to the scene.

A study with this block is time dependent ([101]); without it nothing of this module acts. The
block is read by pydantic like the rest of the study (`wcs.study` holds it as `Study.dynamics`);
`check_dynamics` is the one call the loader makes once the scene and the uncertain data are known.
"""
from __future__ import annotations

from typing import Annotated, Literal, Optional, Union

from pydantic import Field, model_validator

from wcs.errors import StudyError
from wcs.options import Strict
from wcs.scene.spec import Name, check_ricker

MAX_LEVELS = 10_000_000          # time levels of one solve: end_time / time_step
SECONDS = {"gt": 0, "le": 1e12}

Velocity = Annotated[list[Annotated[float, Field(ge=-1e6, le=1e6)]], Field(min_length=2, max_length=3)]


class InitialVelocity(Strict):
    """Rest, with the rigid velocities [m/s] of named bodies."""
    velocity: Annotated[dict[Name, Velocity], Field(min_length=1)]


class Dynamics(Strict):
    end_time: float = Field(**SECONDS, description="the last time level [s]")
    time_step: float = Field(**SECONDS, description="Δt [s]")
    scheme: Literal["seed", "stabilized"] = Field(
        "seed", description="seed: the seed's semi-implicit scheme (seed [101, (10)]); stabilized: the "
        "contact-stabilized Newmark rule of Deuflhard–Krause–Ertel")
    output_every: int = Field(1, ge=1, description="fields are kept at every n-th level (and the last)")
    initial: Union[Literal["static", "rest"], InitialVelocity] = Field(
        "static", description="static: the static contact solution of the scene at t = 0, as the seed "
        "requires (seed [101, §2]); rest; or rest with rigid velocities of named bodies")

    @model_validator(mode="after")
    def _levels(self):
        levels = self.end_time / self.time_step
        if self.time_step > self.end_time:
            raise ValueError(f"time_step {self.time_step:g} s is longer than end_time {self.end_time:g} s")
        if levels > MAX_LEVELS:
            raise ValueError(f"end_time / time_step = {levels:.3g} levels, more than {MAX_LEVELS:g}")
        return self

    @property
    def levels(self) -> int:
        """The number of time steps: t_n = n Δt, n = 1 … levels, the last one at end_time or the
        first level past it (end_time is not cut short)."""
        return int(-(-round(self.end_time / self.time_step, 9) // 1))


def check_dynamics(dynamics: Dynamics | None, scene, uncertain, criteria, solver, error) -> None:
    """The dynamic study against its scene: every material has a density, the bodies given
    velocities exist with the scene's dimension, the solver can step in time; a static study
    does not vary dynamic numbers nor reduce criteria over time. `error(path, message)`."""
    if dynamics is None:
        for key in ("sources", "absorbing"):
            if getattr(scene, key):
                raise error(("scene", key), "acts only in a dynamic study (a `dynamics:` block)")
        for name, load in scene.loads.items():
            if load.time is not None:
                raise error(("scene", "loads", name, "time"), "acts only in a dynamic study (a `dynamics:` block)")
        for entry in uncertain:
            if entry.path.split(".")[-1] == "density" or ".viscosity." in entry.path:
                raise error(("uncertain", entry.path), "acts only in a dynamic study (a `dynamics:` block)")
        for k, crit in enumerate(criteria):
            if crit.over_time is not None:
                raise error(("criteria", k, "over_time"), "applies only to a dynamic study (a `dynamics:` block)")
        return
    for name, material in scene.materials.items():
        if material.density is None:
            raise error(("scene", "materials", name, "density"),
                        "is missing: a dynamic study needs the density [kg/m^3] of every material")
    if solver.method == "qp":
        raise error(("solver", "method"), "'qp' does not step in time yet; use monolithic, iterative, dd or auto")
    check_loads(scene, uncertain, error)
    if isinstance(dynamics.initial, InitialVelocity):
        for body, v in dynamics.initial.velocity.items():
            where = ("dynamics", "initial", "velocity", body)
            if body not in scene.bodies:
                raise error(where, f"no body '{body}' in the scene (bodies: {', '.join(scene.bodies)})")
            if len(v) != scene.dimension:
                raise error(where, f"a velocity has {scene.dimension} components in a {scene.dimension}D scene")


def check_loads(scene, uncertain, error) -> None:
    """The dynamic loads against the scene and the uncertain box: a source's point has the
    scene's dimension; its Ricker wavelet starts from rest (delay · frequency >= 1,
    `wcs.scene.spec.check_ricker`) at every corner of the box, the least corner being the
    lower bounds; every absorbing boundary exists; a support on a boundary with dashpots holds
    it in the static initial state only (`wcs.dynamics.release`), so its value is not uncertain."""
    box = {e.path: (e.lower, e.upper) for e in uncertain}
    for name, src in scene.sources.items():
        if len(src.point) != scene.dimension:
            raise error(("scene", "sources", name, "point"),
                        f"has {len(src.point)} coordinates in a {scene.dimension}D scene")
        keys = {k: f"sources.{name}.wavelet.ricker.{k}" for k in ("frequency", "delay")}
        low = {k: box.get(path, (getattr(src.wavelet.ricker, k),))[0] for k, path in keys.items()}
        try:
            check_ricker(low["frequency"], low["delay"])
        except ValueError as e:
            varied = [path for path in keys.values() if path in box]
            where = ("uncertain", varied[0]) if varied else ("scene", "sources", name, "wavelet", "ricker")
            raise error(where, f"at the corner frequency {low['frequency']:g} Hz, delay {low['delay']:g} s of the "
                               f"box: {e}") from None
    absorbing = scene.absorbing
    if absorbing is None:
        return
    named = [(("scene", "absorbing", "dashpots", i), n) for i, n in enumerate(absorbing.dashpots)]
    if absorbing.layer is not None:
        named += [(("scene", "absorbing", "layer", "boundaries", i), n) for i, n in enumerate(absorbing.layer.boundaries)]
    for where, name in named:
        if name not in scene.boundaries:
            raise error(where, f"unknown boundary '{name}' (boundaries: {', '.join(scene.boundaries) or 'none'})")
    for entry in uncertain:
        keys = entry.path.split(".")
        if keys[0] == "supports" and keys[1] in absorbing.dashpots:
            raise error(("uncertain", entry.path), f"boundary '{keys[1]}' takes dashpots: its support holds it in the "
                                                  "static initial state only (the levels replace it by its "
                                                  "reaction), so its value cannot vary")
