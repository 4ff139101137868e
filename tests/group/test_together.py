"""`wcs.group.together`: the ranks of an evaluation's group agree whether a step failed, once
a step, so that a rank that fails alone does not leave the others waiting in a collective
step. Here on one process, the other rank's word given by a stand-in communicator."""
import pytest

from wcs.group import GroupFailure, rows, share, spanning, together


class Other:
    """A group of 2 seen from rank 0: allgather gives this rank's word and the other's next one."""

    size, rank = 2, 0

    def __init__(self, *words):
        self.words, self.calls = list(words), 0

    def allgather(self, mine):
        self.calls += 1
        return [mine, self.words.pop(0)]


def test_alone_it_is_the_call():
    assert together(lambda x: x + 1, 1) == 2


def test_a_step_that_fails_nowhere_returns_after_one_agreement():
    comm = Other(None)
    with spanning(comm):
        assert together(lambda: 7) == 7
    assert comm.calls == 1


def test_the_other_rank_failing_raises_with_its_message_here():
    comm = Other("MemoryError: out of memory")
    with spanning(comm), pytest.raises(GroupFailure) as e:
        together(lambda: 7)
    assert str(e.value) == "rank 1 of the evaluation's 2 ranks failed: MemoryError: out of memory"


def test_a_failure_here_is_told_once_and_raised_as_itself_through_the_enclosing_steps():
    comm = Other(None)

    def inner():
        raise ValueError("bad rows")
    with spanning(comm), pytest.raises(ValueError, match="bad rows"):
        together(lambda: together(inner))       # the outer step must not agree a second time
    assert comm.calls == 1


def test_a_failure_learnt_from_the_other_rank_passes_the_enclosing_steps_untold():
    comm = Other("KeyError: 3")
    with spanning(comm), pytest.raises(GroupFailure):
        together(lambda: together(lambda: 1))
    assert comm.calls == 1


def test_the_shares_cover_the_items_in_order():
    assert [rows(10, 3, r) for r in range(3)] == [(0, 4), (4, 7), (7, 10)]
    assert share(10) == (0, 10)
    with spanning(Other()):
        assert share(10) == (0, 5)
