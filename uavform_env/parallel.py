"""Playing independent calls serially or on a process pool, yielding results as they finish."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor, as_completed
from multiprocessing import get_context


def imap_unordered(fn: Callable, calls: list[tuple], workers: int) -> Iterator:
    """Yield ``fn(*call)`` for every call, in completion order: in this process for one worker, else on a
    spawn-context pool. On Ctrl-C or an error the calls not started are dropped, not played unrecorded."""
    if not calls:
        return
    if workers == 1:
        for call in calls:
            yield fn(*call)
        return
    pool = ProcessPoolExecutor(max_workers=min(workers, len(calls)), mp_context=get_context("spawn"))
    try:
        futures = [pool.submit(fn, *call) for call in calls]
        for future in as_completed(futures):
            yield future.result()
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
