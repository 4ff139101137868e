"""Dynamic contact of viscoelastic bodies, the seed's paper [101]: loads in time, sources, absorbing boundaries."""
