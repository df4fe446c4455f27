"""Telling the user when numba is about to compile the kernels (a cold cache), instead of sitting silent.

The hot loops are ``@njit(cache=True)`` kernels: the first run compiles them (about a minute) and writes
numba's cache next to each module (``__pycache__/*.nbi`` index + ``*.nbc`` data); later runs load them
in a fraction of a second. ``cold_modules`` reads those index files through the dispatchers themselves,
so it sees exactly what numba will see: a module is cold when none of its cached kernels is compiled
in this process and none has a fresh index entry on disk (missing, from another numba, or older than
the source). A module whose kernels are only partly cached is warm: some kernels (e.g. octree levels)
may never run in a flight, and counting them would announce a compile on every run. Kernels marked
``inline="always"`` are compiled into their callers and never cached on their own, so they do not count.
Once any kernel has been compiled or loaded in this process, the process has already flown and the notice
(if one was due) has been given: a leaderboard worker that makes a new env for every episode says it once.
"""

from __future__ import annotations

import sys

from numba.core.caching import NullCache
from numba.core.registry import CPUDispatcher

MESSAGE = "compiling kernels (first run only, about a minute)"
# The packages of this distribution whose loaded modules are checked (the env never imports the others;
# it only looks at them when the caller has loaded them, e.g. the expert's planners).
PACKAGES = ("uavform_env", "baselines", "training")


def _cached_kernels(module) -> list:
    return [v for v in vars(module).values()
            if isinstance(v, CPUDispatcher) and v.py_func.__module__ == module.__name__
            and not isinstance(v._cache, NullCache) and v.targetoptions.get("inline") != "always"]


def _warm(kernel) -> bool:
    # numba's own index reader: {} when the index is missing, from another numba version, or stale
    return bool(kernel.overloads) or bool(kernel._cache._cache_file._load_index())


def _loaded_modules() -> list:
    return [(name, module) for name, module in sorted(sys.modules.items())
            if module is not None and name.partition(".")[0] in PACKAGES]


def cold_modules() -> list[str]:
    """Loaded modules of ``PACKAGES`` whose numba kernels will compile on their first call (see module doc)."""
    cold = []
    for name, module in _loaded_modules():
        kernels = _cached_kernels(module)
        if kernels and not any(_warm(k) for k in kernels):
            cold.append(name)
    return cold


def flown() -> bool:
    """Whether any kernel of ``PACKAGES`` has been compiled or loaded from the cache in this process."""
    return any(k.overloads for _, module in _loaded_modules() for k in _cached_kernels(module))


def compile_notice(stream=None) -> bool:
    """Print ``MESSAGE`` to stderr (or ``stream``) if this process has not flown yet (``flown``) and loaded
    kernels are cold (``cold_modules``); True if printed.

    The env calls it once, at its first ``reset`` (which is where the kernels compile, the policy's right
    after in its first ``act``), so a user sees one line instead of a silent wait.
    """
    if flown() or not cold_modules():
        return False
    print(MESSAGE, file=stream if stream is not None else sys.stderr, flush=True)
    return True
