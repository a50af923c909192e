"""Trajectory and crossing-intention predictors, and the observation wrappers that plug them into the env."""
