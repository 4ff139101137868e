"""Friction in time: a block sliding on a fixed base under Tresca friction g decelerates at
g·ℓ/m (ℓ the contact length, m the block's mass per unit thickness) while all its contact nodes
slip — the balance of momentum, independent of the scheme: M(v_{n+1} − v_n) sums over the
block to −τ Σ λt, internal forces cancelling, and Σ |λt| = g Σ w = g ℓ on slipping nodes."""
import numpy as np
import pytest

from wcs.dynamics.history import simulate
from wcs.dynamics.energy import body_velocities
from wcs.dynamics.mass import mass_operator
from wcs.model.evaluation import Evaluator
from wcs.study import load_study

RHO, G, V0 = 1000.0, 1.0e4, 1.0           # block 1 m × 0.2 m: m = 200 kg/m, a = G·1 m / m = 50 m/s²


def sliding(scheme: str) -> dict:
    seg = lambda body, a, z: {"body": body, "segment": [a, z]}     # noqa: E731
    return {
        "dynamics": {"end_time": 0.01, "time_step": 5e-4, "scheme": scheme, "output_every": 1,
                     "initial": {"velocity": {"block": [V0, 0.0]}}},
        "scene": {
            "mesh": {"size": 0.1},
            "materials": {"m": {"E": 1.0e9, "nu": 0.3, "density": RHO}},
            "bodies": {"block": {"regions": [{"material": "m", "shape": {"rectangle": [0.0, 0.0, 1.0, 0.2]}}]},
                       "base": {"regions": [{"material": "m", "shape": {"rectangle": [-0.5, -0.3, 2.0, 0.0]}}]}},
            "boundaries": {"block_bottom": seg("block", [0.0, 0.0], [1.0, 0.0]),
                           "base_top": seg("base", [-0.5, 0.0], [2.0, 0.0]),
                           "base_bottom": seg("base", [-0.5, -0.3], [2.0, -0.3])},
            "supports": {"base_bottom": {"u": [0.0, 0.0]}},
            "contacts": {"slide": {"slave": "block_bottom", "master": "base_top", "friction": {"slip_limit": G}}},
        },
    }


@pytest.mark.parametrize("scheme", ["seed", "stabilized"])
def test_tresca_sliding_block_loses_momentum_at_the_friction_force(scheme):
    study = load_study(sliding(scheme))
    ev = Evaluator(study)
    hist = simulate(ev)
    M = mass_operator(ev.model)(np.full(len(ev.model.region_material), RHO))
    block = ev.model.smesh.bodies.index("block")
    v = np.array([body_velocities(ev.model, M, vel)[block, 0] for vel in hist.velocity])
    t = np.asarray(hist.time)
    a = G * 1.0 / (RHO * 0.2)
    # the block's mean velocity falls as v0 − a t while it slides (t ≤ 0.01 s < v0/a = 0.02 s)
    assert v == pytest.approx(V0 - a * t, rel=1e-6, abs=1e-9)
    # friction takes work from the bodies at every level, and the balance closes
    assert np.all(np.diff(hist.friction) > 0)
    drop = hist.kinetic[0] - (hist.kinetic[-1] + hist.elastic[-1])
    assert hist.friction[-1] + hist.numerical[-1] == pytest.approx(drop, rel=1e-9)


@pytest.mark.parametrize("scheme", ["seed", "stabilized"])
def test_coulomb_takes_its_slip_limit_from_the_previous_level(scheme):
    """Coulomb friction F in slip rates with the limit F·p of the previous level ([101, §3]):
    the block pressed by a pressure on its top, sliding, has |λt,i| = F λn,i of the level
    before at every node it slides on, never more."""
    F = 0.3
    doc = sliding(scheme)
    doc["dynamics"]["end_time"] = 0.004
    doc["scene"]["boundaries"]["block_top"] = {"body": "block", "segment": [[0.0, 0.2], [1.0, 0.2]]}
    doc["scene"]["loads"] = {"block_top": {"pressure": 1.0e5}}
    doc["scene"]["contacts"]["slide"]["friction"] = {"coefficient": F}
    hist = simulate(Evaluator(load_study(doc)))
    lam_n, lam_t = np.array(hist.force_n), np.abs(np.array(hist.force_t))
    assert lam_n[1:].sum() > 0
    assert np.all(lam_t[1:] <= F * lam_n[:-1] * (1 + 1e-9) + 1e-9 * lam_n.max())
    assert lam_t[1:].sum() == pytest.approx(F * lam_n[:-1].sum(), rel=1e-9)     # all slide: v0 − a t > 0
