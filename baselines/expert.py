"""The fusion expert's public names (``baselines.fusion`` holds its config, controller, rules and kernels)."""

from .fusion import WEIGHT_NAMES, ExpertConfig, FusionExpert, StandardDWA, planar_formation

__all__ = ["ExpertConfig", "FusionExpert", "StandardDWA", "WEIGHT_NAMES", "planar_formation"]
