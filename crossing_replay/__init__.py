"""`crossing-replay`: episode logs, rerun recordings of simulated episodes and real scenes, and the viewer."""
