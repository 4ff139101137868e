"""The scaling model's arithmetic (tests/bench/scaling_model.py, docs/scaling.md): on one rank
at the measured size it gives the measurement back; weak scaling keeps the local work; the
iterations' growth and the messages add what they say."""
import math
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

import scaling_model as model  # noqa: E402

MEASURED = {"rows": 0.1, "eliminate": 1.5, "matrix": 3.0, "rest": 4.0, "gamg_setup": 16.0, "cg": 17.0,
            "solvability": 0.2}


def test_one_rank_at_the_measured_size_is_the_measurement():
    out = model.predict(MEASURED, 200_000, 100, 200_000, 1, 0.25)
    assert out == pytest.approx({**MEASURED, "communication": 0.0}, rel=1e-15)


def test_weak_scaling_keeps_the_local_work_and_grows_the_multigrid_by_its_log():
    n, p = 1e8, 512
    flat, log = (model.predict(MEASURED, 200_000, 100, n, p, c) for c in (0.0, 0.25))
    share = n / p / 200_000
    assert flat["matrix"] == pytest.approx(3.0 * share) and log["matrix"] == flat["matrix"]
    assert log["cg"] / flat["cg"] == pytest.approx(1 + 0.25 * math.log(n / 200_000))
    assert log["communication"] / flat["communication"] == pytest.approx(1 + 0.25 * math.log(n / 200_000))
    assert 0 < flat["communication"] < 0.01 * flat["cg"]      # messages: small beside the work a rank
