"""Dynamic contact of Kelvin–Voigt viscoelastic bodies (the seed's paper [101], issue 29).

`spec` reads the `dynamics:` block; `mass` assembles the mass and viscous matrices;
`schemes` holds one time level of each scheme (operator, load, update) as pure functions;
`stepping` runs the levels with one contact solve each; `energy` measures what the levels
keep and lose; `time_functions`, `sources` and `absorbing` are the loads in time, the point
sources and the absorbing boundaries as the levels need them (their study keys are models of
`wcs.scene.spec`), `loading` builds a data set's load in time and damping, `release` frees the
supports of boundaries that take dashpots. A material's density and viscosity as addressable
data are `wcs.model.dynamic_numbers`; `wcs solve` on a dynamic study is `wcs.app.dynamics`.
"""
