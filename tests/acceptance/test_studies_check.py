"""Every 2D study in studies/ passes `wcs check`; its contact sides pair up. (The 3D studies,
whose check solves ~1e5 unknowns, are checked in tests/acceptance/test_studies_3d.py, slow.)"""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from wcs.cli import main
from wcs.contact.pairs import pair_contact
from wcs.scene.mesher2d import build_mesh
from wcs.scene.spec import Material
from wcs import load_study

ALL = sorted((Path(__file__).resolve().parents[2] / "studies").glob("*.yaml"))
STUDIES = [p for p in ALL if yaml.safe_load(p.read_text(encoding="utf-8"))["scene"].get("dimension", 2) == 2]


def test_the_seed_scenes_are_there():
    names = {p.stem for p in ALL}
    assert {"tunnel-fault", "tunnel-thermal", "knee-replacement", "hip-replacement",
            "granite-crack", "user-mesh-demo"} <= names


@pytest.mark.parametrize("path", STUDIES, ids=[p.stem for p in STUDIES])
def test_check_passes(path, capsys):
    assert main(["check", str(path)]) == 0
    out = capsys.readouterr().out
    assert out.rstrip().endswith("ok")
    assert "nodes" in out


@pytest.mark.parametrize("path", STUDIES, ids=[p.stem for p in STUDIES])
def test_contacts_pair_and_meshes_are_moderate(path):
    study = load_study(path)
    sm = build_mesh(study.scene)
    assert sm.mesh.p.shape[1] <= 20_000
    for name, spec in study.scene.contacts.items():
        pairs = pair_contact(sm, spec, f"scene.contacts.{name}")
        assert pairs.slave.size >= 3, name
        assert (pairs.gap > -1e-9).all(), name          # no initial penetration


def test_seed_data_in_the_tunnel():
    study = load_study(STUDIES[0].with_name("tunnel-fault.yaml"))
    scene = study.scene
    assert scene.plane == "strain"
    assert scene.materials["rock"] == Material(E=5.2e9, nu=0.18, density_weight=2.45e4)
    assert scene.supports["right"].u[0] == -2.5e-2          # pushes 2.5 cm into the rock
    assert study.sweep.grid["supports.right.u.0"] == [-2.5e-2, -1.0e-1, -2.0e-1]
    assert {c.friction.slip_limit for c in scene.contacts.values()} == {1.0e6}
    assert any(e.points >= 6 for e in study.uncertain)


def test_knee_cut_angle_is_the_anchor():
    """The header's recipe: the two anchors define the cut; 5 deg here."""
    import math
    study = load_study(STUDIES[0].with_name("knee-replacement.yaml"))
    (x0, y0), (x1, y1) = study.scene.bodies["femur"].regions[0].shape.polygon[:2]
    assert math.degrees(math.atan2(y1 - y0, x1 - x0)) == pytest.approx(5.0, abs=1e-3)
