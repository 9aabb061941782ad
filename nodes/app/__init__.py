"""The application: the Python API (``api``), the command line (``cli``), streaming runs
(``runner``), the output files (``outputs``) and what the method records (``record``)."""
