"""The relighting as nodes of the pipeline: ``PhotoRelightNode`` relights each face at the photo's resolution,
``NovelViewNode`` turns it with the albedo measured there; ``face_nodes`` and ``photo_nodes`` are the whole
chains, the method's nodes (``method.nodes``) and then these."""
from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from ...flow.frame import Frame
from ...flow.parts import EachPart
from ..method.nodes import (
    FacesNode,
    FitObserver,
    LoadNode,
    covered_above_eyes,
    method_nodes,
    shading_normals,
)
from ..method.options import MethodOptions
from ..method.products import photo_channels, photo_rgb8
from ..method.quality import EVEN_EXPLAINED, UNEXPLAINED
from ..method.relight import novel_view, resample_surface
from ..method.turned import ViewChoiceNode
from ..model.shape_model import ShapeModel
from ..photo import hair_matte
from ..photo.align import Alignment
from ..photo.encoding import linear_to_srgb
from ..photo.evenness import evenly_lit
from ..photo.mediapipe import person_share
from ..photo.placement import MAX_YAW, FacePlacement
from .compose import FaceLayer, compose
from .face import FaceRelight, light_key
from .face_box import Features
from .foreign import found
from .harm import added_edges, colour_blotches, flattened, harm
from .live import LiveFace
from .products import albedo_on_grid

# an evenly lit face whose relit face would change more than this at a fine scale (``harm``'s H, %) comes back as it
# was (a person called faces bad from 14 %; an evenly lit one relit by a light near its own barely changes)
EVEN_HARM = 8.0
# a face painted over more than this share of it is doubtful: the photo shows less of it than it hides (a render lit
# from 60 degrees without a room light, its far side black, is 42 % painted)
PAINTED_DOUBT = 0.5
# ... judged only on a face turned at most this far (degrees of yaw): the measure's ellipse from the eyes is a frontal
# face's, and a head turned toward the light looks evenly lit whatever the light (a render turned 45 degrees into a
# light from 45 degrees, relit frontally, changed by 13 % with nothing harmed)
EVEN_YAW = 25.0
# a face, under any light, whose relit face would add edges the photo has not and the new light does not make (% of
# the face, ``harm.added_edges``, over the pixels painted less than ``PAINTED_EDGES``: where the photo held too little
# to lift, the fill's shading is new by design) and change its colour at a fine scale (%, ``harm.colour_blotches``) by
# more than ``edges / ADDED_EDGES + blotches / COLOUR_BLOTCHES = 1`` comes back as it was. On the people set relit
# frontally, 10 of the 11 faces seen damaged by hard side light (a painted slab's outline, pasted patches, orange and
# green blotches) read 1.04-2.9 by that sum, the faces seen good or acceptable at most 0.69; the eleventh, a grey wash
# over a black-and-white portrait's shadowed half (``mmpose_indoor_020``), 0.64. Yale B's photos lit from +-50 and
# +-70 degrees, relit frontally, read at most 0.52, and in sRGB colour at most 0.78 (``ADDED_EDGES`` is held up by
# them: at 4.5, their colour copies lit from 70 degrees came back as they were)
ADDED_EDGES = 7.2
COLOUR_BLOTCHES = 14.0
PAINTED_EDGES = 0.5
# a face, under any light, whose relit face would darken more than this share (%) of it where the file is at its top
# (``harm.flattened``: one flat tone where the file cut the photo's texture) comes back as it was. On the people set
# relit frontally, a high-contrast black-and-white portrait's clipped forehead and cheek (``mmpose_indoor_020``, seen
# a grey wash) reads 13.8 %, every other face at most 1.4 %; Yale B's photos from 0 to +-70 degrees at most 1.0 %
FLATTENED = 5.0
# a face whose fit explains little (``quality.UNEXPLAINED``) but whose relit face reads at most this by
# ``ADDED_EDGES`` and ``COLOUR_BLOTCHES``'s sum (and, turned at most ``EVEN_YAW``, changes at a fine scale by at most
# ``EVEN_HARM``) is not doubtful for it: its relighting did it no harm (of the people set's photos, the 9 faces
# doubtful for it, soft-lit, smiling or in glasses, one of them turned 34 degrees, came back cleanly with H 0.6-7.1 %
# and a sum of at most 0.24); its score takes at least ``quality.EVEN_EXPLAINED``, as an evenly lit face's
UNHARMED = 0.5


