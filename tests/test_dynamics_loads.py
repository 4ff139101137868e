"""Loads of a dynamic study (study-format §8, issue 29): time functions, the Ricker wavelet, and a
point source's nodal loads (a force, a moment tensor) in 2D and 3D."""
import numpy as np
import pytest
import skfem
from pydantic import ValidationError

from wcs.dynamics.sources import (Source, containing_cells, moment_tensor_vector, point_force_vector, ricker,
                                  source_vector)
from wcs.dynamics.time_functions import TimeFunction, factor
from wcs.errors import StudyError
from wcs.scene.meshdata import SceneMesh

RICKER = {"ricker": {"frequency": 2.0, "delay": 0.6}}


def _fault(model, data):
    with pytest.raises(ValidationError) as err:
        model.model_validate(data)
    first = err.value.errors()[0]
    return first["loc"], first["msg"]


# ---------------------------------------------------------------- time functions

def test_ramp_rises_linearly_then_holds():
    fn = TimeFunction.model_validate({"ramp": 0.1})
    assert np.allclose(factor(fn, [0.0, 0.025, 0.1, 7.0]), [0.0, 0.25, 1.0, 1.0], rtol=0, atol=1e-15)


def test_table_is_piecewise_linear_and_holds_its_ends():
    fn = TimeFunction.model_validate({"table": [[0.5, 2.0], [1.0, -1.0], [3, 0]]})
    # between rows the straight line: the midpoint of each pair of rows is their mean
    assert np.allclose(factor(fn, [0.75, 2.0]), [0.5, -0.5], rtol=0, atol=1e-15)
    assert np.allclose(factor(fn, [0.0, 0.5, 3.0, 10.0]), [2.0, 2.0, 0.0, 0.0], rtol=0, atol=0)


def test_no_time_function_is_a_constant_load():
    assert np.array_equal(factor(None, [0.0, 1.0, 5.0]), [1.0, 1.0, 1.0])


@pytest.mark.parametrize("data, loc, words", [
    ({"table": [[0.0, 0.0], [0.2, 1.0], [0.2, 2.0]]}, ("table",), "row 2: the times must increase"),
    ({"table": [[0.0, 0.0], [-0.5, 1.0]]}, ("table",), "row 1: the time -0.5"),
    ({"table": [[0.0, float("nan")]]}, ("table", 0, 1), "finite"),
    ({"table": [[0.0, 1e9]]}, ("table",), "row 0: the factor"),
    ({"table": [[0.0]]}, ("table", 0), "at least 2"),
    ({"ramp": 0.0}, ("ramp",), "greater than 0"),
    ({"ramp": float("inf")}, ("ramp",), "finite"),
    ({"ramp": 1.0, "table": [[0.0, 1.0]]}, (), "exactly one of ramp, table"),
    ({"rmap": 1.0}, (), "did you mean 'ramp'"),
])
def test_bad_time_function_names_its_key(data, loc, words):
    where, message = _fault(TimeFunction, data)
    assert where == loc and words in message


# ---------------------------------------------------------------- the Ricker wavelet

def test_ricker_peaks_at_its_delay_with_value_one():
    f, t0 = 2.0, 0.6
    t = np.linspace(0.0, 2.0, 200_001)
    r = ricker(t, f, t0)
    assert t[np.argmax(r)] == pytest.approx(t0, abs=1e-5) and r.max() == pytest.approx(1.0, abs=1e-12)
    # r = d/dt[(t − t₀) exp(−τ²)]: zero mean over all t, so from t = 0 on its impulse is t₀ exp(−(π f t₀)²)
    assert np.trapezoid(r, t) == pytest.approx(t0 * np.exp(-(np.pi * f * t0) ** 2), rel=1e-6)


def test_ricker_spectrum_peaks_at_its_frequency():
    """|R(ν)| = (2/√π)(ν²/f³) exp(−ν²/f²), the continuous Fourier transform, peaks at ν = f: the
    sampled wavelet's discrete transform (dt ≪ 1/f, a window far beyond its support) matches it."""
    f, t0, dt, n = 2.0, 1.5, 1e-3, 2 ** 16                  # 65 s window, frequency step 0.015 Hz
    t = np.arange(n) * dt
    spectrum = np.abs(np.fft.rfft(ricker(t, f, t0))) * dt
    nu = np.fft.rfftfreq(n, dt)
    exact = 2 / np.sqrt(np.pi) * nu ** 2 / f ** 3 * np.exp(-nu ** 2 / f ** 2)
    assert np.max(np.abs(spectrum - exact)) < 1e-9
    k = np.argmax(spectrum)                                  # the peak, refined by the parabola through 3 bins
    a, b, c = spectrum[k - 1:k + 2]
    peak = nu[k] + 0.5 * (a - c) / (a - 2 * b + c) * (nu[1] - nu[0])
    assert peak == pytest.approx(f, rel=1e-3)


def test_ricker_must_start_from_rest():
    where, message = _fault(Source, {"point": [0.0, 0.0], "force": [1.0, 0.0],
                                     "wavelet": {"ricker": {"frequency": 2.0, "delay": 0.3}}})
    assert where == ("wavelet", "ricker") and "the delay 0.3 s is less than 1/frequency = 0.5 s" in message


@pytest.mark.parametrize("data, words", [
    ({"point": [0.0, 0.0], "wavelet": RICKER}, "exactly one of force, moment"),
    ({"point": [0.0, 0.0], "force": [1.0, 0.0, 0.0], "wavelet": RICKER}, "the force has 3 components, the point 2"),
    ({"point": [0.0, 0.0], "moment": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], "wavelet": RICKER}, "must be 2×2"),
])
def test_bad_source_says_what_is_wrong(data, words):
    assert words in _fault(Source, data)[1]


