"""Two equal elastic bars in plane strain held by rollers on their long
sides (a 1D wave problem), the striker at v0 onto the target at rest, frictionless.

Reference (d'Alembert, nobody's code): with rollers the strain is uniaxial, σ_xx = (λ + 2μ) ε_xx,
so waves travel at the P-wave speed c = √((λ + 2μ)/ρ) = √(E(1 − ν)/(ρ(1 + ν)(1 − 2ν))). At the
impact each face takes the velocity v0/2 and a compression wave σ = ρ c v0/2 runs into each bar;
it reflects at the free ends as tension that releases the faces at t = 2L/c exactly, when the
striker is at rest and the target moves at v0 (the velocities exchanged), all energy kinetic.
"""
import numpy as np
import pytest

from wcs.dynamics.history import simulate
from wcs.dynamics.energy import body_velocities
from wcs.dynamics.mass import mass_operator
from wcs.model.evaluation import Evaluator
from wcs.study import load_study

E, NU, RHO, V0, L = 2.1e11, 0.3, 7850.0, 1.0, 1.0
C = float(np.sqrt(E * (1 - NU) / (RHO * (1 + NU) * (1 - 2 * NU))))       # 6001.3 m/s
DURATION = 2 * L / C                                                # 3.333e-4 s


def bars(h: float, dt: float, scheme: str, width: float = 0.04, end: float = 1.5 * DURATION) -> dict:
    """The study of the two bars (width `width`, mesh size h, time step dt)."""
    b = width
    seg = lambda body, a, z: {"body": body, "segment": [a, z]}     # noqa: E731
    return {
        "study": "two-bars",
        "dynamics": {"end_time": end, "time_step": dt, "scheme": scheme, "output_every": 100000,
                     "initial": {"velocity": {"striker": [V0, 0.0]}}},
        "scene": {
            "mesh": {"size": h},
            "materials": {"steel": {"E": E, "nu": NU, "density": RHO}},
            "bodies": {"striker": {"regions": [{"material": "steel", "shape": {"rectangle": [0.0, 0.0, L, b]}}]},
                       "target": {"regions": [{"material": "steel", "shape": {"rectangle": [L, 0.0, 2 * L, b]}}]}},
            "boundaries": {"s_bottom": seg("striker", [0.0, 0.0], [L, 0.0]), "s_top": seg("striker", [0.0, b], [L, b]),
                           "s_face": seg("striker", [L, 0.0], [L, b]),
                           "t_bottom": seg("target", [L, 0.0], [2 * L, 0.0]), "t_top": seg("target", [L, b], [2 * L, b]),
                           "t_face": seg("target", [L, 0.0], [L, b])},
            "supports": {k: {"normal": 0.0} for k in ("s_bottom", "s_top", "t_bottom", "t_top")},
            "contacts": {"impact": {"slave": "t_face", "master": "s_face"}},
            "regions_of_interest": {"face": {"boundary": "t_face"}},
        },
        "criteria": [{"name": "pressure", "kind": "contact_pressure", "regions": ["face"], "over_time": "max"}],
    }


def impact(study):
    """(contact duration, rebound velocities (striker, target) along x, force history, energies,
    history): the duration counts the levels that carry a contact force, each one step long."""
    ev = Evaluator(study)
    hist = simulate(ev, study.nominal())
    force = hist.total_force
    dt = study.dynamics.time_step
    duration = np.count_nonzero(force > 0) * dt
    M = mass_operator(ev.model)(np.full(len(ev.model.region_material), RHO))
    v = body_velocities(ev.model, M, hist.velocity[-1])[:, 0]
    energy = np.asarray(hist.kinetic) + np.asarray(hist.elastic)
    return duration, v, force, energy, hist


def test_stabilized_impact_matches_dalembert():
    """Contact duration and the exchange of velocities within 1 %, no tension, the energy after
    the impact within 1 % of the initial ½ m v0² (h = 0.02 m = L/50, Courant number c Δt/h = 0.6)."""
    study = load_study(bars(0.02, 2e-6, "stabilized"))
    duration, v, force, energy, hist = impact(study)
    width = 0.04
    assert energy[0] == pytest.approx(0.5 * RHO * L * width * V0**2, rel=1e-12)
    assert duration == pytest.approx(DURATION, rel=0.01)               # measured +0.2 %
    assert abs(v[0]) < 0.01 * V0 and v[1] == pytest.approx(V0, rel=0.01)   # measured 0.8 %
    assert force.min() >= 0.0                                          # never a tension
    assert energy[-1] == pytest.approx(energy[0], rel=0.01)            # measured −0.35 %
    assert energy[-1] <= energy[0] * (1 + 1e-12)                       # the projection never adds energy
    closed = force > 0
    # d'Alembert's contact force ρ c v0/2 · width during the contact: its mean over the contact
    # within 2 % (measured −1.0 % here, −2.1 % at h = L/25: first order in h, the P1 dispersion)
    assert force[closed].mean() == pytest.approx(RHO * C * V0 / 2 * width, rel=0.02)
    # the impulse of the contact is the momentum the target gained (a balance, to round-off)
    assert force[closed].sum() * study.dynamics.time_step == pytest.approx(RHO * L * width * v[1], rel=1e-9)


