"""Accuracy harnesses: rendered test scenes (``scenes``), the synthetic benchmark
(``synthetic``), and real photos of Extended Yale B against photometric stereo
(``yaleb``, ``photometric_stereo``, ``yaleb_benchmark``)."""
