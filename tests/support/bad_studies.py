"""Broken variants of the demo study, one broken rule each.

`CASES` is a list of `(id, mutate, expected_path_fragment)`: `mutate(doc)` edits a
deep copy of the parsed demo study in place; the loader's error message must
contain `expected_path_fragment` (the dotted key path of the fault). Importing
this module has no side effects; use `demo_doc()` and `write_study()`.
"""
import copy
import math
from pathlib import Path

import yaml

DEMO = Path(__file__).resolve().parents[2] / "studies" / "two-blocks-demo.yaml"


def demo_doc() -> dict:
    """The parsed demo study (a fresh copy each call)."""
    return yaml.safe_load(DEMO.read_text(encoding="utf-8"))


def write_study(doc: dict, directory: Path, name: str = "study.yaml") -> Path:
    path = Path(directory) / name
    path.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    return path


def broken(mutate) -> dict:
    """The demo study with `mutate` applied."""
    doc = demo_doc()
    mutate(doc)
    return doc


def _parent(doc, keys):
    for key in keys[:-1]:
        doc = doc[key]
    return doc


def put(keys, value):
    """Set the value at a key list (keys may contain dots, e.g. uncertain paths)."""
    def mutate(doc):
        _parent(doc, keys)[keys[-1]] = copy.deepcopy(value)
    return mutate


def drop(keys):
    def mutate(doc):
        del _parent(doc, keys)[keys[-1]]
    return mutate


def rename(keys, new_key):
    def mutate(doc):
        parent = _parent(doc, keys)
        parent[new_key] = parent.pop(keys[-1])
    return mutate


def both(*mutations):
    """Several edits that together break one rule."""
    def mutate(doc):
        for m in mutations:
            m(doc)
    return mutate


SCENE = ["scene"]
STEEL = SCENE + ["materials", "steel"]
BASE_REGION = SCENE + ["bodies", "base", "regions", 0]
PAD_REGION = SCENE + ["bodies", "pad", "regions", 0]
SLIP = "contacts.interface.friction.slip_limit"
PROFILE = {"range": [0.5e5, 1.5e5], "lipschitz": 2.0e5, "points": 6}

