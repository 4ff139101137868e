"""Study files: load and validate them, and address the numbers of a scene by dotted path.

`load_study(path_or_mapping)` reads a study file, or takes the mapping YAML would
parse one into, checks it with typed models and cross-reference rules, and
returns a frozen `Study` whose `scene` is the frozen `wcs.scene.spec.Scene`, resolved:
scene and material files inlined, region names and defaults filled in. The criteria,
the sweep and the uncertain entries are frozen objects too: nothing downstream of
loading reads a dict. The `Study` is plain data: it builds and solves nothing (the
evaluator is built by whoever runs the study, `wcs.app`).
Every bad input raises `StudyError` naming the file (`<mapping>` for a mapping),
the dotted key path and the fault.

A file a study names (scene, material library, mesh) is found relative to the
folder of the file that names it; the study's own names relative to `base_dir`
when given (the current directory for a mapping). A material library not found
there is looked up among the libraries shipped in the package (`configs/`, `wcs/configs/` installed).
A study's `include:` names preset files whose keys it takes unless it sets them itself
(`includes`: relative to the study's folder, then among the shipped configs).

The modules, in the order the loader uses them: `source` (reading YAML, where a piece of
input lives), `schema` (the typed models), `scene` (the scene resolved and its references
checked), `resources` (mesh size and cost), `paths` (dotted paths and what can vary),
`uncertain` (uncertain data, sweep, the parameter vector), `criteria` (criteria and limits),
`fuzzy` (α-levels and cuts), `study` (the `Study`), `data` (a data set applied: vector or
mapping -> parameter vector) and `load` (`load_study`, `load_scene`).
"""
from .load import load_scene, load_study
from .study import Study

__all__ = ["Study", "load_scene", "load_study"]
