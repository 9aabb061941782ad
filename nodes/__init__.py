"""The face method and its application, in layers that import only downward:

``geometry`` (surfaces and light) < ``model`` (the needle-map model and its training faces)
and ``photo`` (reading and aligning the input) < ``method`` (the paper's steps and their nodes)
< ``evaluation`` (benchmarks) < ``app`` (Python API, command line, runs, outputs, recordings).
"""
