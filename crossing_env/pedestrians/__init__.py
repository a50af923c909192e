"""Pedestrians: the pool and its trip state machine, walking, crossing decisions and their QLB maths.

Social-force walking, classical and quantum-like crossing decisions, and the quantum-like Bayes maths that
those decisions and the intention predictor (`predictors.qlb`) share.
"""
