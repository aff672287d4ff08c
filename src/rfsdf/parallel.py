"""Run independent tasks on the standard engines: in this process, a local process pool
(``concurrent.futures``), or Ray tasks on a local instance or a cluster. No scheduler,
queue or retry loop of our own: the engines have them."""

from __future__ import annotations

import multiprocessing
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Callable, Sequence

from .errors import RfsdfError

__all__ = ["threads_per_worker", "use_threads", "error_line", "map_tasks"]


def threads_per_worker(workers: int) -> int:
    """Torch threads for each of ``workers`` concurrent tasks sharing this process's threads
    (torch's count: the cores, or ``OMP_NUM_THREADS``); one worker keeps them all, so tasks
    run in this process leave its count as it was."""
    import torch

    return max(1, torch.get_num_threads() // max(1, workers))


def use_threads(threads: int) -> None:
    """Run this process's torch and numba kernels on ``threads`` threads (numba's at most its
    ``NUMBA_NUM_THREADS``, the cores by default). Both share one OpenMP runtime, whose team
    numba sets to its own count when it starts its threads: numba's first, then torch's."""
    import numba
    import torch

    threads = max(1, threads)
    numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))  # starts numba's threads
    torch.set_num_threads(threads)


def error_line(exc: BaseException) -> str:
    """A task's failure as the one line its result row records: 'Type: first line of the message'."""
    return f"{type(exc).__name__}: {exc}".splitlines()[0]


def map_tasks(function: Callable, arguments: Sequence[tuple], *, workers: int = 1, ray_address: str | None = None,
              cpus_per_task: int = 1, on_result: Callable[[int, object], None] = lambda i, r: None) -> list:
    """[function(*a) for a in arguments], run in this process (``workers`` 1), a process pool
    of ``workers``, or as Ray tasks (``ray_address``: "local" starts a Ray instance, anything
    else is passed to ``ray.init``; shut down on return unless Ray was initialised before the
    call) with ``cpus_per_task`` each. ``on_result(index, result)``
    is called as each finishes. ``function`` must be importable (pickled by reference)."""
    results: list = [None] * len(arguments)

    def finished(index: int, result) -> None:
        results[index] = result
        on_result(index, result)

    if ray_address is not None:
        try:
            import ray
        except ImportError:
            raise RfsdfError("--ray: Ray is not installed (pip install 'rfsdf[cluster]')") from None
        started = not ray.is_initialized()  # ours to shut down: a local instance's processes outlive the tasks
        ray.init(address=None if ray_address == "local" else ray_address, ignore_reinit_error=True,
                 include_dashboard=False, log_to_driver=False, configure_logging=False)
        try:
            task = ray.remote(num_cpus=cpus_per_task)(function)
            pending = {task.remote(*args): i for i, args in enumerate(arguments)}
            while pending:
                done, _ = ray.wait(list(pending), num_returns=1)
                finished(pending.pop(done[0]), ray.get(done[0]))
        finally:
            if started:
                ray.shutdown()
    elif workers <= 1:
        for i, args in enumerate(arguments):
            finished(i, function(*args))
    else:
        # spawned, not forked: a child forked from a process whose numba or OpenMP threads are
        # running hangs in its first parallel kernel (the facet simulation's did, in a sweep)
        with ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn")) as pool:
            futures = {pool.submit(function, *args): i for i, args in enumerate(arguments)}
            for future in as_completed(futures):
                finished(futures[future], future.result())
    return results
