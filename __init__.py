"""shadowflow: the 3D shape of a face from one photograph, and the photograph without its shadows.

``flow/`` is the dataflow engine (``shadowflow.flow``); ``nodes/`` is the face method and the
application (``shadowflow.nodes``). See README.md, "Python".
"""
