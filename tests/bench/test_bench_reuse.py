"""Speed of the foundation at ~1e5 unknowns, as ratios measured in one run.

The first `evaluate` pays for meshing, assembly and the symbolic analysis;
a second one with other material values only combines the affine pieces and
refactors numerically, so it must be at least 5x faster. A benchmark: the
machine is shared, so only the ratio of two times taken in one run is asserted."""
import time
from pathlib import Path

import pytest
import yaml

import wcs

STUDIES = Path(__file__).resolve().parents[2] / "studies"


@pytest.mark.bench
def test_second_evaluation_reuses_assembly(tmp_path):
    doc = yaml.safe_load((STUDIES / "heated-plate.yaml").read_text())
    doc["scene"]["mesh"]["size"] = 0.0034          # ~1e5 displacement unknowns
    path = tmp_path / "big.yaml"
    path.write_text(yaml.safe_dump(doc))
    t0 = time.perf_counter()
    study = wcs.load_study(path)
    first = study.evaluate(study.nominal())
    t1 = time.perf_counter()
    x = study.nominal().copy()
    x[study.parameters.names.index("materials.steel.E")] *= 1.08
    x[study.parameters.names.index("materials.steel.nu")] = 0.27
    second = study.evaluate(x)
    t2 = time.perf_counter()
    unknowns = 2 * first.fields.sizes["node"]
    assert 0.9e5 <= unknowns <= 1.2e5, unknowns
    assert first.status == second.status == 0
    assert second.phi["heave"] != first.phi["heave"]
    ratio = (t1 - t0) / (t2 - t1)
    print(f"\n{unknowns} unknowns: first {t1 - t0:.2f} s, second {t2 - t1:.3f} s, ratio {ratio:.1f}")
    assert ratio >= 5.0, ratio
