"""The method's recorded channels (``<node>/<name>``), named once: the recorder writes them
(``record.py``), the Rerun layout shows them (``blueprint.py``), ``replay`` tables and plots them.
Constants only, so the recording process reads them without loading the method."""
from __future__ import annotations

# per fit iteration (``record.FitRecorder``)
FIT_NORMALS = "robust_fit/normals"
FIT_MODEL_NORMALS = "robust_fit/model_normals"
FIT_WEIGHTS = "robust_fit/weights"
FIT_RESIDUALS = "robust_fit/residuals"
FIT_COEFFICIENTS = "robust_fit/b"
CONVERGENCE = "robust_fit/convergence"  # the fit's scalars (``FitIteration.scalars``)

# once per face (``record.RecordNode``)
GRID_IMAGE = "load/grid_image"
REMAPPED = "remap/remapped"
INITIAL_NORMALS = "sfs_init/normals"
FINAL_NORMALS = "combine/normals"
DEPTH = "integrate/depth"
MESH = "integrate/mesh"
CAST_SHADOW = "shadow/cast"
ATTACHED_SHADOW = "shadow/attached"
# with ``foreign_shadows``: how far each pixel is in the shadows the face does not cast (a brim's, a hand's)
FOREIGN_SHADOW = "shadow/foreign"
ALBEDO = "albedo/albedo"
RELIT = "relight/relit"
NOVEL_VIEW = "relight/novel_view"

# the convergence scalars, each with its label (and unit): ``replay --plot``'s panels and the viewer's plots
CONVERGENCE_LABELS = {"sigma": "robust scale σ (radians)", "change_deg": "mean change of the normals (degrees)",
                      "residual_mean": "mean residual (radians)"}
CONVERGENCE_PLOTS = tuple(CONVERGENCE_LABELS)
# scalars that flag an iteration, marked on the convergence plots: the fit's albedo measured again (its smooth-albedo
# round) moves the cones, and the change of the normals and the residuals jump there
CONVERGENCE_MARKS = {"albedo_round": "albedo measured again"}
