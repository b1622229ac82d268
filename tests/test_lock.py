"""m-of-k lock: locked exactly at the m-th hit inside a k-frame window, never before."""

import pytest

from sarmission.tracking.lock import MofKLock, first_lock_index


def run(hits, m=3, k=5):
    lock = MofKLock(m, k)
    return [lock.update(h) for h in hits], lock


def test_locks_exactly_at_mth_hit_within_window():
    hits = [1, 0, 1, 0, 1, 0]  # third hit at index 4, window 0..4 holds 3 hits
    states, lock = run(hits)
    assert states == [False, False, False, False, True, True]
    assert lock.lock_index == 4
    assert first_lock_index(hits) == 4


def test_consecutive_hits_lock_at_index_m_minus_1():
    assert first_lock_index([True] * 10) == 2
    states, _ = run([True] * 10)
    assert states.index(True) == 2


def test_hits_spread_wider_than_k_never_lock():
    hits = [1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0]  # any 5-window has at most 2 hits
    states, lock = run(hits)
    assert not any(states)
    assert lock.lock_index is None
    assert first_lock_index(hits) is None


def test_window_slides_old_hits_drop_out():
    assert first_lock_index([1, 1, 0, 0, 1]) == 4  # hits 0, 1, 4 share the window 0..4
    assert first_lock_index([1, 1, 0, 0, 0, 1, 1]) is None  # hit 0/1 leave before 5/6 arrive
    assert first_lock_index([1, 1, 0, 0, 0, 1, 1, 1]) == 7


def test_stays_locked_after_misses():
    states, lock = run([1, 1, 1] + [0] * 20)
    assert all(states[2:])
    assert lock.locked and lock.lock_index == 2


def test_m_equals_k_needs_k_consecutive_hits():
    assert first_lock_index([1, 1, 1, 0, 1, 1, 1, 1], m=4, k=4) == 7
    assert first_lock_index([1, 1, 1, 0] * 5, m=4, k=4) is None
    assert first_lock_index([1], m=1, k=1) == 0
    assert first_lock_index([0, 0, 1], m=1, k=5) == 2


def test_class_and_function_agree():
    pattern = [1, 0, 0, 1, 1, 0, 1, 0, 1, 1, 0, 0, 1]
    for m, k in [(1, 1), (2, 3), (3, 5), (4, 6), (5, 5)]:
        _, lock = run(pattern, m, k)
        assert lock.lock_index == first_lock_index(pattern, m, k)


@pytest.mark.parametrize("m,k", [(0, 5), (6, 5), (-1, 3)])
def test_invalid_parameters(m, k):
    with pytest.raises(ValueError):
        MofKLock(m, k)
    with pytest.raises(ValueError):
        first_lock_index([True], m, k)