CASES = [
    # file structure and unknown keys
    ("unknown-top-key", rename(["search"], "serach"), "serach"),
    ("unknown-region-key", rename(PAD_REGION + ["material"], "materal"),
     "scene.bodies.pad.regions.0.materal"),
    ("unknown-shape-key", put(BASE_REGION + ["shape"], {"square": [0, 0, 1, 1]}),
     "scene.bodies.base.regions.0.shape.square"),
    ("scene-missing", drop(["scene"]), "scene"),
    ("scene-not-mapping", put(["scene"], 3), "scene"),
    ("scene-file-missing", put(["scene"], "no-such-scene.yaml"), "scene"),
    ("materials-file-missing", put(SCENE + ["materials"], "no-such-library.yaml"), "scene.materials"),
    ("name-with-dot", rename(STEEL, "steel.v2"), "scene.materials.steel.v2"),
    # scene header and mesh
    ("dimension-4", put(SCENE + ["dimension"], 4), "scene.dimension"),
    ("plane-unknown", put(SCENE + ["plane"], "axisymmetric"), "scene.plane"),
    ("mesh-size-zero", put(SCENE + ["mesh", "size"], 0.0), "scene.mesh.size"),
    ("refine-size-missing", drop(SCENE + ["mesh", "refine", 0, "size"]), "scene.mesh.refine.0.size"),
    ("refine-unknown-boundary", put(SCENE + ["mesh", "refine", 0], {"boundary": "top", "size": 0.01}),
     "scene.mesh.refine.0.boundary"),
    # materials
    ("material-E-negative", put(STEEL + ["E"], -2.1e11), "scene.materials.steel.E"),
    ("material-nu-half", put(STEEL + ["nu"], 0.5), "scene.materials.steel.nu"),
    ("material-both-pairs", put(STEEL + ["lambda"], 1.0e11), "scene.materials.steel"),
    ("material-nu-missing", drop(STEEL + ["nu"]), "scene.materials.steel"),
    ("material-lame-bulk", put(STEEL, {"lambda": -2.0e9, "mu": 1.0e9, "conductivity": 45.0}),
     "scene.materials.steel"),
    # nu = lambda / (2 (lambda + mu)) = -2: lambda + mu > 0 but 3 lambda + 2 mu < 0 (indefinite)
    ("material-lame-nu-minus-two", put(STEEL, {"lambda": -0.8e9, "mu": 1.0e9, "conductivity": 45.0}),
     "scene.materials.steel"),
    ("material-lame-nu-minus-1.1", put(STEEL, {"lambda": -0.6875e9, "mu": 1.0e9, "conductivity": 45.0}),
     "scene.materials.steel"),
    ("material-conductivity-zero", put(STEEL + ["conductivity"], 0.0), "scene.materials.steel.conductivity"),
    ("material-expansion-inf", put(STEEL + ["expansion"], float("inf")), "scene.materials.steel.expansion"),
    ("material-density-negative", put(STEEL + ["density_weight"], -1.0), "scene.materials.steel.density_weight"),
    ("material-E-string", put(STEEL + ["E"], "stiff"), "scene.materials.steel.E"),
    # bodies, regions, shapes
    ("region-material-unknown", put(PAD_REGION + ["material"], "gum"), "scene.bodies.pad.regions.0.material"),
    ("bodies-empty", put(SCENE + ["bodies"], {}), "scene.bodies"),
    ("body-no-regions", put(SCENE + ["bodies", "pad", "regions"], []), "scene.bodies.pad.regions"),
    ("region-name-twice", put(PAD_REGION + ["name"], "base_0"), "scene.bodies.pad.regions.0.name"),
    ("region-name-is-other-body", put(PAD_REGION + ["name"], "base"), "scene.bodies.pad.regions.0.name"),
    ("rectangle-inverted", put(BASE_REGION + ["shape", "rectangle"], [2.0, 0.0, 0.0, 1.0]),
     "scene.bodies.base.regions.0.shape.rectangle"),
    ("shape-two-primitives", put(BASE_REGION + ["shape", "disc"], {"center": [1.0, 0.5], "radius": 0.2}),
     "scene.bodies.base.regions.0.shape"),
    ("polygon-two-points", put(BASE_REGION + ["shape"], {"polygon": [[0, 0], [2, 0]]}),
     "scene.bodies.base.regions.0.shape.polygon"),
    ("polygon-no-area", put(BASE_REGION + ["shape"], {"polygon": [[0, 0], [1, 0], [2, 0]]}),
     "scene.bodies.base.regions.0.shape.polygon"),
    ("disc-radius-negative", put(BASE_REGION + ["shape"], {"disc": {"center": [1, 0.5], "radius": -1}}),
     "scene.bodies.base.regions.0.shape.disc.radius"),
    ("minus-bad-disc", put(BASE_REGION + ["shape", "minus"], [{"disc": {"center": [1, 0.5], "radius": 0}}]),
     "scene.bodies.base.regions.0.shape.minus.0.disc.radius"),
    # boundaries and conditions
    ("boundary-body-unknown", put(SCENE + ["boundaries", "pad_top", "body"], "padd"),
     "scene.boundaries.pad_top.body"),
    ("boundary-two-selectors", put(SCENE + ["boundaries", "pad_top", "box"], [0, 0, 1, 1]),
     "scene.boundaries.pad_top"),
    ("boundary-segment-point", put(SCENE + ["boundaries", "pad_top", "segment"], [[1, 1], [1, 1]]),
     "scene.boundaries.pad_top.segment"),
    ("support-boundary-unknown", rename(SCENE + ["supports", "base_bottom"], "base_botom"),
     "scene.supports.base_botom"),
    ("support-holds-nothing", put(SCENE + ["supports", "base_bottom", "u"], [None, None]),
     "scene.supports.base_bottom"),
    ("support-two-kinds", put(SCENE + ["supports", "pad_left", "u"], [0.0, None]), "scene.supports.pad_left"),
    ("load-boundary-unknown", rename(SCENE + ["loads", "pad_top"], "pad_roof"), "scene.loads.pad_roof"),
    ("load-two-kinds", put(SCENE + ["loads", "pad_top", "traction"], [0.0, -1.0]), "scene.loads.pad_top"),
    ("body-force-unknown-body", rename(SCENE + ["body_forces", "base"], "bse"), "scene.body_forces.bse"),
    ("body-force-three-components", put(SCENE + ["body_forces", "base"], [0, 0, 1]), "scene.body_forces.base"),
    ("contact-slave-unknown", put(SCENE + ["contacts", "interface", "slave"], "pad_under"),
     "scene.contacts.interface.slave"),
    ("contact-master-unknown", put(SCENE + ["contacts", "interface", "master"], "base_up"),
     "scene.contacts.interface.master"),
    ("contact-same-body", put(SCENE + ["contacts", "interface", "master"], "pad_left"),
     "scene.contacts.interface.master"),
    ("friction-slip-negative", put(SCENE + ["contacts", "interface", "friction", "slip_limit"], -1.0),
     "scene.contacts.interface.friction.slip_limit"),
    ("friction-two-laws", put(SCENE + ["contacts", "interface", "friction", "coefficient"], 0.3),
     "scene.contacts.interface.friction"),
    ("thermal-temperature-unknown-boundary", rename(SCENE + ["thermal", "temperature", "base_bottom"], "floor"),
     "scene.thermal.temperature.floor"),
    ("thermal-source-unknown-body", rename(SCENE + ["thermal", "sources", "pad"], "pud"),
     "scene.thermal.sources.pud"),
    ("thermal-needs-conductivity", drop(STEEL + ["conductivity"]), "scene.materials.steel"),
    ("thermal-reference-negative", put(SCENE + ["thermal", "reference"], -20.0), "scene.thermal.reference"),
    ("thermal-no-fixed-temperature", put(SCENE + ["thermal", "temperature"], {}), "scene.thermal.temperature"),
    ("roi-boundary-unknown", put(SCENE + ["regions_of_interest", "pad_edge", "boundary"], "pad_right"),
     "scene.regions_of_interest.pad_edge.boundary"),
    ("roi-body-unknown", put(SCENE + ["regions_of_interest", "pad_edge", "body"], "lid"),
     "scene.regions_of_interest.pad_edge.body"),
    ("roi-box-flat", put(SCENE + ["regions_of_interest", "under_pad", "box"], [0.9, 1.0, 1.1, 1.0]),
     "scene.regions_of_interest.under_pad.box"),
    # uncertain data
    ("uncertain-lower-above-upper", put(["uncertain", "materials.rubber.E"], [1.2e7, 0.8e7]),
     "uncertain.materials.rubber.E"),
    ("uncertain-nan", put(["uncertain", "materials.rubber.nu"], [float("nan"), 0.48]),
     "uncertain.materials.rubber.nu"),
    ("uncertain-nominal-outside", put(["uncertain", "loads.pad_top.pressure"], [2.5e6, 3.0e6]),
     "uncertain.loads.pad_top.pressure"),
    ("uncertain-nu-unphysical", put(["uncertain", "materials.rubber.nu"], [0.4, 0.6]),
     "uncertain.materials.rubber.nu"),
    ("uncertain-E-unphysical", put(["uncertain", "materials.rubber.E"], [-1.0, 1.2e7]),
     "uncertain.materials.rubber.E"),
    ("uncertain-path-not-addressable", put(["uncertain", "materials.rubber.G"], [1.0, 2.0]),
     "uncertain.materials.rubber.G"),
    ("uncertain-geometry-path", put(["uncertain", "mesh.size"], [0.04, 0.06]), "uncertain.mesh.size"),
    ("uncertain-material-unknown", put(["uncertain", "materials.gum.E"], [1.0, 2.0]),
     "uncertain.materials.gum.E"),
    ("uncertain-absent-number", put(["uncertain", "materials.steel.density_weight"], [0.0, 1.0]),
     "uncertain.materials.steel.density_weight"),
    ("uncertain-null-component", both(put(SCENE + ["supports", "base_bottom", "u"], [None, 0.0]),
                                      put(["uncertain", "supports.base_bottom.u.0"], [-1e-3, 1e-3])),
     "uncertain.supports.base_bottom.u.0"),
    ("uncertain-E-on-lame-material", put(SCENE + ["materials", "rubber"],
                                         {"lambda": 3.1e7, "mu": 3.4e6, "conductivity": 0.2}),
     "uncertain.materials.rubber.E"),
    ("uncertain-lame-bulk", both(put(STEEL, {"lambda": 1.0e9, "mu": 1.0e9, "conductivity": 45.0}),
                                 put(["uncertain", "materials.steel.lambda"], [-1.5e9, 2.0e9])),
     "uncertain.materials.steel.lambda"),
    # the lowest corner lambda = -0.7e9, mu = 1e9: lambda + mu > 0, 3 lambda + 2 mu = -1e8
    ("uncertain-lame-corner-indefinite", both(put(STEEL, {"lambda": 1.0e9, "mu": 1.0e9, "conductivity": 45.0}),
                                              put(["uncertain", "materials.steel.lambda"], [-0.7e9, 2.0e9])),
     "uncertain.materials.steel.lambda"),
    ("uncertain-lame-fuzzy-support-indefinite",
     both(put(STEEL, {"lambda": 1.0e9, "mu": 1.0e9, "conductivity": 45.0}),
          put(["uncertain", "materials.steel.lambda"], {"support": [-0.7e9, 2.0e9], "core": [1.0e9, 1.0e9]})),
     "uncertain.materials.steel.lambda"),
    # lambda + mu > 0 at every grid value, 3 lambda + 2 mu = -1e8 at -0.7e9 with mu = 1e9
    ("sweep-lame-indefinite", both(put(STEEL, {"lambda": 1.0e9, "mu": 1.0e9, "conductivity": 45.0}),
                                   put(["sweep"], {"grid": {"materials.steel.lambda": [1.0e9, -0.7e9]}})),
     "sweep.grid.materials.steel.lambda"),
    ("uncertain-lipschitz-not-friction", put(["uncertain", "loads.pad_top.pressure"],
                                             dict(PROFILE, range=[1.5e6, 2.5e6])),
     "uncertain.loads.pad_top.pressure"),
    ("uncertain-lipschitz-one-point", put(["uncertain", SLIP, "points"], 1),
     f"uncertain.{SLIP}.points"),
    ("uncertain-lipschitz-negative", put(["uncertain", SLIP, "lipschitz"], -2.0e5),
     f"uncertain.{SLIP}.lipschitz"),
    ("uncertain-lipschitz-unknown-key", put(["uncertain", SLIP, "slope"], 1.0), f"uncertain.{SLIP}.slope"),
    ("uncertain-slip-negative", put(["uncertain", SLIP, "range"], [-1.0e5, 1.5e5]), f"uncertain.{SLIP}"),
    ("uncertain-not-a-box", put(["uncertain", "loads.pad_top.pressure"], "wide"),
     "uncertain.loads.pad_top.pressure"),
    ("uncertain-three-numbers", put(["uncertain", "loads.pad_top.pressure"], [1.5e6, 2.0e6, 2.5e6]),
     "uncertain.loads.pad_top.pressure"),
    # criteria and limits
    ("criterion-roi-unknown", put(["criteria", 0, "regions"], ["under_the_pad"]), "criteria.0.regions.0"),
    ("criterion-kind-unknown", put(["criteria", 1, "kind"], "tresca"), "criteria.1.kind"),
    ("criterion-name-twice", put(["criteria", 1, "name"], "settlement"), "criteria.1.name"),
    ("criterion-no-regions", put(["criteria", 1, "regions"], []), "criteria.1.regions"),
    ("criterion-point-on-shear", put(["criteria", 1, "point"], [1.0, 1.0]), "criteria.1"),
    ("criterion-direction-zero", put(["criteria", 0, "direction"], [0.0, 0.0]), "criteria.0.direction"),
    ("mean-temperature-without-thermal", both(drop(SCENE + ["thermal"]),
                                              put(["criteria", 1, "kind"], "mean_temperature")),
     "criteria.1.kind"),
    ("contact-pressure-without-contact", both(drop(SCENE + ["contacts"]), drop(["uncertain", SLIP]),
                                              put(["criteria", 1, "kind"], "contact_pressure")),
     "criteria.1.kind"),
    ("limit-criterion-unknown", rename(["limits", "shear"], "sheer"), "limits.sheer"),
    ("limit-not-number", put(["limits", "shear"], "high"), "limits.shear"),
    # search, solver, sweep, output
    ("search-method-unknown", put(["search", "method"], "exhaustive"), "search.method"),
    ("search-design-unknown", put(["search", "sample", "design"], "random"), "search.sample.design"),
    ("search-budget-zero", put(["search", "budget"], 0), "search.budget"),
    ("search-n-zero", put(["search", "sample", "n"], 0), "search.sample.n"),
    ("search-n-float", put(["search", "sample", "n"], 32.5), "search.sample.n"),
    ("search-local-unknown-key", put(["search", "local"], {"strats": 3}), "search.local.strats"),
    ("solver-method-unknown", put(["solver", "method"], "newton"), "solver.method"),
    ("solver-tolerance-zero", put(["solver", "tolerance"], 0.0), "solver.tolerance"),
    ("solver-subdomains-zero", put(["solver", "dd", "subdomains"], 0), "solver.dd.subdomains"),
    ("solver-fallback-not-bool", put(["solver", "fallback"], "yes"), "solver.fallback"),
    ("sweep-path-unknown", put(["sweep"], {"grid": {"materials.rubber.G": [1.0]}}), "sweep.grid.materials.rubber.G"),
    ("sweep-value-unphysical", put(["sweep"], {"grid": {"materials.rubber.nu": [0.3, 0.6]}}),
     "sweep.grid.materials.rubber.nu"),
    ("sweep-empty-list", put(["sweep"], {"grid": {"loads.pad_top.pressure": []}}),
     "sweep.grid.loads.pad_top.pressure"),
    ("output-not-string", put(["output"], 42), "output"),
    # ranges that keep a run meaningful, the resource guard, degenerate geometry
    ("material-E-tiny", put(STEEL + ["E"], 1e-300), "scene.materials.steel.E"),
    ("material-E-huge", put(STEEL + ["E"], 1e300), "scene.materials.steel.E"),
    ("uncertain-E-huge", put(["uncertain", "materials.rubber.E"], [0.8e7, 1e300]), "uncertain.materials.rubber.E"),
    ("material-expansion-huge", put(STEEL + ["expansion"], 2.0**70), "scene.materials.steel.expansion"),
    ("load-pressure-huge", put(SCENE + ["loads", "pad_top", "pressure"], 1e300), "scene.loads.pad_top.pressure"),
    ("solver-tolerance-ten", put(["solver", "tolerance"], 10.0), "solver.tolerance"),
    ("search-budget-huge", put(["search", "budget"], 10**30), "search.budget"),
    ("search-budget-float", put(["search", "budget"], 1e30), "search.budget"),
    ("mesh-size-beyond-scene", put(SCENE + ["mesh", "size"], 10.0), "scene.mesh.size"),
    ("mesh-size-below-kernel", put(SCENE + ["mesh", "size"], 1e-7), "scene.mesh.size"),
    ("mesh-size-guard", put(SCENE + ["mesh", "size"], 1e-5), "scene.mesh.size"),
    ("refine-size-guard", put(SCENE + ["mesh", "refine", 0, "size"], 1e-6), "scene.mesh.refine.0.size"),
    ("mesh-max-cells-low", put(SCENE + ["mesh", "max_cells"], 100), "scene.mesh"),
    ("uncertain-lipschitz-points-huge", put(["uncertain", SLIP, "points"], 10**7), f"uncertain.{SLIP}.points"),
    ("polygon-repeated-vertex", put(BASE_REGION + ["shape"], {"polygon": [[0, 0], [2, 0], [2, 0], [2, 1], [0, 1]]}),
     "scene.bodies.base.regions.0.shape.polygon"),
    ("polygon-self-intersecting", put(BASE_REGION + ["shape"], {"polygon": [[0, 0], [2, 1], [2, 0], [0, 1]]}),
     "scene.bodies.base.regions.0.shape.polygon"),
    ("rectangle-nanometre", put(BASE_REGION + ["shape", "rectangle"], [0.0, 0.0, 1e-9, 1e-9]),
     "scene.bodies.base.regions.0.shape.rectangle"),
    ("coordinate-huge", put(BASE_REGION + ["shape", "rectangle"], [0.0, 0.0, 1e308, 1.0]),
     "scene.bodies.base.regions.0.shape.rectangle.2"),
    ("segment-coordinate-huge", put(SCENE + ["boundaries", "pad_top", "segment"], [[0.5, 1.5], [1e300, 1.5]]),
     "scene.boundaries.pad_top.segment.1.0"),
    # inputs that crashed, hung or blew up memory after passing `check`
    ("study-name-too-long", put(["study"], "s" * 100_000), "study: a name has at most 100 characters, got 100000"),
    ("study-name-lone-surrogate", put(["study"], "demo\ud800"), "study: a name may contain printable characters only"),
    ("region-name-nul", put(PAD_REGION + ["name"], "pa\x00d"), "scene.bodies.pad.regions.0.name: a name may contain "
     "printable characters only, got '\\x00' at position 2"),
    ("body-name-nul", rename(SCENE + ["bodies", "pad"], "pa\x00d"), "scene.bodies.pa\\x00d: a name may contain"),
    ("criterion-name-control", put(["criteria", 0, "name"], "settle\x1bment"), "criteria.0.name"),
    ("sweep-grid-1e18-points", put(["sweep"], {"grid": {
        "materials.rubber.E": [1e7 + k for k in range(1000)], "materials.rubber.nu": [0.3 + 1e-4 * k for k in range(1000)],
        "materials.steel.E": [2e11 + k for k in range(1000)], "materials.steel.nu": [0.2 + 1e-4 * k for k in range(1000)],
        "loads.pad_top.pressure": [1e6 + k for k in range(1000)], "body_forces.base.1": [-k for k in range(1000)]}}),
     "sweep.grid: the grid has 1e+18 points, more than 1000000 solves"),
    ("polygon-too-many-vertices", put(BASE_REGION + ["shape"], {"polygon": [
        [1 + math.cos(2 * math.pi * k / 1001), 0.5 + 0.5 * math.sin(2 * math.pi * k / 1001)] for k in range(1001)]}),
     "scene.bodies.base.regions.0.shape.polygon: must have at most 1000 items"),
    ("shapes-beyond-cap", put(BASE_REGION + ["shape"], {"rectangle": [0.0, 0.0, 2.0, 1.0], "minus": [
        {"rectangle": [0.05 + 0.048 * (k % 40), 0.05 + 0.03 * (k // 40), 0.06 + 0.048 * (k % 40), 0.06 + 0.03 * (k // 40)]}
        for k in range(1000)]}), "scene.bodies.base.regions.0.shape: the scene's shapes number more than 1000"),
    ("support-unknown-long-name", put(SCENE + ["supports", "b" * 100_000], {"u": [0.0, 0.0]}),
     f"scene.supports.{'b' * 100}... (100000 characters): unknown boundary '{'b' * 100}... (100000 characters)'"),
    ("output-nul", put(["output"], "results/demo\x00.nc"), "output: the output name holds a NUL character"),
    ("output-lone-surrogate", put(["output"], "results/demo\ud800.nc"), "output: the output name holds '\\ud800'"),
    ("solver-tolerance-below-rounding", put(["solver", "tolerance"], 1e-300), "solver.tolerance: a relative tolerance "
     "below 1e-14"),
    ("dd-contact-tolerance-below-rounding", put(["solver", "dd", "contact_tolerance"], 1e-20),
     "solver.dd.contact_tolerance"),
]
