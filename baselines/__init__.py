"""Scripted policies: the A* + improved DWA + 3D VFH+ fusion expert and the simpler baselines."""
