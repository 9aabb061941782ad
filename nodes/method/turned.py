"""Turned heads: a face the landmarks find turned is fitted with the model whose training heads are turned
as it is (``model.default_model.turned_model``), placed on that model's grid by the same landmarks seen at
that view. The landmarks' yaw is good to a few degrees, and a model 10 degrees off the head's yaw costs the
normals 5 degrees (docs/accuracy.md, "Turned heads"), so a face measured turned is fitted at its nearest
view and at the views either side (``default_model.views_near``), and the fit that explains the photo best
(the least robust scale of its residuals, ``final_sigma``) decides (``ViewChoiceNode``). Every node of a
face's fit asks ``face_model`` for its model: the frame's view is ``meta["model_view"]``."""
from __future__ import annotations

from ...flow.frame import Frame, FrameFailed
from ..model.default_model import turned_model, views_near
from ..model.shape_model import ShapeModel
from ..photo.placement import FacePlacement, place_found

# measured this close to frontal (degrees of yaw), a face is fitted frontally only. The fit's scale tells a turned
# render's views apart, but not a real frontal face's: on Yale B (measured within 4.5 deg of frontal) choosing
# between views 5 deg apart cost the normals 0.3-1.2 deg (docs/accuracy.md, "Turned heads"); and the frontal
# path keeps its speed
FRONTAL_YAW = 7.5
# ... unless it is read tilted this far (degrees of pitch): level faces read within 10 deg (Yale B -8...+5, renders
# 0...+6), a misplaced upside-down face at -15, while a head tilted 20 deg and fitted frontally is 6-8 deg worse than
# with its pitched view (docs/accuracy.md, "Turned heads")
FRONTAL_PITCH = 17.5


def turned_placements(model: ShapeModel, placement: FacePlacement, shape: tuple[int, int],
                      face_length: str | float, note=None) -> list[FacePlacement]:
    """The placements of a found face to fit (``placement`` itself first when it is frontal enough): one per
    view near its pose (``views_near``), each on the grid of ``model`` turned so. Just ``placement`` when it
    is refused, read within ``FRONTAL_YAW`` of frontal in yaw and ``FRONTAL_PITCH`` in pitch, not placed by landmarks,
    or ``model`` has no turned views (a model file: fitted frontally, doubtful beyond its reach). ``note`` is given the
    cache file of each view's model this builds (once per view and process, about two seconds each)."""
    if placement.face is None or placement.pose is None or placement.refused:
        return [placement]
    yaw, pitch = placement.pose.view
    # a little pitch alone is not turned: a misplaced face (nostrils for eyes) read -15 deg was fitted "ok" by a
    # pitched view where the frontal fit refused it
    if abs(yaw) < FRONTAL_YAW and abs(pitch) < FRONTAL_PITCH:
        return [placement]
    out = []
    for view in views_near(yaw, pitch):
        turned = model if view == (0.0, 0.0) else turned_model(model, view, note)
        if turned is None:
            return [placement]
        out.append(placement if view == (0.0, 0.0) else place_found(turned, placement.face, shape, face_length))
    return out


def face_model(frame: Frame, model: ShapeModel) -> ShapeModel:
    """The model a face's frame is fitted with: ``model`` turned to the frame's ``meta["model_view"]``."""
    view = frame.meta.get("model_view")
    if not view or model.view == (float(view[0]), float(view[1])):  # frontal, or ``model`` is the turned one
        return model
    turned = turned_model(model, (float(view[0]), float(view[1])))
    if turned is None:
        raise ValueError(f"{frame.source}: placed for a turned model that {model.source!r} has no view of")
    return turned


class ViewChoiceNode:
    """Of a face's candidate placements (``data["view_candidates"]``, ``turned_placements``), keeps the one
    whose fit explains the photo best: each is remapped, started and fitted (``fit_nodes``, no observer: the
    fit that counts runs again in the chain, recorded) and the least ``final_sigma`` wins. The frame is
    then the winner's face as ``make_face`` made it, with ``meta["view_choice"]``: each view tried and its
    sigma."""

    name = "view_choice"
    thread_safe = True

    def __init__(self, make_face, fit_nodes: list):
        self.make_face, self.fit_nodes = make_face, fit_nodes

    def __call__(self, frame: Frame) -> Frame:
        candidates = frame.data.pop("view_candidates", None)
        if not candidates:
            return frame
        tried: dict[str, float] = {}
        best, best_sigma = None, float("inf")
        for placement in candidates:
            trial = self.make_face(frame, placement)
            before = dict(trial.data), dict(trial.meta)  # the face before its fit (the nodes only add entries)
            try:
                for node in self.fit_nodes:
                    trial = node(trial)
            except (FrameFailed, ValueError, FloatingPointError):
                continue
            sigma = float(trial.meta["final_sigma"])
            tried[f"{placement.view[0]:+.0f},{placement.view[1]:+.0f}"] = round(sigma, 6)
            if sigma < best_sigma:
                best, best_sigma = before, sigma
        if best is None:
            return frame
        frame.data, meta = best
        frame.meta.pop("model_view", None)
        frame.meta.update(meta, view_choice=tried)
        return frame
