"""Running a suite for a list of policies: serial, on a process pool or on Ray, append-only and resumable.

The results folder holds ``suite.json`` (the suite's manifest and hash, written once) and
``results.jsonl`` (one JSON line per finished (episode, policy), appended atomically by the parent
process only). A run skips every pair already in ``results.jsonl`` when resumed, so a killed run
loses at most the episodes in flight. An exception inside a policy, or an episode that exceeds its
wall-clock limit, becomes a ``failed`` record with its traceback; the run goes on.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import subprocess
import time
import traceback
from pathlib import Path

import numpy as np

from ..files import append_line, atomic_write_json, read_jsonl, set_aside_torn_line
from ..parallel import connect_ray, imap_unordered
from .suites import Episode, Suite

RESULTS_FILE = "results.jsonl"
MANIFEST_FILE = "suite.json"
BACKENDS = ("process", "ray")


def play(episode: dict, policy_spec: str, time_limit: float | None) -> dict:
    """Play one episode with a freshly loaded policy and return its results record (never raises).

    A top-level function of plain arguments so process pools and Ray can ship it; a fresh env and
    policy per episode make the metrics independent of which worker ran what before.
    """
    from ..formation_v0 import parallel_env
    from ..metrics import episode_outcome
    from ..policies import load_policy
    from ..rollout import EpisodeTimeout, run_episode

    ep = Episode(**episode)
    record = {"episode": ep.key, "policy": policy_spec, **ep.to_dict()}
    start = time.perf_counter()
    policy = None
    try:
        penv = parallel_env(**ep.env_kwargs())
        policy = load_policy(policy_spec)
        metrics = run_episode(penv, policy, ep.seed, time_limit=time_limit)
        outcome, detail = episode_outcome(penv.unwrapped)
        record.update(status="ok", steps=int(penv.unwrapped.step_count), metrics=metrics, error=None,
                      outcome=outcome, outcome_detail=detail)
    except Exception as e:  # a broken policy must not stop the benchmark: record it and go on
        status = "time_limit" if isinstance(e, EpisodeTimeout) else "failed"
        record.update(status=status, steps=None, metrics=None, outcome=status, outcome_detail=f"{type(e).__name__}: {e}",
                      error="".join(traceback.format_exception(type(e), e, e.__traceback__)))
    if record["outcome"] != "success":
        record["diagnostics"] = policy_diagnostics(policy)
    record["wall_time"] = time.perf_counter() - start
    return record


def policy_diagnostics(policy) -> dict | None:
    """The policy's own account of its last step (its ``diagnostics`` attribute, if it has one) as plain JSON
    values, so a failed episode's record says what the policy thought it was doing."""
    diagnostics = getattr(policy, "diagnostics", None)
    if diagnostics is None:
        return None

    def plain(value):
        if isinstance(value, dict):
            return {str(k): plain(v) for k, v in value.items()}
        if isinstance(value, (list, tuple, np.ndarray)):
            return [plain(v) for v in value]
        if isinstance(value, np.generic):
            return value.item()
        return value if isinstance(value, (str, int, float, bool)) or value is None else repr(value)

    return plain(diagnostics)


def policy_fingerprint(spec: str) -> str | None:
    """SHA-256 of a checkpoint file (so results name the exact weights), None for named policies."""
    path = Path(spec)
    if ":" in spec or not path.is_file():
        return None
    return hashlib.sha256(path.read_bytes()).hexdigest()[:16]


def code_version() -> str:
    """The package version, plus the git commit ('.dirty' with uncommitted changes) when run from a checkout.

    The suite hash fixes the episodes; this names the code that flew them, so a table can say when its
    rows come from different code.
    """
    from .. import __version__

    root = Path(__file__).resolve().parents[2]
    try:
        def git(*args):
            return subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True, timeout=10,
                                  check=True).stdout.strip()
        commit = git("rev-parse", "--short=10", "HEAD")
        dirty = git("status", "--porcelain", "--untracked-files=no")
    except (OSError, subprocess.SubprocessError):
        return __version__
    return f"{__version__}+g{commit}" + (".dirty" if dirty else "")


def check_policies(specs: list[str]) -> None:
    """Load every policy once before anything is written, so a bad name or checkpoint fails up front."""
    from ..policies import load_policy

    if not specs:
        raise ValueError("policies: expected at least one policy")
    if len(set(specs)) != len(specs):
        raise ValueError(f"policies: {specs} lists a policy twice")
    for spec in specs:
        try:
            load_policy(spec)
        except ValueError:
            raise
        except Exception as e:
            raise ValueError(f"policy {spec!r} could not be loaded: {type(e).__name__}: {e}") from e


def read_results(out: str | os.PathLike) -> list[dict]:
    """The records of ``out/results.jsonl`` (see ``files.read_jsonl``: a torn last line is skipped)."""
    return read_jsonl(Path(out) / RESULTS_FILE, "results line",
                      frozenset({"episode", "policy", "status", "suite_hash"}))


