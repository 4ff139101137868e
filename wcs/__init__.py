"""wcs: worst-scenario uncertainty quantification for contact problems of elastic bodies."""
from .errors import SolveError, StudyError

__version__ = "0.1.0"


def load_study(path_or_mapping, base_dir=None):
    """Load and validate a study file or mapping (raises StudyError on bad input); see wcs.study.load_study."""
    from .study import load_study as _load
    return _load(path_or_mapping, base_dir)


def run(study, output=None, resume=False, progress=None, **kwargs):
    """The whole worst-scenario study -> xarray.Dataset (study-format.md §3, §4); see wcs.runner.run."""
    from .runner import run as _run
    return _run(study, output=output, resume=resume, progress=progress, **kwargs)


__all__ = ["StudyError", "SolveError", "load_study", "run", "__version__"]
