"""wcs: worst-scenario uncertainty quantification for contact problems of elastic bodies."""
from .errors import SolveError, StudyError

__version__ = "0.1.0"

__all__ = ["StudyError", "SolveError", "__version__"]
