"""A private gmsh session (gmsh is a process-wide singleton): initialise it, or start a fresh
model if it is already running, set wcs's options, and undo all of it on exit."""
from __future__ import annotations

import importlib
import threading

from .estimate import CURVATURE_ELEMENTS


class _Gmsh:
    """The gmsh module, loaded at its first use (`gmsh.model...`): its library and OpenMP
    runtime hold 87 MB that a scene read from a mesh file never uses. The scene's modules
    take `gmsh` from here."""

    def __getattr__(self, name):
        return getattr(importlib.import_module("gmsh"), name)


gmsh = _Gmsh()
ALGORITHM_2D = 6                # Frontal-Delaunay

_lock = threading.Lock()        # gmsh is a process-wide singleton

OPTIONS = {
    "General.Terminal": 0,
    "General.Verbosity": 0,
    "General.NumThreads": 1,
    "Mesh.MaxNumThreads1D": 1,
    "Mesh.MaxNumThreads2D": 1,
    "Mesh.Algorithm": ALGORITHM_2D,
    # no Laplacian smoothing pass: it cost 40 % of meshing (0.55 s of 1.3 s at 8.6e4 unknowns)
    # for Frontal-Delaunay triangles that are good without it (shape quality 4√3·area/Σ edge²:
    # smallest 0.55-0.6, mean 0.96-0.99 on the shipped scenes, against 0.64-0.74 / 0.97-0.99)
    "Mesh.Smoothing": 0,
    "Mesh.ElementOrder": 1,
    "Mesh.RecombineAll": 0,
    "Mesh.MeshSizeFromPoints": 0,
    "Mesh.MeshSizeFromParametricPoints": 0,
    "Mesh.MeshSizeFromCurvature": CURVATURE_ELEMENTS,
    "Mesh.MeshSizeExtendFromBoundary": 1,
    "Mesh.MeshSizeMin": 0.0,
    "Mesh.MeshSizeMax": 1e22,
    "Mesh.MeshSizeFactor": 1.0,
    "Mesh.SaveAll": 0,
}


class Session:
    """A private gmsh session: initialise (or a fresh model if gmsh is already
    running), set our options, and undo all of it on exit."""

    counter = 0

    def __enter__(self):
        _lock.acquire()
        try:
            self.own = not gmsh.isInitialized()
            if self.own:
                gmsh.initialize(readConfigFiles=False, run=False, interruptible=False)
                self.saved = {}
            else:
                self.saved = {k: gmsh.option.getNumber(k) for k in OPTIONS}
                self.prev_model = gmsh.model.getCurrent()
            Session.counter += 1
            gmsh.model.add(f"wcs_scene_{Session.counter}")
            for k, v in OPTIONS.items():
                gmsh.option.setNumber(k, v)
        except BaseException:
            _lock.release()
            raise
        return self

    def __exit__(self, *exc):
        try:
            if self.own:
                gmsh.finalize()
            else:
                try:
                    gmsh.model.mesh.removeSizeCallback()
                except Exception:
                    pass
                gmsh.model.remove()
                for k, v in self.saved.items():
                    gmsh.option.setNumber(k, v)
                if self.prev_model:
                    try:
                        gmsh.model.setCurrent(self.prev_model)
                    except Exception:
                        pass
        finally:
            _lock.release()
        return False
