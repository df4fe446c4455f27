"""Playing independent calls serially or on a process pool, yielding results as they finish; joining Ray."""

from __future__ import annotations

import os
import socket
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


RAY_MISSING = 'backend "ray" needs Ray: pip install -e ".[ray]" (or pip install "uavform[ray]")'


def connect_ray(address: str | None, num_cpus: int):
    """Import Ray and join a cluster; returns the ``ray`` module.

    ``address`` (else the ``RAY_ADDRESS`` environment variable) names an existing cluster to join
    ("auto", "HOST:PORT" or "ray://HOST:PORT"); without one a new local Ray with ``num_cpus`` CPUs starts
    (``address="local"``: Ray would otherwise join whatever cluster last started on this machine, e.g. another
    process's, and refuse ``num_cpus``). A Ray already initialised in this process is used as it is.
    """
    try:
        import ray
    except ImportError as e:
        raise ValueError(RAY_MISSING) from e
    if not ray.is_initialized():
        address = address or os.environ.get("RAY_ADDRESS") or None
        if address:
            _check_reachable(address)
            try:
                ray.init(address=address, log_to_driver=False)
            except (ConnectionError, RuntimeError, TimeoutError) as e:
                raise ValueError(f"Ray address {address!r}: could not join the cluster ({e})") from e
        else:
            ray.init(address="local", num_cpus=num_cpus, include_dashboard=False, log_to_driver=False)
    return ray


def _check_reachable(address: str, timeout: float = 5.0) -> None:
    """Fail within ``timeout`` s when nothing listens at a HOST:PORT address (Ray itself retries for minutes)."""
    host, sep, port = address.split("://", 1)[-1].rpartition(":")
    if not sep or not port.isdigit():
        return                                              # "auto" and the like: Ray resolves them
    try:
        socket.create_connection((host, int(port)), timeout=timeout).close()
    except OSError as e:
        raise ValueError(f"Ray address {address!r}: nothing answers at {host}:{port} ({e}); start the cluster "
                         "(ray start --head) or fix --ray-address / RAY_ADDRESS") from e