def read_manifest(out: str | os.PathLike) -> dict | None:
    path = Path(out) / MANIFEST_FILE
    if not path.exists():
        return None
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except ValueError as e:
        raise ValueError(f"{path}: corrupt suite manifest ({e})") from e


def prepare_folder(suite: Suite, out: str | os.PathLike, resume: bool) -> set[tuple[str, str]]:
    """Check ``out`` belongs to ``suite`` and return the finished (episode, policy) pairs; write the manifest.

    Refuses, without touching anything, a folder of another suite hash, and a folder with results
    unless ``resume`` is set.
    """
    out = Path(out)
    manifest = read_manifest(out)
    if manifest is not None and manifest.get("suite_hash") != suite.hash:
        raise ValueError(f"results folder {str(out)!r} holds suite {manifest.get('suite')!r} (hash "
                         f"{manifest.get('suite_hash')}), not suite {suite.name!r} (hash {suite.hash}); "
                         "results of different suites are not comparable: choose another --out")
    records = read_results(out)
    foreign = sorted({r["suite_hash"] for r in records} - {suite.hash})
    if foreign:
        raise ValueError(f"{out / RESULTS_FILE} holds results of suite hash(es) {foreign}, not {suite.hash}")
    if records and not resume:
        raise ValueError(f"results folder {str(out)!r} already holds {len(records)} results: pass --resume to "
                         "continue it (finished episodes are skipped) or choose another --out")
    if manifest is None:
        atomic_write_json(out / MANIFEST_FILE, suite.manifest())
    set_aside_torn_line(out / RESULTS_FILE)
    return {(r["episode"], r["policy"]) for r in records}


def run_suite(suite: Suite, policies: list[str], out: str | os.PathLike, *, workers: int = 1,
              backend: str = "process", resume: bool = False, time_limit: float | None = None,
              progress: bool = True, ray_address: str | None = None) -> list[dict]:
    """Play every (episode, policy) of ``suite`` not yet in ``out`` and append its record; return all records.

    ``workers=1`` with the process backend plays in this process; more use a spawn-context process
    pool. ``backend="ray"`` submits the same ``play`` calls as Ray tasks: on the cluster at ``ray_address``
    (else ``RAY_ADDRESS``), else on a local Ray of ``workers`` CPUs (``parallel.connect_ray``). Metrics do
    not depend on the backend or the order.
    """
    if backend not in BACKENDS:
        raise ValueError(f"backend={backend!r}: expected one of {list(BACKENDS)}")
    if ray_address is not None and backend != "ray":
        raise ValueError(f"ray_address={ray_address!r}: only with backend='ray'")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers={workers!r}: expected an integer >= 1")
    if time_limit is not None and not (isinstance(time_limit, (int, float)) and time_limit > 0
                                       and math.isfinite(time_limit)):
        raise ValueError(f"time_limit={time_limit!r}: expected a positive number of seconds or None")
    check_policies(policies)
    if backend == "ray":
        connect_ray(ray_address, workers)      # no Ray, or no cluster at the address: fail before writing anything
    done = prepare_folder(suite, out, resume)
    fingerprints = {p: policy_fingerprint(p) for p in policies}
    code = code_version()
    todo = [(e, p) for p in policies for e in suite.episodes if (e.key, p) not in done]
    results_path = Path(out) / RESULTS_FILE

    def record(rec: dict) -> None:
        rec.update(suite=suite.name, suite_hash=suite.hash, policy_sha256=fingerprints[rec["policy"]], code=code)
        append_line(results_path, json.dumps(rec, sort_keys=True, allow_nan=True))

    calls = [(e.to_dict(), p, time_limit) for e, p in todo]
    from tqdm import tqdm

    with tqdm(total=len(calls), desc=f"suite {suite.name} [{suite.hash}]", unit="episode",
              disable=not progress) as bar:
        failed = 0
        for rec in _execute(calls, workers, backend, ray_address):
            record(rec)
            failed += rec["status"] != "ok"
            bar.update(1)
            bar.set_postfix(failed=failed, refresh=False)
    return read_results(out)


def _execute(calls: list[tuple], workers: int, backend: str, ray_address: str | None = None):
    """Yield ``play(*call)`` for every call, in completion order."""
    if not calls:
        return
    if backend == "ray":
        yield from _execute_ray(calls, workers, ray_address)
    else:
        yield from imap_unordered(play, calls, workers)


def _execute_ray(calls: list[tuple], workers: int, address: str | None = None):
    ray = connect_ray(address, workers)
    remote_play = ray.remote(num_cpus=1)(play)
    pending = [remote_play.remote(*call) for call in calls]
    try:
        while pending:
            ready, pending = ray.wait(pending, num_returns=1)
            yield ray.get(ready[0])
    finally:
        for ref in pending:
            ray.cancel(ref)