def test_seed_scheme_impact_loses_energy_but_keeps_the_contact_time():
    """[101, (10)] is backward Euler in the velocity: the contact time within 1 % of 2L/c, no
    tension, but it damps — the energy after the impact is below the stabilized scheme's and
    its loss is recorded as numerical dissipation (measured −14 % at h = L/25, Δt = 4e-6 s; −9.8 %
    at L/50, 2e-6 s)."""
    study = load_study(bars(0.04, 4e-6, "seed"))
    duration, v, force, energy, hist = impact(study)
    assert duration == pytest.approx(DURATION, rel=0.01)               # measured −0.4 %
    assert force.min() >= 0.0
    assert energy[-1] < 0.95 * energy[0]
    assert hist.numerical[-1] == pytest.approx(energy[0] - energy[-1], rel=1e-12)
    assert np.all(np.diff(energy) <= 1e-9 * energy[0])                 # dissipative at every level


def test_iterative_method_steps_the_same_impact():
    """Each level through the iterative method (PETSc CG, its own `solve_problem`) gives the
    monolithic levels to its tolerance (measured 1e-7 of the peak force)."""
    hists = {}
    for method in ("monolithic", "iterative"):
        doc = bars(0.05, 1e-5, "stabilized", width=0.05, end=DURATION / 4)
        doc["solver"] = {"method": method}
        study = load_study(doc)
        hists[method] = simulate(Evaluator(study))
    a, b = hists["monolithic"].total_force, hists["iterative"].total_force
    assert np.count_nonzero(a) == np.count_nonzero(b) > 0
    assert np.abs(a - b).max() <= 1e-5 * a.max()


@pytest.mark.slow
def test_stabilized_impact_converges_in_h():
    """At Courant number 0.6, h = L/50 → L/100: the rebound and energy errors fall (measured
    0.8 → 0.5 % and −0.35 → −0.17 %), the contact time stays within one step of 2L/c."""
    errors = []
    for h, dt in ((0.02, 2e-6), (0.01, 1e-6)):
        study = load_study(bars(h, dt, "stabilized"))
        duration, v, force, energy, _ = impact(study)
        assert abs(duration - DURATION) <= dt * (1 + 1e-9) + 1e-3 * DURATION
        errors.append((abs(v[0]) / V0, 1 - energy[-1] / energy[0]))
    assert errors[1][0] < errors[0][0] and 0 <= errors[1][1] < errors[0][1]


def test_viscous_impact_dissipates_exactly_what_the_stabilized_rule_loses():
    """Kelvin–Voigt bars (c⁽¹⁾ = η c⁽⁰⁾, η = 1e-6 s): during the contact the trapezoidal rule
    keeps kinetic + elastic + viscous dissipation equal to the initial energy to round-off
    (its viscous force is C Δ/τ, its dissipation τ (Δ/τ)ᵀ C (Δ/τ) ≥ 0), and never gains."""
    doc = bars(0.05, 1e-5, "stabilized", width=0.05, end=DURATION)
    doc["scene"]["materials"]["steel"]["viscosity"] = {"ratio": 1e-6}
    hist = simulate(Evaluator(load_study(doc)))
    e0 = hist.kinetic[0]
    closed = np.count_nonzero(hist.total_force > 0)
    energy = np.asarray(hist.kinetic) + np.asarray(hist.elastic)
    assert hist.viscous[closed] > 0.01 * e0                            # measured 5.5 %
    assert np.abs(hist.numerical[:closed]).max() <= 1e-10 * e0
    assert np.all(np.diff(energy) <= 1e-12 * e0)


def test_step_load_on_a_bar_moves_its_end_at_p_over_rho_c():
    """No contact (the levels' plain linear solves): a bar held at x = 0, a pressure P suddenly on
    its end x = L. d'Alembert: the end moves at P/(ρc) until the reflected wave is back at
    t = 2L/c; the stabilized rule keeps kinetic + elastic = the work of the load to round-off."""
    P, b = 1.0e6, 0.04
    seg = lambda a, z: {"segment": [a, z]}                         # noqa: E731
    doc = {"dynamics": {"end_time": 0.75 * DURATION, "time_step": 1e-6, "scheme": "stabilized",
                        "initial": "rest", "output_every": 1},
           "scene": {"mesh": {"size": 0.02}, "materials": {"s": {"E": E, "nu": NU, "density": RHO}},
                     "bodies": {"bar": {"regions": [{"material": "s", "shape": {"rectangle": [0.0, 0.0, L, b]}}]}},
                     "boundaries": {"left": seg([0.0, 0.0], [0.0, b]), "right": seg([L, 0.0], [L, b]),
                                    "top": seg([0.0, b], [L, b]), "bottom": seg([0.0, 0.0], [L, 0.0])},
                     "supports": {"left": {"u": [0.0, None]}, "top": {"normal": 0.0}, "bottom": {"normal": 0.0}},
                     "loads": {"right": {"pressure": P}}}}
    ev = Evaluator(load_study(doc))
    hist = simulate(ev)
    t = np.asarray(hist.time)
    end = np.flatnonzero(np.isclose(ev.smesh.mesh.p[0], L))
    ux = np.array([u[2 * end].mean() for u in hist.displacement])
    i, j = np.searchsorted(t, 0.45 * L / C), np.searchsorted(t, 0.9 * L / C)
    assert (ux[j] - ux[i]) / (t[j] - t[i]) == pytest.approx(-P / (RHO * C), rel=0.005)   # measured 0.06 %
    energy = np.asarray(hist.kinetic) + np.asarray(hist.elastic)
    assert energy == pytest.approx(np.asarray(hist.work), rel=1e-9, abs=1e-12 * energy.max())
