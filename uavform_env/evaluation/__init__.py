"""The leaderboard: frozen benchmark suites, a resumable runner and the ranked table.

    from uavform_env.evaluation import load_suite, run_suite, write_tables
    suite = load_suite("smoke")
    records = run_suite(suite, ["expert", "apf"], "results/", workers=2)
    write_tables(suite, records, "results/")
"""

from .runner import BACKENDS, play, read_results, run_suite
from .suites import Episode, Suite, list_suites, load_suite
from .table import RANKING, WALL_CLOCK_METRICS, bootstrap_ci, summarize, write_tables

__all__ = ["BACKENDS", "Episode", "RANKING", "Suite", "WALL_CLOCK_METRICS", "bootstrap_ci", "list_suites",
           "load_suite", "play", "read_results", "run_suite", "summarize", "write_tables"]
