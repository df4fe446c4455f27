"""Residual reinforcement learning on the fusion expert's evaluation weights."""
