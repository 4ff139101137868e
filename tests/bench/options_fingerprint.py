"""Nominal evaluations of four studies and four short DD runs (Aitken, fixed ω, on the demo
and a small Tresca pad), printed bitwise (float.hex, sha256 of u): run before and after a
change of the option handling and diff the outputs.

    PYTHONPATH=$PWD python tests/bench/options_fingerprint.py $PWD > after.txt
"""
import hashlib
import sys
from pathlib import Path

import numpy as np
import yaml

import wcs

root = Path(sys.argv[1])


def show(tag, ev):
    phi = {k: float(v).hex() for k, v in ev.phi.items()}
    u = hashlib.sha256(np.ascontiguousarray(ev.state.u).tobytes()).hexdigest()[:16] if ev.state is not None else None
    print(tag, ev.status.name, ev.iterations, phi, u, ev.message)


for name in ["two-blocks-demo", "validation/tresca-pad", "heated-plate", "validation/cooled-layer"]:
    path = root / "studies" / f"{name}.yaml"
    s = wcs.load_study(path)
    show(name, s.evaluate(s.nominal()))
# DD runs: two-blocks-demo with method dd (default dd options; thermal dd on cooled-layer), and anderson-free variants
for name, extra in [("two-blocks-demo", {"method": "dd"}), ("two-blocks-demo", {"method": "dd", "dd": {"relaxation": 1.0, "subdomains": 4}}),
                    ("validation/tresca-pad", {"method": "dd", "tolerance": 1e-10, "max_iterations": 300, "dd": {"subdomains": 8}}),
                    ("validation/tresca-pad", {"method": "dd", "dd": {"subdomains": 4, "relaxation": 1.0}})]:
    path = root / "studies" / f"{name}.yaml"
    doc = yaml.safe_load(path.read_text())
    doc["solver"] = {**doc.get("solver", {}), **extra}
    if "tresca" in name:
        doc["scene"]["mesh"] = {"size": 0.1, "refine": [{"box": [0.4, 0.9, 1.6, 1.1], "size": 0.05}]}
    s = wcs.load_study(doc, base_dir=path.parent)
    ev = s.evaluate(s.nominal())
    show(f"{name} dd {extra}", ev)
    print("   state", ev.state.solver if ev.state is not None else None)
