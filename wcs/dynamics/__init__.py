"""Dynamic contact of Kelvin–Voigt viscoelastic bodies (the seed's paper [101], issue 29).

`spec` reads the `dynamics:` block; `numbers` makes a material's density and viscosity
addressable data; `mass` assembles the mass and viscous matrices;
`schemes` holds one time level of each scheme (operator, load, update) as pure functions;
`stepping` runs the levels with one contact solve each; `energy` measures what the levels
keep and lose; `command` is `wcs solve` on a dynamic study; `time_functions`, `sources` and
`absorbing` are the loads in time, the point sources and the absorbing boundaries.
"""

from ..scene import spec as _scene  # noqa: E402,F401 - the scene's models hold the loads below: the scene loads first
