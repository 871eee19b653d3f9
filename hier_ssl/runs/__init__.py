"""Training runs: one run (``train``), the run directory's state as a job (``jobs``), many runs in turn, as
processes or as Ray Tune trials (``launch``, ``ray_tune``), grids of them (``sweep``) and the paper's rows
(``reproduce``). Modules are imported by name; this package alone imports nothing (``train`` brings torch).
"""
