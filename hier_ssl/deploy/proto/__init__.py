"""The wire protocols' ``.proto`` files and their generated modules (``tests/deploy/test_protocols.py``
regenerates and compares them)."""
