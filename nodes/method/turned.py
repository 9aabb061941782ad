"""Turned heads: a face the landmarks find turned is fitted with the model whose training heads are turned
as it is (``model.default_model.turned_model``), placed on that model's grid by the same landmarks seen at
that view. A model 10 degrees off the head's yaw costs the normals 5 degrees, and the landmarks' yaw leans away
from a side light while the fit's leans toward it (docs/accuracy.md, "Turned heads"), so a face read turned,
or near frontal under a side light, is fitted at the views around its reading (``default_model.views_near``, then
further out while the last view explains the photo best), and its yaw read as the mean of the landmarks' and of
the view that explains the photo best (``misfits``, ``ViewChoiceNode``); it is fitted with the view of that yaw.
A face's model is chosen once, when its frame is made (``face_model``: the frame's view is
``meta["model_view"]``), and travels with it as ``data["model"]``."""
from __future__ import annotations

import dataclasses

import cv2
import numpy as np

from ...flow.frame import Frame, FrameFailed
from ..model.default_model import MEASURED_VIEW_YAW, VIEW_STEP, turned_model, view_of, views_near
from ..model.shape_model import ShapeModel
from ..photo.faces import Pose
from ..photo.placement import TURN_DOUBT, FacePlacement, outline_on_grid, place_found, pose_doubts

# measured this close to frontal (degrees of yaw), a face is fitted frontally only. The fit's scale tells a turned
# render's views apart, but not a real frontal face's: on Yale B (measured within 4.5 deg of frontal) choosing
# between views 5 deg apart cost the normals 0.3-1.2 deg (docs/accuracy.md, "Turned heads"); and the frontal
# path keeps its speed
FRONTAL_YAW = 7.5
# ... unless it is read tilted this far (degrees of pitch): level faces read within 10 deg (Yale B -8...+5, renders
# 0...+6), a misplaced upside-down face at -15, while a head tilted 20 deg and fitted frontally is 6-8 deg worse than
# with its pitched view (docs/accuracy.md, "Turned heads")
FRONTAL_PITCH = 17.5
# a light this close to the view axis (degrees) moves no landmark: a face read near frontal under it is left as read
FRONTAL_LIGHT = 15.0
# views tried beyond the candidates, at most, while the least misfit is the last view tried
EXTRA_VIEWS = 3
# a face's views must share this many model pixels to be compared
MIN_COMMON = 200


def turned_placements(model: ShapeModel, placement: FacePlacement, shape: tuple[int, int],
                      face_length: str | float, note=None) -> list[FacePlacement]:
    """The placements of a found face to fit (``placement`` itself first when it is frontal enough): one per
    view near its pose (``views_near``), each on the grid of ``model`` turned so; read within ``FRONTAL_YAW`` of
    frontal in yaw and ``FRONTAL_PITCH`` in pitch, ``placement`` and the views either side of it
    (``ViewChoiceNode`` fits them only under a side light). Just ``placement`` when it is refused, not placed by
    landmarks, or ``model`` has no turned views (a model file: fitted frontally, doubtful beyond its reach).
    ``note`` is given the cache file of each view's model this builds (once per view and process, about two
    seconds each)."""
    if placement.face is None or placement.pose is None or placement.refused:
        return [placement]
    yaw, pitch = placement.pose.view
    views = views_near(yaw, pitch)
    # a little pitch alone is not turned: a misplaced face (nostrils for eyes) read -15 deg was fitted "ok" by a
    # pitched view where the frontal fit refused it
    if _near_frontal((yaw, pitch)):
        views = [(0.0, 0.0)] + [v for v in views_near(0.0, 0.0) if v != (0.0, 0.0)]
    out = []
    for view in views:
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


def _shading_on(trial: Frame, model: ShapeModel) -> tuple[np.ndarray, np.ndarray]:
    """(Hm, Wm) the shading a fitted face's on-cone normals give under its light, 0 off its model, and (Hm, Wm)
    float, 1 where it is known: what the fit says the photo shows, on its own model grid."""
    r = trial.data["fit"]
    shading = np.zeros(model.grid, np.float32)
    shading[model.mask] = np.clip(r.normals @ np.asarray(trial.data["grid_light"], np.float64), 0.0, None)
    return shading, model.mask.astype(np.float32)


