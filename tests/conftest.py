import pytest

from wcs.linalg import configure_threads

LONG = 1800     # s: slow validations and benchmarks on a loaded machine; the default suite keeps 300 s


def pytest_collection_modifyitems(items):
    for item in items:
        if item.get_closest_marker("timeout") is None and (
                item.get_closest_marker("slow") or item.get_closest_marker("bench")):
            item.add_marker(pytest.mark.timeout(LONG))


def pytest_configure(config):
    """The process edge of the test session: one BLAS thread, as `wcs` sets for itself."""
    configure_threads()
