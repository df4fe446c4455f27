"""Scripted policies: the paper's planners bare (``paper``), the engineered A* + improved DWA + 3D VFH+ fusion
expert (``expert``) and the simpler baselines."""
