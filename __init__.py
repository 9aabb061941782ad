"""shadowflow: the 3D shape of a face from one photograph, and the photograph without its shadows.

    import shadowflow
    result = shadowflow.fit("face.png")        # normals, depth, albedo, shadow, relit, mesh, history
    result.save("out/face")
    shadowflow.run(["photos/"], "out")         # a stream of files, as ``shadowflow run``

``flow/`` is the dataflow engine (``shadowflow.flow``, knows nothing of faces); ``nodes/`` is the
method and the application (``shadowflow.nodes``). README.md, "Python", has more.
"""
from importlib import import_module

# loaded on first use (PEP 562): ``import shadowflow.flow`` alone, as a recording process does,
# does not load the method, OpenCV and SciPy
_NAMES = {"Products": "nodes.app.api", "fit": "nodes.app.api", "run": "nodes.app.api",
          "MethodOptions": "nodes.method.nodes", "FitConfig": "nodes.method.robust_fit",
          "read_arrays": "nodes.app.outputs"}

__all__ = ["FitConfig", "MethodOptions", "Products", "fit", "read_arrays", "run"]
__version__ = "0.1.0"


def __getattr__(name: str):
    if name in _NAMES:
        value = getattr(import_module(f".{_NAMES[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(list(globals()) + __all__)
