"""Trained networks read back from a run directory, below both the workers and the learners that use
them (``actor``: a run's frozen deterministic actor). Importing ``hier_ssl.checkpoints.actor`` brings
torch; this package alone does not."""
