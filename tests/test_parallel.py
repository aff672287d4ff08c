"""The engines' thread shares: torch's count held through numba's parallel loops."""

import numba
import numpy as np
import torch

from rfsdf.parallel import threads_per_worker, use_threads


@numba.njit(parallel=True)
def _total(values):
    total = 0.0
    for i in numba.prange(len(values)):
        total += values[i]
    return total


def test_one_thread_holds_through_a_numba_loop_and_a_worker_share_divides_this_process_s():
    """numba, starting its OpenMP threads at its first parallel loop, sets the team it shares
    with torch to numba's count: with torch's count alone set, a worker meant to run one thread
    ran every core after that loop (this test with it fails so)."""
    before = torch.get_num_threads()
    try:
        use_threads(1)
        assert _total(np.ones(10_000)) == 10_000
        assert torch.get_num_threads() == 1 == numba.get_num_threads()
        assert threads_per_worker(1) == 1 and threads_per_worker(4) == 1
        use_threads(2)
        assert threads_per_worker(1) == 2 and threads_per_worker(2) == 1
    finally:
        use_threads(before)
