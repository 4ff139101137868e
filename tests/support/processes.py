"""Waiting on a `wcs run` started as a subprocess (to kill it midway)."""
import time

import pytest

from wcs.results.store import store_path


def wait_until(proc, ready, seconds: float = 240.0, poll: float = 0.01) -> bool:
    """Whether `ready()` came true while the process `proc` ran, polled until it does, the process
    ends or `seconds` pass (generous: a loaded machine is slow, not wrong — no speed is asserted)."""
    deadline = time.time() + seconds
    while time.time() < deadline and proc.poll() is None:
        if ready():
            return True
        time.sleep(poll)
    return False


def wait_for_records(proc, out, n, seconds: float = 240.0):
    """Return once the run writing `out` has stored n evaluations; fail if it ends first or does not
    get there in `seconds`."""
    if not wait_until(proc, lambda: out.exists() and len(list(store_path(out).glob("*.npz"))) >= n, seconds):
        pytest.fail(f"the run did not store {n} evaluations: {proc.communicate()}")