# ---------------------------------------------------------------- nodal loads of a point source

def _mesh(dim):
    """A skewed unstructured-looking mesh (nodes moved inside, boundary kept) of [0, 1]^dim."""
    x = np.linspace(0.0, 1.0, 5)
    m = skfem.MeshTri.init_tensor(x, x) if dim == 2 else skfem.MeshTet.init_tensor(x, x, x)
    p = m.p.copy()
    inner = np.all((p > 1e-9) & (p < 1 - 1e-9), axis=0)
    p[:, inner] += 0.06 * np.sin(7.0 * p[:, inner] + np.arange(dim)[:, None])
    return type(m)(p, m.t)


POINTS = {2: [[0.37, 0.61], [0.25, 0.5]], 3: [[0.37, 0.61, 0.44], [0.5, 0.5, 0.5]]}   # in a cell, on a face / node


@pytest.mark.parametrize("dim", [2, 3])
def test_point_force_sums_to_the_force_and_its_moment(dim):
    """Σ_a f_a = F and Σ_a x_a ⊗ f_a = x₀ ⊗ F: P1 reproduces 1 and x exactly."""
    m = _mesh(dim)
    F = np.array([3.0, -2.0, 5.0])[:dim]
    for x0 in map(np.array, POINTS[dim]):
        cells, bary = containing_cells(m.p, m.t, x0)
        f = point_force_vector(m.p, m.t, cells, bary, F).reshape(-1, dim)
        assert np.allclose(f.sum(axis=0), F, rtol=0, atol=1e-14)
        assert np.allclose(m.p @ f, np.outer(x0, F), rtol=0, atol=1e-14)


@pytest.mark.parametrize("dim", [2, 3])
def test_moment_tensor_forces_have_no_resultant_and_their_dipole_is_m(dim):
    """Σ_a f_a = 0, Σ_a f_a ⊗ x_a = M (f_a = M ∇φ_a(x₀)): an explosion M = M₀I pushes outward
    (Σ f_a·(x_a − x₀) = tr M > 0); the torque is the antisymmetric part (2D: M_yx − M_xy)."""
    m = _mesh(dim)
    M = np.arange(1.0, dim * dim + 1).reshape(dim, dim) + 3 * np.eye(dim)    # not symmetric: a torque
    for x0 in map(np.array, POINTS[dim]):
        cells, _ = containing_cells(m.p, m.t, x0)
        f = moment_tensor_vector(m.p, m.t, cells, M).reshape(-1, dim)
        assert np.allclose(f.sum(axis=0), 0.0, rtol=0, atol=1e-13)
        assert np.allclose(f.T @ m.p.T, M, rtol=0, atol=1e-13)
        explosion = moment_tensor_vector(m.p, m.t, cells, 2.0 * np.eye(dim)).reshape(-1, dim)
        assert np.sum(explosion * (m.p.T - x0)) == pytest.approx(2.0 * dim, rel=1e-13)
        if dim == 2:
            torque = np.sum(m.p[0] * f[:, 1] - m.p[1] * f[:, 0])
            assert torque == pytest.approx(M[1, 0] - M[0, 1], rel=1e-13)


def _two_bodies():
    """Two unit squares side by side, [0, 1]² (body a, with the hole (0.25, 0.75)²) and [1, 2] × [0, 1]
    (body b), each with its own nodes on x = 1 (as the mesher duplicates them)."""
    x = np.linspace(0.0, 1.0, 5)
    a, b = skfem.MeshTri.init_tensor(x, x), skfem.MeshTri.init_tensor(x + 1.0, x)
    p = np.hstack([a.p, b.p])
    t = np.hstack([a.t, b.t + a.p.shape[1]])
    body = np.repeat([0, 1], [a.t.shape[1], b.t.shape[1]])
    hole = np.flatnonzero(np.all(np.abs(a.p[:, a.t].mean(axis=1) - 0.5) < 0.25, axis=0))    # (0.25, 0.75)²
    keep = np.setdiff1d(np.arange(t.shape[1]), hole)
    return SceneMesh(skfem.MeshTri(p, t[:, keep]), ["a", "b"], [("a", "a"), ("b", "b")], body[keep], body[keep])


def test_source_in_a_body_loads_that_body():
    sm = _two_bodies()
    src = Source.model_validate({"point": [1.3, 0.4], "force": [0.0, 1e9], "wavelet": RICKER})
    f = source_vector(sm, src, "scene.sources.quake").reshape(-1, 2)
    assert f.sum(axis=0) == pytest.approx([0.0, 1e9], rel=1e-14)
    assert np.all(sm.node_body[np.flatnonzero(np.any(f != 0.0, axis=1))] == 1)


@pytest.mark.parametrize("point, words", [
    ([2.5, 0.5], "lies outside the mesh"),
    ([0.5, 0.55], "lies outside the mesh"),                  # in the hole
    ([1.0, 0.3], "on the interface of bodies a and b"),
    ([0.5, 0.5, 0.5], "the point has 3 coordinates, the scene is 2D"),
])
def test_source_point_that_is_no_place_in_one_body_is_refused(point, words):
    data = {"point": point, "force": [1.0] * len(point), "wavelet": RICKER}
    with pytest.raises(StudyError) as err:
        source_vector(_two_bodies(), Source.model_validate(data), "scene.sources.quake")
    assert err.value.path == "scene.sources.quake.point" and words in str(err.value)
