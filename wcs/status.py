"""The status of an evaluation: one code per way a solve ends, the `status` variable of the results file.

The contact solver, the model and the evaluator report these members; the results file writes
their codes as `flag_values` and their descriptions as CF `flag_meanings`. The domain
decomposition has its own outcomes (`DDOutcome`, here beside them so that the model reads
them without importing the decomposition); every one but converged leaves the model as
DD_FAILED.
"""
from enum import Enum, IntEnum

import numpy as np


class Status(IntEnum):
    """code, NAME and description of how an evaluation ended (0 solved)."""
    SOLVED = 0, "solved"
    CONTACT_NOT_CONVERGED = 1, "contact solver did not converge"
    FIXED_POINT_NOT_CONVERGED = 2, "Coulomb fixed point did not converge"
    UNSOLVABLE = 3, "solvability violated: a floating body is not balanced"
    SINGULAR = 4, "singular system or factorization failed"
    DD_FAILED = 5, "domain decomposition failed"
    OTHER_FAILURE = 6, "other failure"
    NOT_UNIQUE = 7, "solution not unique: a rigid motion of a floating body is free"

    def __new__(cls, code: int, description: str):
        member = int.__new__(cls, code)
        member._value_ = code
        member.description = description
        return member

    @property
    def scene_fault(self) -> bool:
        """The scene itself has no (unique) solution at these data: bad input at the nominal data."""
        return self in (Status.UNSOLVABLE, Status.NOT_UNIQUE)

    @property
    def flag_meaning(self) -> str:
        """The description as one CF flag word: runs of non-alphanumerics become one underscore."""
        w = "".join(ch if ch.isalnum() else "_" for ch in self.description)
        while "__" in w:
            w = w.replace("__", "_")
        return w.strip("_")


def describe(code: int) -> str:
    """The description of a status code read from a file; "unknown" for a code not in `Status`."""
    return Status(code).description if code in Status._value2member_map_ else "unknown"


def flag_attrs() -> dict:
    """CF `flag_values` and `flag_meanings` of a `status` variable."""
    return {"flag_values": np.array([s.value for s in Status], dtype=np.int32),
            "flag_meanings": " ".join(s.flag_meaning for s in Status)}


class DDOutcome(Enum):
    """How a DD solve ended; the value names it in messages and `info["status_name"]`. Not an
    evaluation status: the model reports every outcome but CONVERGED as `Status.DD_FAILED`."""
    CONVERGED = "converged"
    DIVERGED = "diverged"
    STAGNATED = "stagnated"
    BUDGET = "budget exhausted"
    LOCAL_FAILED = "local solve failed"
    SETUP_FAILED = "setup failed"
