"""Solvability of a floating body (wcs.contact.solvability): the 2D linear program by Clarabel
against its closed form, and the evaluator's imports without scipy.optimize / scipy.spatial.

The pad of `two_blocks` under a uniform top traction (fx, fy), fy < 0: Rᵀf = (fx, fy, −fx/4)
(translations x, y; rotation about the pad's centre (1, 0.25)), the normal rows give
α_y ≥ |α_θ|/2 and the slip is α_x + α_θ/4. For fx > Σ gw the maximum is fx − Σ gw at
α = (1, 0, 0) (lifting or turning costs more than it gains), otherwise 0. Clarabel stops at
gaps of 1e-12 on data scaled to O(1): 1e-10 of the scale has two orders of margin, and the
solver's test (value > 1e-9 Σ|Rᵀf|) three.
"""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from tests.contact.test_solver import two_blocks

from wcs.contact.solvability import unbalanced_rigid_motion

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("g", [0.0, 0.001, 0.0025])
def test_unbalanced_value_and_motion_in_closed_form(g):
    P = two_blocks(10, floating=True, load=(0.003, -0.01))
    gw = g * P["w"]
    value, alpha = unbalanced_rigid_motion(P["f"], P["Bn"], P["Bt"], gw, P["R"])
    scale = np.abs(P["R"].T @ P["f"]).sum()
    assert abs(value - (0.003 - gw.sum())) <= 1e-10 * scale, value
    np.testing.assert_allclose(alpha, [1.0, 0.0, 0.0], atol=1e-9)


@pytest.mark.parametrize("g", [0.003 + 1e-6, 0.004, 0.1])
def test_balanced_load_has_value_zero(g):
    P = two_blocks(10, floating=True, load=(0.003, -0.01))
    value, _ = unbalanced_rigid_motion(P["f"], P["Bn"], P["Bt"], g * P["w"], P["R"])
    assert abs(value) <= 1e-10 * np.abs(P["R"].T @ P["f"]).sum(), value


def test_an_evaluator_loads_neither_scipy_optimize_nor_scipy_spatial():
    """A fresh process that imports the evaluator (what `wcs run` does before its first
    evaluation) does not load scipy.optimize (~0.15 s with the scipy.spatial, scipy.special and
    scipy.fft it pulls in): the solvability LP goes to Clarabel, the KD-tree loads with 3D faces."""
    code = ("import sys, wcs.model.evaluation; "
            "print(' '.join(m for m in ('scipy.optimize', 'scipy.spatial') if m in sys.modules))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "", proc.stdout


def _one_node_on_a_plane(g: float):
    """Rigid translations α of a body on 4 contact nodes (normal e_z, tangents e_x, e_y), load
    work e = (0.3, 0.4, 1): the load presses on the contact (α_z ≤ 0 admissible gains no work),
    so the maximum is max(0, |(0.3, 0.4)| − Σ gw) at α = (0.6, 0.8, 0) on the unit ball."""
    m = 4
    Bn = np.tile([0.0, 0.0, 1.0], (m, 1))
    Bt = np.vstack([np.tile([1.0, 0.0, 0.0], (m, 1)), np.tile([0.0, 1.0, 0.0], (m, 1))])
    return np.array([0.3, 0.4, 1.0]), Bn, Bt, np.full(m, g / m), np.eye(3)


@pytest.mark.parametrize("g", [0.0, 0.2, 0.6])
def test_disc_friction_socp_in_closed_form(g):
    f, Bn, Bt, gw, R = _one_node_on_a_plane(g)
    value, alpha = unbalanced_rigid_motion(f, Bn, Bt, gw, R)
    assert abs(value - max(0.0, 0.5 - g)) <= 1e-10 * 1.7, value
    if g < 0.5:
        np.testing.assert_allclose(alpha, [0.6, 0.8, 0.0], atol=1e-8)


def test_the_3d_solvability_check_does_not_load_cvxpy():
    """The disc-friction SOCP goes to Clarabel directly: importing cvxpy for it took 1.9 s of a
    7 s `wcs solve` of the 3D patch (a floating block: every solve checks solvability); cvxpy
    stays the `qp` reference method's only."""
    code = ("import sys, numpy as np; from wcs.contact.solvability import unbalanced_rigid_motion as u; "
            "v, a = u(np.r_[0.3, 0.4, 1.0], np.c_[[0.0], [0.0], [1.0]], np.eye(3)[:2], np.r_[0.2], np.eye(3)); "
            "print(round(v, 9), 'cvxpy' in sys.modules)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == ["0.3", "False"], proc.stdout


def test_the_command_layer_loads_neither_scipy_optimize_nor_cvxpy():
    """What `wcs solve` loads before its first evaluation (the CLI and its commands) does not load
    scipy.optimize (0.44 s: the search's LPs import it where they run) nor cvxpy (1.9 s): fixed
    costs that kept `wcs solve` of the 3D patch at face 0.04 behind Kratos."""
    code = ("import sys, wcs.cli, wcs.app.commands; "
            "print(' '.join(m for m in ('scipy.optimize', 'cvxpy') if m in sys.modules))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "", proc.stdout