def misfits(trials: dict[float, tuple[Frame, ShapeModel]], reference: Frame, region: np.ndarray) -> dict[float, float]:
    """How ill each fitted view explains the photo: per view (its yaw), the median absolute difference between the
    photo's brightness and the gain and offset of its fitted shading that fit it best (``_shading_on``), over the
    ``region`` (Hm, Wm) bool of the ``reference`` trial's model grid that every view covers. Each view's shading is
    brought onto that grid through the photo (its placement, then the reference's). The median leaves out what no
    shape explains (the eyes, brows and lips), and the gain and offset the brightness scale and the room's light."""
    grid = reference.data["grid_image"].shape
    ref = np.vstack([reference.data["alignment"].matrix, [0.0, 0.0, 1.0]])
    warped, common = {}, region.copy()
    for yaw, (trial, model) in trials.items():
        shading, known = _shading_on(trial, model)
        to_view = np.vstack([cv2.invertAffineTransform(trial.data["alignment"].matrix), [0.0, 0.0, 1.0]]) @ ref
        flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
        warped[yaw] = cv2.warpAffine(shading, to_view[:2], (grid[1], grid[0]), flags=flags)
        common &= cv2.warpAffine(known, to_view[:2], (grid[1], grid[0]), flags=flags) >= 0.999
    photo = np.asarray(reference.data["grid_image"], np.float64)[common]
    out = {}
    for yaw, shading in warped.items():
        a = np.column_stack([shading[common], np.ones(int(common.sum()))])
        coef = np.linalg.lstsq(a, photo, rcond=None)[0] if len(photo) >= MIN_COMMON else np.zeros(2)
        out[yaw] = float(np.median(np.abs(photo - a @ coef))) if len(photo) >= MIN_COMMON else float("inf")
    return out


def least_misfit_yaw(scores: dict[float, float]) -> float:
    """The yaw (degrees) where the views' misfits (``misfits``, views ``VIEW_STEP`` apart) are least: the vertex of
    the parabola through the least and its two neighbours, or the least itself at the end of the views."""
    yaws = sorted(scores)
    k = int(np.argmin([scores[y] for y in yaws]))
    if k == 0 or k == len(yaws) - 1:
        return yaws[k]
    a, b, c = (scores[yaws[i]] for i in (k - 1, k, k + 1))
    curve = a - 2.0 * b + c
    return yaws[k] + (0.5 * (a - c) / curve * (yaws[k + 1] - yaws[k]) if curve > 0 else 0.0)


