"""shadowflow's dataflow engine: frames passed through a chain of nodes.

Knows nothing about faces: a node is any callable ``Frame -> Frame`` with a ``name``.
"""
from .chain import Chain
from .frame import Frame, FrameFailed
from .pipeline import Pipeline, Stage, run_node

__all__ = ["Frame", "FrameFailed", "Chain", "Pipeline", "Stage", "run_node"]
