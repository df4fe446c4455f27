"""The built-in policies under their short names (entry-point group ``uavform.policies`` in pyproject.toml)."""

from .expert import ExpertConfig, FusionExpert, StandardDWA, planar_formation
from .paper import paper_planner
from .simple import APF, Hover, Random

dwa_e8 = planar_formation("DWA+E8")
dwa_e8_e10 = planar_formation("DWA+E8+E10")
idwa_planar = planar_formation("IDWA")


def expert_no_gap() -> FusionExpert:
    """The expert without its gap rule (``gap_lookahead=0``): 3D VFH+ alone must find vertical passages (an ablation)."""
    return FusionExpert(ExpertConfig(gap_lookahead=0.0))


# The paper-faithful family (baselines.paper): the paper's planners bare, without the expert's [X] rules.
paper_dwa = paper_planner("DWA")
paper_dwa_e8 = paper_planner("DWA+E8")
paper_dwa_e8_e10 = paper_planner("DWA+E8+E10")
paper_idwa = paper_planner("IDWA")
paper_fusion = paper_planner("IDWA", use_vfh=True)

BUILTIN = {"expert": FusionExpert, "expert-no-gap": expert_no_gap, "standard-dwa": StandardDWA, "dwa+e8": dwa_e8, "dwa+e8+e10": dwa_e8_e10,
           "idwa-2d": idwa_planar, "apf": APF, "hover": Hover, "random": Random,
           "paper-dwa": paper_dwa, "paper-dwa+e8": paper_dwa_e8, "paper-dwa+e8+e10": paper_dwa_e8_e10,
           "paper-idwa": paper_idwa, "paper-fusion": paper_fusion}
