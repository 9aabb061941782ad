"""shadowflow: the 3D shape of a face from one photograph, and the photograph without its shadows.

    import shadowflow
    result = shadowflow.fit("face.png")        # normals, depth, albedo, shadow, relit, mesh, history
    result.save("out/face")
    shadowflow.run(["photos/"], "out")         # a stream of files, as ``shadowflow run``

``flow/`` is the dataflow engine (``shadowflow.flow``, knows nothing of faces); ``nodes/`` is the
method and the application (``shadowflow.nodes``). README.md, "Python", has more.
"""
from .nodes.app.api import Products, fit, run
from .nodes.method.nodes import MethodOptions
from .nodes.method.robust_fit import FitConfig

__all__ = ["FitConfig", "MethodOptions", "Products", "fit", "run"]
__version__ = "0.1.0"
