"""Research and reproduction scripts on top of the library: training sweeps, evaluation tables, studies.

Run each from the repository root as ``python -m studies.<name>``. Nothing in the library layers imports
from here; these scripts may import from any of them.
"""
