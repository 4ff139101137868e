"""Scenes: geometry shapes -> gmsh -> a mesh with named bodies, regions and boundaries."""