class ViewChoiceNode:
    """Reads a found face's turn with its fit, and fits it with the view that explains it best. The landmarks' yaw
    leans away from a side light (renders of another face model: up to 5 deg at 45 deg of light, and short of the
    turn by 4-9 deg at 50 deg), the fit's toward it: each candidate view (``data["view_candidates"]``,
    ``turned_placements``) is remapped, started and fitted (``fit_nodes``, no observer: the fit that counts runs
    again in the chain, recorded), then views further out while the least misfit (``misfits``) is the last tried;
    the face's yaw is the mean of the landmarks' and the least misfit's (``least_misfit_yaw``), its view the one
    of least misfit (frontal when the landmarks read it within ``FRONTAL_YAW``). A face read near frontal
    under a light near the view axis is left as the landmarks read it (they lean only under a side light), as is
    one read near frontal on a clip's frame that is not to read its view again (``meta["view_refresh"]`` False). The
    frame is then that view's face as ``make_face`` made it, its pose's yaw the one read so, with
    ``meta["view_choice"]``: each view tried and its misfit, and ``meta["yaw_read"]``: the landmarks' and the fit's
    yaw; turned past ``placement.MAX_YAW``, it is refused."""

    name = "view_choice"
    thread_safe = True

    def __init__(self, make_face, fit_nodes: list, model: ShapeModel | None = None, face_length: str | float = "auto"):
        self.make_face, self.fit_nodes, self.model, self.face_length = make_face, fit_nodes, model, face_length

    def __call__(self, frame: Frame) -> Frame:
        candidates = frame.data.pop("view_candidates", None)
        if not candidates or self.model is None:
            return frame
        first = candidates[0]
        if _near_frontal(first.pose.view) and (_light_off_axis(frame.data["light"]) < FRONTAL_LIGHT
                                               or frame.meta.get("view_refresh") is False):
            # fitted frontally whatever the fit reads: what the trials would give is the yaw read alone, which a
            # clip's face reads on some of its frames and carries to the others (``app.steady``)
            return frame
        placements = {p.view[0]: p for p in candidates}
        trials = self._tried(frame, placements)
        if not trials:
            return frame
        scores = _scores(trials, first.view[0])
        for _ in range(EXTRA_VIEWS):
            further = _further(scores)
            if further is None or further in trials:
                break
            placements[further] = self._placed(frame, first, (further, first.view[1]))
            trials.update(self._tried(frame, {further: placements[further]}))
            scores = _scores(trials, first.view[0])
        return self._chosen(frame, first, scores)

    def _tried(self, frame: Frame, placements: dict) -> dict[float, tuple[Frame, ShapeModel]]:
        """Each placement's face made and fitted (``fit_nodes``), by its view's yaw; those whose fit fails left out."""
        out = {}
        for yaw, placement in placements.items():
            trial = self.make_face(frame, placement)
            try:
                for node in self.fit_nodes:
                    trial = node(trial)
            except (FrameFailed, ValueError, FloatingPointError):
                continue
            out[yaw] = (trial, trial.data["model"])
        return out

    def _placed(self, frame: Frame, found: FacePlacement, view: tuple[float, float]) -> FacePlacement:
        """``found``'s face placed for ``view``'s model (a model built here is added to the frame's
        ``meta["models_built"]``, for the run to say)."""
        if view == (0.0, 0.0):
            return place_found(self.model, found.face, frame.data["image"].shape, self.face_length)
        built = frame.meta.setdefault("models_built", [])
        model = turned_model(self.model, view, lambda path: built.append(str(path)))
        return place_found(model, found.face, frame.data["image"].shape, self.face_length)

    def _chosen(self, frame: Frame, first: FacePlacement, scores: dict[float, float]) -> Frame:
        """The face made again with the view of the yaw read (landmarks and fit), its pose so, or refused."""
        pose, fitted = first.pose, least_misfit_yaw(scores)
        yaw = 0.5 * (pose.yaw + fitted)
        read = Pose(float(yaw), pose.pitch, pose.roll)
        # fitted with the view that explains it best (the normals follow the shading, not the yaw read): Surrey faces
        # turned -30 deg under a light from +45 read -27...-30 and were 11.8 deg off with that view, 9.7 with the best
        best = min(scores, key=scores.get)
        # one the landmarks read near frontal is fitted frontally all the same: on Yale B (real frontal faces) under
        # lights from +-50 and +-70 deg the fit's yaw reads up to 15-20 deg, and their turned views cost the normals
        # 1.1 and 3.2 deg on average (docs/accuracy.md, "Turned heads")
        view = (0.0, 0.0) if _near_frontal(pose.view) else view_of(best, pose.pitch)
        placement = self._placed(frame, first, view)
        # the turn's refusal and doubts are the yaw read's, not the landmarks' alone
        refused, turned = pose_doubts(read, view == (0.0, 0.0))
        doubts = tuple(d for d in placement.doubts if not d.startswith(TURN_DOUBT)) + tuple(turned)
        placement = dataclasses.replace(placement, pose=read, refused=refused, doubts=doubts)
        made = self.make_face(frame, placement)
        if frame.meta.get("models_built"):
            made.meta["models_built"] = frame.meta["models_built"]
        made.meta["view_choice"] = {f"{y:+.0f},{first.view[1]:+.0f}": round(v, 6) for y, v in sorted(scores.items())}
        made.meta["yaw_read"] = {"landmarks": round(pose.yaw, 2), "fit": round(fitted, 2)}
        return made


def _scores(trials: dict[float, tuple[Frame, ShapeModel]], yaw: float) -> dict[float, float]:
    """``misfits`` of the ``trials`` on the grid of the one nearest ``yaw``, over the face's whole outline there."""
    reference, model = trials[min(trials, key=lambda y: abs(y - yaw))]
    region = outline_on_grid(reference.data["placement"], model, reference.data["image"].shape, "oval") & model.mask
    return misfits(trials, reference, region)


def _near_frontal(view: tuple[float, float]) -> bool:
    """Whether a head read at ``view`` (yaw, pitch) is fitted frontally (``FRONTAL_YAW``, ``FRONTAL_PITCH``)."""
    return abs(view[0]) < FRONTAL_YAW and abs(view[1]) < FRONTAL_PITCH


def _light_off_axis(light) -> float:
    """Degrees between the light (3,) and the view axis."""
    s = np.asarray(light, np.float64)
    return float(np.degrees(np.arccos(np.clip(s[2] / max(np.linalg.norm(s), 1e-12), -1.0, 1.0))))


def _further(scores: dict[float, float]) -> float | None:
    """The view beyond the end of those tried whose misfit is least, when it is at an end and within reach."""
    yaws = sorted(scores)
    k = int(np.argmin([scores[y] for y in yaws]))
    if 0 < k < len(yaws) - 1:
        return None
    step = VIEW_STEP if k == len(yaws) - 1 else -VIEW_STEP
    further = yaws[k] + step + 0.0
    return further if abs(further) <= MEASURED_VIEW_YAW else None
