"""Crash checks of a step (collisions): separations against scipy bit for bit, causes and their precedence."""

import numpy as np
import pytest
from scipy.spatial.distance import cdist

from uavform_env.collisions import CRASH_CAUSES, GEOFENCE, NONE, OBSTACLE, UAV, contacts, separations
from uavform_env.env import END_REASONS


def test_crash_causes_name_the_env_end_reasons():
    assert CRASH_CAUSES[NONE] == "none"
    assert [f"crash-{c}" for c in CRASH_CAUSES[1:]] == [r for r in END_REASONS if r.startswith("crash-")]


def test_separations_match_scipy_bit_for_bit():
    rng = np.random.default_rng(0)
    for n in (1, 2, 5, 17):
        pos = rng.uniform(-50, 50, (n, 3))
        d = cdist(pos, pos)
        np.fill_diagonal(d, np.inf)
        assert separations(pos).tobytes() == d.min(axis=1).tobytes()
        states = np.column_stack([pos, rng.normal(size=(n, 4))])  # state rows: the first three columns count
        assert separations(states).tobytes() == d.min(axis=1).tobytes()


def test_contacts_known_answers_and_precedence():
    lo, hi = np.array([0.0, 0.0, 0.0]), np.array([10.0, 10.0, 5.0])
    pos = np.array([[5.0, 5.0, 2.0],    # 0: inside an obstacle and outside the fence: the obstacle wins
                    [-1.0, 5.0, 2.0],   # 1: outside the fence (x < 0), near nothing
                    [2.0, 2.0, 9.0],    # 2: above the box: z is no fence
                    [8.0, 8.0, 2.0],    # 3 and 4: 0.3 m apart
                    [8.3, 8.0, 2.0],
                    [8.0, 8.2, 2.0]])   # 5: close to 3 but crashed earlier (inactive)
    pos[0, 0] = 11.0
    clearance = np.array([-0.1, 3.0, 3.0, 3.0, 3.0, 3.0])
    active = np.array([True, True, True, True, True, False])
    sep, cause, hit = contacts(pos, clearance, lo, hi, 0.5, active)
    assert hit
    assert cause.tolist() == [OBSTACLE, GEOFENCE, NONE, UAV, UAV, NONE]
    assert sep[3] == pytest.approx(0.2) and sep[4] == pytest.approx(0.3)  # a crashed UAV is still there
    _, cause, hit = contacts(pos, np.full(6, 3.0), lo, hi, 0.1, np.array([False, False, True, True, True, True]))
    assert not hit and (cause == NONE).all()
