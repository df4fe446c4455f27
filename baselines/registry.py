"""The built-in policies under their short names (entry-point group ``uavform.policies`` in pyproject.toml)."""

from .expert import FusionExpert, StandardDWA, planar_formation
from .simple import APF, Hover, Random

dwa_e8 = planar_formation("DWA+E8")
dwa_e8_e10 = planar_formation("DWA+E8+E10")
idwa_planar = planar_formation("IDWA")

BUILTIN = {"expert": FusionExpert, "standard-dwa": StandardDWA, "dwa+e8": dwa_e8, "dwa+e8+e10": dwa_e8_e10,
           "idwa-2d": idwa_planar, "apf": APF, "hover": Hover, "random": Random}
