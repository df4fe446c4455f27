"""Shared fixtures: small, fast env constructors used across the test suite."""

import os

import matplotlib
import pytest
from hypothesis import settings

matplotlib.use("Agg")
# Property tests draw the same examples on every run and machine (a fresh CI clone found a new one otherwise);
# HYPOTHESIS_PROFILE=explore searches afresh.
settings.register_profile("deterministic", derandomize=True, database=None)
settings.register_profile("explore")
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "deterministic"))
os.environ.setdefault("SB3_LOGDIR", os.path.join(os.environ.get("TMPDIR", "/tmp"), "uavform-sb3"))


def small_env_kwargs(**overrides):
    """A small default: the forest scenario with 3 UAVs in a triangle and a short horizon."""
    kw = dict(scenario="forest", n_uavs=3, formation="triangle", max_cycles=60)
    kw.update(overrides)
    return kw


@pytest.fixture
def small_kwargs():
    return small_env_kwargs()
