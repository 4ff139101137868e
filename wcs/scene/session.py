"""A private gmsh session (gmsh is a process-wide singleton): initialise it, or start a fresh
model if it is already running, set wcs's options, and undo all of it on exit."""
from __future__ import annotations

import threading

import gmsh

CURVATURE_ELEMENTS = 24         # Mesh.MeshSizeFromCurvature: elements per 2*pi of arc
ALGORITHM_2D = 6                # Frontal-Delaunay

_lock = threading.Lock()        # gmsh is a process-wide singleton

OPTIONS = {
    "General.Terminal": 0,
    "General.Verbosity": 0,
    "General.NumThreads": 1,
    "Mesh.MaxNumThreads1D": 1,
    "Mesh.MaxNumThreads2D": 1,
    "Mesh.Algorithm": ALGORITHM_2D,
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
