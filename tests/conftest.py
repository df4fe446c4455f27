"""Shared fixtures: small, fast env constructors used across the test suite."""

import os

import matplotlib
import pytest

matplotlib.use("Agg")
os.environ.setdefault("SB3_LOGDIR", os.path.join(os.environ.get("TMPDIR", "/tmp"), "uavform-sb3"))


def small_env_kwargs(**overrides):
    """A small default: the forest scenario with 3 UAVs in a triangle and a short horizon."""
    kw = dict(scenario="forest", n_uavs=3, formation="triangle", max_cycles=60)
    kw.update(overrides)
    return kw


@pytest.fixture
def small_kwargs():
    return small_env_kwargs()
