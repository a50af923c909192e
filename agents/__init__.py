"""Driving policies for the crossing environment and the evaluation script."""
