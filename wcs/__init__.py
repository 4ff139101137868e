"""wcs: worst-scenario uncertainty quantification for contact problems of elastic bodies."""
from .errors import SolveError, StudyError

__version__ = "0.1.0"


def load_study(path):
    """Load and validate a study file (raises StudyError on bad input)."""
    from .study import load_study as _load
    return _load(path)


__all__ = ["StudyError", "SolveError", "load_study", "__version__"]
