"""uavform_env: a PettingZoo ParallelEnv of N UAVs flying in formation through 3D obstacle fields."""
