"""shadowflow's dataflow engine: frames passed through a chain of nodes.

Knows nothing about faces: a node is any callable ``Frame -> Frame`` with a ``name``.
"""
from flow.frame import Frame, FrameFailed
from flow.chain import Chain
from flow.pipeline import Pipeline, Stage, run_node

__all__ = ["Frame", "FrameFailed", "Chain", "Pipeline", "Stage", "run_node"]
