"""The fusion expert (spec (g)): ``config`` (ExpertConfig), ``controller`` (FusionExpert: target -> vertical
decision -> DWA -> rules), ``rules`` (the ordered command rules) and ``kernels`` (numba geometry kernels)."""

from .config import WEIGHT_NAMES, ExpertConfig
from .controller import FusionExpert, StandardDWA, planar_formation

__all__ = ["ExpertConfig", "FusionExpert", "StandardDWA", "WEIGHT_NAMES", "planar_formation"]
