"""Evaluation of managers: seeded batched episodes (``evaluate``), managers by name side by side
(``compare``), tables and records (``report``), figures and GIFs (``figures``) and the paper's tables
(``paper_tables``). Modules are imported by name; this package alone imports nothing.
"""