def face_eyes(frame: Frame) -> np.ndarray | None:
    """(2, 2) the face's eyes in photo pixels: where a face mesh or the eyes given placed them, else None."""
    placement = frame.data.get("placement")
    return None if placement is None or placement.eyes is None else np.asarray(placement.eyes, np.float64)


def face_yaw(frame: Frame) -> float:
    """The head's turn in degrees as its placement read it (0 without a reading)."""
    placement = frame.data.get("placement")
    pose = None if placement is None else getattr(placement, "pose", None)
    return 0.0 if pose is None else float(pose.view[0])


def layer_pair(face: FaceRelight, layer: FaceLayer) -> tuple[np.ndarray, np.ndarray]:
    """(before, after) (h, w, C) linear on ``layer``'s box: the photo there with the shadows the face does not cast
    lifted (``FaceRelight.foreign_lift``: that change is the one asked for, its edges the shadows'), and ``layer``
    put into it."""
    y0, y1, x0, x1 = layer.box
    after = compose(face.layer_photo, [dataclasses.replace(layer, box=(0, y1 - y0, 0, x1 - x0))])
    lift = face.foreign_lift()
    return (face.layer_photo if lift is None else face.layer_photo * lift), after


def made_under(face: FaceRelight, light: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(h, w) float32 each on the layer's box (0 around the face's box), for the face relit by ``light`` (3,): the
    lighting it gives the fit's surface, its cast shadow with it (where the new light's own edges are), and how far
    each pixel was painted (where the photo held too little to lift)."""
    if light_key(light) not in face.made:
        face.relit(light)
    return tuple(face.at.in_layer(np.asarray(v, np.float32)) for v in face.made[light_key(light)])


def damage(report: dict) -> float:
    """``report``'s added edges and colour blotches (``harm_flag``'s figures) over their bounds, summed: above 1 a
    face is given back."""
    return report["added_edges"] / ADDED_EDGES + report["colour_blotches"] / COLOUR_BLOTCHES


def harm_flag(face: FaceRelight, light: np.ndarray, layer: FaceLayer, pair: tuple[np.ndarray, np.ndarray],
              eyes: np.ndarray, report: dict, even: bool) -> str | None:
    """Why the face relit by ``light`` (3,) as ``layer`` would be harmed, ending in ``LEFT``, or None; its
    figures put into ``report``. Over the face's own pixels (``layer.inside``) of the ellipse from ``eyes`` (2, 2)
    photo pixels: under any light, edges the photo has not and the new light does not make (``harm.added_edges``)
    with a change of colour at a fine scale (``harm.colour_blotches``), their sum over ``ADDED_EDGES`` and
    ``COLOUR_BLOTCHES`` above 1, or, over all of the face's pixels, more than ``FLATTENED`` of it darkened where the
    file is at its top (``harm.flattened``); a face lit evenly and turned at
    most ``EVEN_YAW`` (``even``), a change at a fine scale (``harm``'s H above ``EVEN_HARM``). H judges only such
    faces: a strong change of light raises it legitimately (Yale B relit frontally from +-50 and +-70, 21.8 and 19.0
    dB against the real frontal photo, are blotched over 28-54 % of the face)."""
    before, after = pair
    eyes = eyes - [layer.box[2], layer.box[0]]
    # where the photo held too little to lift, the fill's shading and texture are new by design
    shading, painted = made_under(face, light)
    shown = layer.inside & (painted < PAINTED_EDGES)
    edges = added_edges(before, after, eyes, within=shown, new_light=shading)
    blotches = colour_blotches(before, after, eyes, within=layer.inside)
    report.update(added_edges=round(edges, 2), colour_blotches=round(blotches, 2))
    if even:
        h = harm(before, after, eyes, within=layer.inside).h
        report["harm"] = round(h, 2)
        if h > EVEN_HARM:
            return left_flag(h)
    if damage(report) > 1.0:
        return (f"relit it would add edges over {edges:.0f} % of the face and change its colour at a fine scale by "
                f"{blotches:.0f} % (patches, outlines, blotches): {LEFT}")
    # the file's own values (``before`` may have the shadows from elsewhere lifted out of it)
    flat = report["flattened"] = round(flattened(face.layer_photo, after, layer.inside), 2)
    if flat > FLATTENED:
        return (f"relit it would darken {flat:.0f} % of the face where the photo is at its brightest into one flat "
                f"tone (the file does not hold how bright it was): {LEFT}")
    return None


def lit_evenly(face: FaceRelight, layer: FaceLayer, pair: tuple[np.ndarray, np.ndarray], eyes: np.ndarray,
               quality: dict) -> bool:
    """Whether the face is lit evenly (``quality["even"]``), judged, when shadows the face does not cast were lifted
    out of it, on the photo without them (``layer_pair``'s before; ``eyes`` (2, 2) photo pixels): a hand's shadow over
    the lit half of a face lit from 25 deg evens its halves, and the change of light that asks for is no harm."""
    if face.shown_light.foreign_lift is None:
        return bool(quality.get("even"))
    return evenly_lit(pair[0], eyes - [layer.box[2], layer.box[0]])


def _unharmed_fit(layer: FaceLayer, pair: tuple[np.ndarray, np.ndarray], eyes: np.ndarray, report: dict,
                  quality: dict, frontal: bool) -> None:
    """``quality`` without the doubt of a fit that explains little (``quality.UNEXPLAINED``) when the face relit as
    ``layer`` shows no harm (``UNHARMED``; a ``frontal`` face's H at most ``EVEN_HARM`` too, which ``report`` gets: a
    turned one's ellipse is no frontal face's, and H reads its change of light as harm): the flag taken off, its score
    undone and raised to at least ``EVEN_EXPLAINED`` (halved by each flag left)."""
    flags = quality.get("flags", [])
    kept = [f for f in flags if not f.startswith(UNEXPLAINED)]
    if len(kept) == len(flags) or damage(report) > UNHARMED:
        return
    if frontal:
        if "harm" not in report:
            report["harm"] = round(harm(*pair, eyes - [layer.box[2], layer.box[0]], within=layer.inside).h, 2)
        if report["harm"] > EVEN_HARM:
            return
    score = float(quality.get("score", 0.0)) * 2.0 ** (len(flags) - len(kept))
    quality["flags"], quality["score"] = kept, round(max(score, EVEN_EXPLAINED * 0.5 ** len(kept)), 3)


def left_flag(h: float) -> str:
    """The quality flag of a face left as it was because relit it would change by ``h`` % (``harm``'s H)."""
    return f"lit evenly, yet relit it would change by {h:.0f} % at a fine scale: {LEFT}"


LEFT = "left as it was"


def left_as_it_was(frame: Frame) -> bool:
    """Whether the face ``frame`` comes back as it was (``PhotoRelightNode``'s honesty step, or ``leave``)."""
    return any(f.endswith(LEFT) for f in (frame.meta.get("quality") or {}).get("flags", []))


def leave(frame: Frame, photo: np.ndarray, why: str) -> None:
    """The face ``frame`` made to come back as it was (``photo`` (H, W, C) linear, the whole photo), ``doubtful``
    with ``why`` (ending in ``LEFT``), its score halved as the honesty step's flags halve it; its relit layers kept
    (``photo_layers_relit``) so it can be relit again (``relight_again``)."""
    d, quality = frame.data, frame.meta.setdefault("quality", {})
    d["photo_layers_relit"] = d["photo_layers"]
    d["photo_layers"] = [(light, unchanged(layer, np.atleast_3d(photo[layer.box[0]:layer.box[1],
                                                                        layer.box[2]:layer.box[3]])))
                         for light, layer in d["photo_layers"]]
    quality["flags"] = [*quality.get("flags", []), why]
    quality["score"] = round(float(quality.get("score", 0.0)) * 0.5, 3)


def relight_again(frame: Frame) -> None:
    """The face ``frame``, left as it was, given its relit layers back: the flag saying so taken off and its score
    restored (the inverse of ``leave`` and of the honesty step)."""
    d, quality = frame.data, frame.meta.get("quality") or {}
    d["photo_layers"] = d.pop("photo_layers_relit")
    kept = [f for f in quality.get("flags", []) if not f.endswith(LEFT)]
    quality["score"] = round(float(quality.get("score", 0.0)) * 2.0 ** (len(quality.get("flags", [])) - len(kept)), 3)
    quality["flags"] = kept


def shown_share(layer: FaceLayer, photo: np.ndarray, share: float) -> FaceLayer:
    """``layer`` shown ``share`` (0-1) of the way from the photo as it was (``photo`` (H, W, C) linear, the whole
    photo) to it: its relit face and its gain blended so."""
    y0, y1, x0, x1 = layer.box
    crop = np.atleast_3d(photo[y0:y1, x0:x1]).astype(np.float32)
    s = np.float32(share)
    return FaceLayer(layer.box, layer.inside, s * layer.relit + (np.float32(1.0) - s) * crop,
                     s * layer.gain + (np.float32(1.0) - s), layer.alpha)


def unchanged(layer: FaceLayer, photo: np.ndarray) -> FaceLayer:
    """``layer`` made to leave its box of the photo (``photo`` (h, w, C), linear) as it is."""
    return FaceLayer(layer.box, layer.inside, np.asarray(photo, np.float32), np.ones_like(layer.gain), None)


class PhotoRelightNode:
    """The face relit at the photo's own resolution, in colour when the input is (``face.FaceRelight``), all of it
    in the box around the face (plus the feather): the albedo and shadows there (``photo_albedo``,
    ``photo_shadow``, ``photo_box``), one ``FaceLayer`` per light (``relight_light``, then each of
    ``extra_lights``) for ``compose`` to put into the photo, and what the relighting did (``meta["relight"]``). With
    ``foreign_shadows``, the shadows the face does not cast too (``meta["foreign_shadows"]``: how many and their share
    of the face; ``photo_foreign``: how far each pixel of the box is in them). The face's own exposure is kept, and
    nothing beyond the face's feather changes."""

    name = "relight_photo"
    thread_safe = True  # a function of the frame (the nets it runs are lent one caller at a time): ``--workers``

    def __init__(self, options: MethodOptions):
        self.options = options

    def __call__(self, frame: Frame) -> Frame:
        d = frame.data
        face = self.face_relight(frame)
        layers, reports = [], []
        for light in (self.options.relight_light, *self.options.extra_lights):
            layers.append((np.asarray(light, np.float64), face.layer(light)))
            reports.append(face.report)
        report = {k: round(float(v), 4) for k, v in reports[0].items()}
        quality = frame.meta.get("quality")
        if quality is not None:
            layers = self._honest(frame, face, layers, report, quality)
        d.update(photo_box=face.box, photo_albedo=face.albedo, photo_shadow=face.shadow, photo_layers=layers)
        frame.meta["relight"] = report
        if self.options.foreign_shadows:
            frame.meta["foreign_shadows"] = found(face.shown_light.evidence.foreign, face.at.face, face.iod)
            d["photo_foreign"] = face.shown_light.evidence.foreign
        d["live"] = face.live_data  # made when a page asks (``live_face``): a clip's frames have none of their own
        return frame

    @staticmethod
    def _honest(frame: Frame, face: FaceRelight, layers: list, report: dict, quality: dict) -> list:
        """The face's layers, or its photo as it was when the relighting would harm it (``harm_flag``): then the
        face is ``doubtful`` with why, its relit layers kept for a clip's frames after (``app.steady``); else a fit
        that explains little is no doubt if its relit face shows no harm (``_unharmed_fit``). A face painted over
        more than ``PAINTED_DOUBT`` of it is ``doubtful`` too. The flags go into ``quality`` (its score halved by
        each, as ``quality.assess``'s), the figures into ``report``."""
        flags = []
        eyes = face_eyes(frame)
        frontal = abs(face_yaw(frame)) <= EVEN_YAW
        why = None
        if eyes is not None:
            light, layer = layers[0]
            pair = layer_pair(face, layer)  # (the photo and the relit face, once for both judgements)
            why = harm_flag(face, light, layer, pair, eyes, report, lit_evenly(face, layer, pair, eyes, quality)
                            and frontal)
            if why is None and abs(face_yaw(frame)) <= MAX_YAW:
                _unharmed_fit(layer, pair, eyes, report, quality, frontal)
        if why is not None:
            flags.append(why)
            frame.data["photo_layers_relit"] = layers
            layers = [(light, unchanged(layer, face.layer_photo)) for light, layer in layers]
        if report.get("painted", 0.0) > PAINTED_DOUBT:
            flags.append(f"{100 * report['painted']:.0f} % of the face painted: the photo shows too little of it")
        if flags:
            quality["flags"] = [*quality.get("flags", []), *flags]
            quality["score"] = round(float(quality.get("score", 0.0)) * 0.5 ** len(flags), 3)
        return layers

    def face_relight(self, frame: Frame) -> FaceRelight:
        """The frame's entries as ``FaceRelight``'s arrays."""
        d = frame.data
        m = d["model"]
        al: Alignment = d["alignment"]
        placement: FacePlacement | None = d.get("placement")
        meshed = placement is not None and bool(placement.outlines)
        # only eyes the face mesh found in the photo get their detail back; its eye openings, not the model's
        # eye points (only where the placement put the iris centres)
        eyes = None
        if d.get("eyes_found") in ("detected", "mesh only"):
            eyes = placement.eyes if meshed else al.points_to_input(m.eyes)
        # a frontal or tilted face's symmetry axis: the model's, across its eyes' midpoint; a turned face's mirror is
        # a map on the model grid, which the fit's albedo uses: its photo gets no detail from across the face
        iod = m.iod  # model pixels
        midline = None
        if m.mirrors_by_column:
            centre = np.mean(m.eyes, axis=0)
            midline = al.points_to_input(np.array([centre, centre + [0.0, iod]]))
        encoding = frame.meta.get("encoding", "linear")
        features = None
        if meshed:
            outlines = placement.outlines
            features = Features(eyes=list(outlines.get("eyes", [])), brows=list(outlines.get("brows", [])),
                                lips=[*outlines.get("lips", []), *outlines.get("mouth", [])],
                                nostrils=list(outlines.get("nostrils", [])))
        return FaceRelight(
            photo=photo_channels(frame), alignment=al, mask=m.mask, normals=shading_normals(frame),
            lit=d["shadow"].lit, albedo=d["albedo"], depth=d["depth"], light=d["light"], iod_px=iod * al.scale,
            encoding=encoding, outline=placement.outlines["oval"][0] if meshed else None, eyes=eyes,
            eye_contrast=self.options.eye_contrast, midline=midline, fill_detail=self.options.fill_detail,
            mirror_lift=self.options.mirror_lift, mirror=None if m.mirrors_by_column else m.mirror,
            features=features, segment=person_segmenter(encoding), hair=covered_above_eyes(frame, m),
            hair_matte=hair_segmenter(frame),
            model_normals=foreign_cue(frame) if self.options.foreign_shadows else None)


def live_face(frame: Frame) -> LiveFace | None:
    """The face ``frame``'s ``LiveFace`` (what view.html relights it with), made the first time it is asked for: its
    arrays took an eighth of a webcam frame's relighting, and a clip's frames write no page unless asked
    (``--frames``); None for a face not relit."""
    live = frame.data.get("live")
    if callable(live):
        live = frame.data["live"] = live()
    return live


def foreign_cue(frame: Frame) -> np.ndarray | None:
    """(Hm, Wm, 3) the fitted model's own normals (model camera frame), against whose shading the shadows the face
    does not cast are found (``shown_light.ShownLight``); None without a fit."""
    fit = frame.data.get("fit")
    return None if fit is None else frame.data["model"].to_image(fit.model_normals.astype(np.float32))


def hair_segmenter(frame: Frame) -> Callable[[tuple], np.ndarray] | None:
    """A face's box ``(y0, y1, x0, x1)`` of ``frame``'s photo -> (h, w) how sure MediaPipe's hair segmentation is that
    each pixel there is hair (``hair_matte.hair_in_box``: the head around the box shown to it as the face finder's
    nets see the photo, ``photo_rgb8``); None where it cannot run (no LiteRT) or for a grey photo: without colour it
    takes a side light's deep shadows for hair (a cast shadow across a Yale B cheek, the shade beside a nose)."""
    if not hair_matte.available() or np.shape(photo_channels(frame))[-1] != 3:
        return None
    rgb8 = photo_rgb8(frame)
    return lambda box: hair_matte.hair_in_box(rgb8, box)


def person_segmenter(encoding: str) -> Callable[[np.ndarray], np.ndarray]:
    """(h, w, C) linear photo -> (h, w) how sure MediaPipe's selfie segmentation is that each pixel is the person
    (``mediapipe.person_share``), the photo shown to it as its file holds it (sRGB-encoded for an sRGB photo)."""
    to_display = linear_to_srgb if encoding == "srgb" else None
    return lambda linear: person_share(linear, to_display)


class NovelViewNode:
    """The surface turned ``novel_yaw_deg`` about the vertical axis (``method.relight.novel_view``), with the
    albedo measured on the photo (colour for a colour photo: ``photo_albedo``, brought to the model grid):
    the face within its own outline, not the hair, ears or background the model grid reaches beyond it."""

    name = "novel_view"

    def __init__(self, options: MethodOptions):
        self.options = options

    def __call__(self, frame: Frame) -> Frame:
        d = frame.data
        albedo, depth = d["albedo"], d["depth"]
        if "photo_albedo" in d:
            measured = albedo_on_grid(d["photo_albedo"], d["photo_box"], d["alignment"],
                                      d["model"].grid)
            depth = np.where(np.isfinite(measured[..., 0]), depth, np.nan)
            albedo = measured[..., 0] if measured.shape[-1] == 1 else measured
        if self.options.novel_size is not None:  # rendered from the surface resampled to the size asked for
            depth, albedo = resample_surface(depth, albedo, self.options.novel_size)
        d["novel_view"] = novel_view(depth, albedo, self.options.novel_yaw_deg)
        return frame


def face_nodes(options: MethodOptions, observer: FitObserver | None = None, with_views: bool = True) -> list:
    """A face's nodes after loading: the method's (``method_nodes``), then, ``with_views``, the face relit at the
    photo's resolution and turned (``PhotoRelightNode``, ``NovelViewNode``)."""
    nodes = method_nodes(options, observer, with_views)
    if with_views:
        nodes += [PhotoRelightNode(options), NovelViewNode(options)]
    return nodes


def photo_nodes(model: ShapeModel, options: MethodOptions, observer: FitObserver | None = None,
                with_views: bool = True, after: tuple = (), after_faces: tuple = ()) -> list:
    """The whole chain for a photo: load, find its faces, the method on each face (``face_nodes``, then each of
    ``after``, e.g. recording). With ``with_views`` each face's relit layers are made (``photo_layers``); the photo
    relit with every face is made from them when asked (``products.relit_photo``). ``after_faces``: nodes on the
    whole frame once its faces are found (a clip's steadying)."""
    faces = FacesNode(model, options)
    # a turned face's candidate views, each fitted once without an observer (``turned.ViewChoiceNode``)
    choice = ViewChoiceNode(faces.again, method_nodes(options, None, False)[:3], model, options.face_length)
    per_face = [choice, *face_nodes(options, observer, with_views), *after]
    return [LoadNode(options), faces, *after_faces, *(EachPart(n) for n in per_face)]
