"""Mission variety, disturbances, honest endings and goal-slot checks (issue 12).

The first test pins version 1 of every generator bit for bit: the digest was computed on the code
before version 2 existed, from a serialisation written here (independent of the package's own TOML).
"""

import hashlib

import numpy as np
import pytest

from uavform_env.scenarios import make_scenario
from uavform_env.world import Box, Cylinder

V1_CASES = [("classic-2d@1", s, {}) for s in (0, 3)] + [("classic-2d@1", 1, {"difficulty": "extended", "n_uavs": 2,
                                                                         "formation": "column"})]
V1_CASES += [(f"{name}@1", s, {}) for name in ("forest", "urban", "wall-gap", "corridor") for s in (0, 1, 7)]
V1_CASES += [("random-3d@1", s, {"difficulty": d}) for s, d in ((0, "easy"), (1, "medium"), (2, "hard"))]
V1_CASES += [("forest@1", 4, {"n_uavs": 10}), ("urban@1", 5, {"n_uavs": 3, "formation": "triangle", "spacing": 2.5})]
V1_DIGEST = "d57e0ebdb7b7311e5af92447e9e8a9a12e701356bcc8cbba8f474f9846233347"


def _canonical(scn) -> str:
    """Every number as float.hex, so the digest changes with any bit of any field."""
    def h(values):
        return ",".join(float(v).hex() for v in values)
    parts = [scn.name, str(scn.version), str(scn.seed), h(scn.bounds_lo), h(scn.bounds_hi), float(scn.resolution).hex()]
    for ob in scn.obstacles:
        if isinstance(ob, Box):
            parts.append("box:" + h(ob.lo + ob.hi))
        elif isinstance(ob, Cylinder):
            parts.append("cyl:" + h((ob.x, ob.y, ob.radius, ob.z_lo, ob.z_hi)))
        else:
            parts.append("sph:" + h((ob.x, ob.y, ob.z, ob.radius)))
    m = scn.mission
    parts += [h(m.start), h(m.goal), float(m.start_heading).hex(), m.formation, float(m.spacing).hex(), str(m.n_uavs)]
    return "|".join(parts)


def v1_digest() -> str:
    text = "\n".join(_canonical(make_scenario(name, seed, **kw)) for name, seed, kw in V1_CASES)
    return hashlib.sha256(text.encode()).hexdigest()


def test_version_1_generators_are_frozen_bit_for_bit():
    assert v1_digest() == V1_DIGEST
