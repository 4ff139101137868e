import matplotlib

matplotlib.use("Agg")


def pytest_sessionfinish(session, exitstatus):
    """A session that ran benchmarks (`make bench`) ends by writing docs/benchmarks.md from
    their tables (tests/bench/page.py); the default suite, which deselects them, does not."""
    if any(item.get_closest_marker("bench") for item in session.items):
        from page import write
        print(f"\nbenchmarks page: {write()}")
