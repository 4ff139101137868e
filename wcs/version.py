"""The version of wcs (the one pyproject.toml states), which every results file records."""
__version__ = "0.1.0"
