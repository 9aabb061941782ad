"""The method as a chain of small nodes. Each node reads named entries of ``frame.data``,
calls one pure function of arrays, and stores its products: the entries and who writes them
are the table of ``keys``. ``method_nodes`` is the chain after loading; ``LoadNode`` reads a
photo, ``on_model_grid`` makes the frame of an image already on the model grid.
"""
from __future__ import annotations

from typing import Protocol

import numpy as np

from ...flow.frame import Frame, FrameFailed
from ..model.shape_model import ShapeModel
from ..photo.align import IDENTITY, Alignment, inside_input, to_model_grid
from ..photo.cover import covered_on_grid
from ..photo.evenness import evenly_lit
from ..photo.follow import FaceFollower
from ..photo.given import given_eyes, known_light
from ..photo.input_error import InputError
from ..photo.loader import MIN_SIDE, Photo, photo_from_samples, read_photo
from ..photo.placement import FacePlacement, face_on_grid, features_on_grid, model_box, place_faces
from ..photo.sidecar import read_sidecar
from ..photo.skin import skin
from .albedo import FILL_CEILING, estimate_albedo
from .light import light_on_face
from .options import INTEGRATORS, MethodOptions
from .products import photo_channels, photo_rgb8
from .quality import (EYEWEAR_MARGIN, NO_FACE, TRACKED_FACE, assess, core_face, explained_variance, grown_region,
                      unread_weights)
from .relight import relight
from .remap import SATURATION, clipped_pixels, expected_peak_shading, lambertian_remap, ratio_scale
from .robust_fit import FitConfig, FitIteration, combine, fit, initial_normals
from .shadow import NEAR_CAST_MOUTH, confirm_with_image, far_darker, near_cast, shadow_maps
from .turned import face_model, turned_placements

HAIR_BELOW_EYES = 0.25  # interocular distances below the eyes' row that hair over a temple may reach


class FitObserver(Protocol):
    """Sees a frame's fit: every iteration, then the end of the fit (``RobustFitNode``)."""

    def iteration(self, frame: Frame, it: FitIteration) -> None: ...

    def finish(self, frame: Frame) -> None: ...


def on_model_grid(fid: int, source: str, image: np.ndarray, light: np.ndarray, model: ShapeModel) -> Frame:
    """The frame of an image already on the model grid (a render, a benchmark scene): the entries
    ``LoadNode`` would write, with the identity alignment. image: (Hm, Wm) in [0, 1]; light: (3,)
    unit, camera frame; model: the model whose grid the image is on, which the face is fitted with. Run
    ``method_nodes`` on it."""
    return Frame(fid, source, data={"image": image, "light": light, "alignment": IDENTITY, "grid_image": image,
                                    "grid_light": light, "model": model})


def seen_pixels(frame: Frame, model: ShapeModel) -> np.ndarray:
    """(N,) bool over the model pixels: those the photo shows (all when the frame was put on the
    model grid without ``LoadNode``'s ``grid_valid``, e.g. a render)."""
    valid = frame.data.get("grid_valid")
    return np.ones(model.n_pixels, bool) if valid is None else valid[model.mask]


def covered_mask(frame: Frame, model: ShapeModel) -> np.ndarray:
    """(N,) bool over the model pixels: those the photo shows that hair or a dark head covers
    (``photo.cover``; none without ``grid_covered``)."""
    grid = frame.data.get("grid_covered")
    return np.zeros(model.n_pixels, bool) if grid is None else grid[model.mask]


def covered_above_eyes(frame: Frame, model: ShapeModel) -> np.ndarray:
    """(Hm, Wm) bool: what covers the face (``covered_mask``) from above the eyes' row plus ``HAIR_BELOW_EYES``
    interocular distances: hair over the forehead and temples. Lower down it is as often the jaw's own shadow on
    the neck, which the cover step takes too (the demo's faces lit from above)."""
    grid = frame.data.get("grid_covered")
    if grid is None:
        return np.zeros(model.grid, bool)
    below = float(np.mean(np.asarray(model.eyes, np.float64)[:, 1])) + HAIR_BELOW_EYES * model.iod
    return grid & (np.arange(model.grid[0])[:, None] <= below)


def fitted_pixels(frame: Frame, model: ShapeModel) -> np.ndarray:
    """(N,) bool over the model pixels: those whose brightness the fit, the brightness scale and the
    albedo read: shown by the photo and not covered."""
    return seen_pixels(frame, model) & ~covered_mask(frame, model)


def shading_normals(frame: Frame) -> np.ndarray:
    """(Hm, Wm, 3) the normals that explain the photo's shading (``CombineNode``): the albedo divides
    them out and the relighting puts them back; the output ``normals`` where the two are one."""
    return frame.data.get("shading_normals", frame.data["normals"])


class LoadNode:
    """Reads the input file (``read_photo``) and its sidecar, or the samples given as an array in
    ``frame.data["samples"]`` (``photo_from_samples``: checked and scaled as a file's, no sidecar); an
    image already in ``frame.data["image"]`` (a render) is taken as it is. Writes the photo (``image``,
    ``colour``, ``rgb8``), the light when it is known before any face is (``light``), and eyes given for
    the photo (``given_eyes``, photo pixels)."""

    name = "load"

    def __init__(self, options: MethodOptions):
        self.options = options

    def __call__(self, frame: Frame) -> Frame:
        d, o = frame.data, self.options
        from_file = "image" not in d and "samples" not in d  # a file: it may have a sidecar
        scale = 1.0  # the image's pixels per pixel of the file or array: given eyes follow it
        if "image" not in d:
            samples = d.pop("samples", None)
            photo = read_photo(frame.source, o.max_pixels, o.encoding) if samples is None else \
                photo_from_samples(frame.source, samples, o.max_pixels, o.encoding)
            scale = self._take(frame, photo)
        image = d["image"]
        if min(image.shape) < MIN_SIDE:
            raise InputError(f"{frame.source}: image is {image.shape[1]}x{image.shape[0]}, too small for a face")
        side = read_sidecar(frame.source) if from_file and "light" not in d else None
        eyes = given_eyes(frame.source, image.shape, side, o.eyes, scale)
        if eyes is not None:
            d["given_eyes"], frame.meta["eyes_source"] = eyes
        if "light" in d:
            frame.meta.setdefault("light_source", "given")
        elif (known := known_light(frame.source, side, o.light)) is not None:
            d["light"], frame.meta["light_source"] = known
        return frame

    @staticmethod
    def _take(frame: Frame, photo: Photo) -> float:
        """The photo into the frame (grey, colour, its 8-bit values when sRGB, its encoding, and
        ``reduced`` when it was); returns its pixels per pixel of the file."""
        frame.data["image"] = photo.grey
        if photo.colour is not None:
            frame.data["colour"] = photo.colour
        if photo.rgb8 is not None:  # decoded from sRGB: the file's own values, for the face finder and outputs
            frame.data["rgb8"] = photo.rgb8
        frame.meta["encoding"] = photo.encoding
        if photo.scale != 1.0:
            frame.meta["reduced"] = {"from": list(photo.size), "to": [photo.grey.shape[1], photo.grey.shape[0]]}
        return photo.scale


class FacesNode:
    """Finds and places the photo's faces (``photo.placement.place_faces``) and makes each a part of
    the frame (``Frame.parts``, largest first): a frame of its own on the model grid, with the
    photo's arrays, its placement, its light (given, or estimated on its own pixels) and the model
    pixels it shows. A photo with no face fails here: "no face found". A clip's faces are followed from its frame
    before (``photo.follow.FaceFollower``), so its frames come in order."""

    name = "faces"
    in_order = True

    def __init__(self, model: ShapeModel, options: MethodOptions):
        self.model, self.options, self.follow = model, options, FaceFollower()

    def __call__(self, frame: Frame) -> Frame:
        d, m = frame.data, self.model
        image = d["image"]
        if "alignment" in d:  # given: e.g. a render put in a photo's place
            al = d["alignment"]
            placements = [FacePlacement(al, "given", al.points_to_input(m.eyes), model_box(m, al, image.shape))]
        else:
            placements = place_faces(m, photo_rgb8(frame), d.get("given_eyes"), frame.meta.get("eyes_source", ""),
                                     self.options.find_faces, self.options.face_length,
                                     lambda rgb: self.follow(rgb, frame.meta.get("clip")))
        if not placements:
            raise FrameFailed(f"{frame.source}: {NO_FACE}")
        frame.parts = []
        for k, placement in enumerate(placements):
            built: list = []
            candidates = turned_placements(m, placement, image.shape, self.options.face_length, built.append)
            face = self._face(frame, k, candidates[0])
            if built:  # the run says so (``runner``): a view's model is built once, on its first face
                face.meta["models_built"] = [str(path) for path in built]
            if len(candidates) > 1 and face.ok:
                face.data["view_candidates"] = candidates
            frame.parts.append(face)
        return frame

    def again(self, face: Frame, placement: FacePlacement) -> Frame:
        """The face of frame ``face`` (a part ``__call__`` made) made again with ``placement``."""
        photo = Frame(face.id, face.source, data={key: face.data[key] for key in ("image", "colour", "rgb8")
                                                  if key in face.data},
                      meta={"stem": face.meta.get("stem"), "encoding": face.meta.get("encoding", "linear")})
        if face.meta.get("light_source", "estimated") != "estimated":  # given: the same for every placement
            photo.data["light"], photo.meta["light_source"] = face.data["light"], face.meta["light_source"]
        made = self._face(photo, int(face.meta.get("face", 1)) - 1, placement, face.source)
        # a clip's face's: its light's own estimate, which face it is over its frames (``app.steady``)
        made.meta.update({k: v for k, v in face.meta.items() if k in ("light_raw", "track", "track_age",
                                                                       "view_refresh", "light_changed", "light_alone")})
        return made

    def _face(self, frame: Frame, k: int, placement: FacePlacement, source: str | None = None) -> Frame:
        """Face ``k`` (0 the largest) of the photo as a frame of its own (failed when it is refused), fitted
        with the model of its view (``turned.face_model``)."""
        d = frame.data
        if source is None:
            source = frame.source if k == 0 else f"{frame.source} (face {k + 1})"
        face = Frame(frame.id, source, data={key: d[key] for key in ("image", "colour", "rgb8") if key in d},
                     meta={"stem": frame.meta.get("stem"), "face": k + 1,
                           "encoding": frame.meta.get("encoding", "linear")})
        if placement.view != (0.0, 0.0):
            face.meta["model_view"] = list(placement.view)
        # the face's model, chosen here once: every node after reads it from the frame
        m = face.data["model"] = face_model(face, self.model)
        if placement.refused:
            face.meta["placement"] = placement.record()
            face.fail(self.name, f"{source}: {placement.refused}")
            return face
        al = placement.alignment
        grid_image, seen = face_on_grid(d["image"], placement, m)
        if "light" in d:
            light, how = np.asarray(d["light"], np.float64), frame.meta.get("light_source", "given")
        else:
            use = seen.copy()
            if "colour" in d:  # the skin only: hair over the forehead, brows and eyes are dark but not shaded
                grid_colour = to_model_grid(d["colour"], al, m.grid)
                use &= skin(grid_colour, use & m.mask)
            light, how = al.vector_to_input(light_on_face(grid_image, use, m)), "estimated"
        grid_light = al.vector_to_model(light)
        # judged under the light found above: estimated again without what covers the face, on the five Yale B
        # subjects the light moved by -0.5 to +0.6 degrees (means per light), B05's at +25 from 4.4 to 10.2 and at
        # +35,+15 from 6.9 to 11.9
        covered = covered_on_grid(grid_image, seen, placement, m, grid_light)
        face.data.update(alignment=al, placement=placement, eyes_found=placement.found, grid_image=grid_image,
                         grid_valid=seen, grid_covered=covered, light=light, grid_light=grid_light)
        face.meta.update(alignment=al.how, light=[round(float(x), 6) for x in light], light_source=how,
                         placement=placement.record())
        return face


class RemapNode:
    """Brightness scale. ``scale="peak"``: the brightest point (3x3 median) has the mean face's
    peak shading (``model_peak``; the paper's 1 otherwise). ``"ratio"``: the median ratio of
    brightness to the mean face's shading (``ratio_scale``), which specular shine and a few
    pale pixels cannot move. Either way, when more than ``max_clipped`` of the face is at or
    above ``saturation`` (over-exposed) the ratio is used."""

    name = "remap"

    def __init__(self, model_peak: bool = True, saturation: float = SATURATION, max_clipped: float = 0.02,
                 scale: str = "peak"):
        if scale not in ("peak", "ratio"):
            raise ValueError(f"unknown remap scale {scale!r}: peak or ratio")
        self.model_peak, self.scale = model_peak, scale
        self.saturation, self.max_clipped = saturation, max_clipped

    def __call__(self, frame: Frame) -> Frame:
        image, s, model = frame.data["grid_image"], frame.data["grid_light"], frame.data["model"]
        seen = fitted_pixels(frame, model)  # face pixels the photo shows, no hair over them
        face = image[model.mask][seen]
        saturated = np.zeros(model.n_pixels, bool)  # over-exposure decided here, once
        saturated[seen] = clipped_pixels(face, self.saturation, self.max_clipped)
        frame.data["saturated"] = saturated
        clipped = float(np.mean(saturated[seen]))
        if self.scale == "ratio" or clipped > 0:  # over-exposed: no peak to go by
            scale = ratio_scale(face, model.mean_normals[seen] @ s, self.saturation)
            frame.data["remapped"] = np.clip(image / scale, 0.0, 1.0).astype(np.float32)
            frame.meta.update(remap_scale=scale, clipped_fraction=round(clipped, 4))
            return frame
        peak = expected_peak_shading(model.mean_normals, s) if self.model_peak else 1.0
        m = model.to_image(seen, fill=False).astype(bool)
        frame.data["remapped"], frame.meta["remap_scale"] = lambertian_remap(image, m, peak_shading=peak)
        return frame


class SfsInitNode:
    name = "sfs_init"

    def __init__(self, config: FitConfig):
        self.config = config

    def __call__(self, frame: Frame) -> Frame:
        frame.data["initial"] = initial_normals(frame.data["model"], frame.data["remapped"],
                                                frame.data["grid_light"], self.config)
        return frame


class RobustFitNode:
    """The fit loop; ``observer`` (if any) sees every iteration and the end of each fit. Holds no
    state of a frame: it may run on several threads (``thread_safe``)."""

    name = "robust_fit"
    thread_safe = True

    def __init__(self, config: FitConfig, observer: FitObserver | None = None):
        self.config, self.observer = config, observer

    def __call__(self, frame: Frame) -> Frame:
        def hook(it: FitIteration) -> None:
            with frame.while_running() as going:  # not cancelled between the check and what is recorded
                if not going:  # timed out or stopped: nobody waits for this fit any more
                    raise FrameFailed(f"{frame.source}: fit abandoned at iteration {it.iteration}")
                if self.observer is not None:
                    self.observer.iteration(frame, it)

        model = frame.data["model"]
        intensity = frame.data["remapped"][model.mask]
        unreliable = frame.data["saturated"] | ~fitted_pixels(frame, model)  # hair is not the face's shape
        result = fit(model, intensity, frame.data["grid_light"], self.config, frame.data["initial"], hook,
                     unreliable=unreliable)
        if self.observer is not None:
            with frame.while_running() as going:
                if going:
                    self.observer.finish(frame)
        frame.data["fit"] = result
        frame.meta.update(iterations=result.iterations, converged=result.converged, final_sigma=result.sigma)
        return frame


class CombineNode:
    """Output normals: the on-cone and model normals blended by ``cone_trust`` x the weights
    (``normals``: the shape, integrated to depth). With ``cone_trust`` < 1 the paper's blend is
    kept as well (``shading_normals``) for the albedo and the relighting: the on-cone normals
    reproduce the photo's shading, which is what those divide out and put back."""

    name = "combine"

    def __init__(self, cone_trust: float = 1.0):
        self.cone_trust = cone_trust

    def __call__(self, frame: Frame) -> Frame:
        r, model = frame.data["fit"], frame.data["model"]
        paper = model.to_image(combine(r.normals, r.model_normals, r.weights).astype(np.float32))
        if self.cone_trust == 1.0:
            frame.data["normals"] = paper
        else:
            w = self.cone_trust * r.weights
            frame.data["normals"] = model.to_image(combine(r.normals, r.model_normals, w).astype(np.float32))
            frame.data["shading_normals"] = paper
        return frame


class IntegrateNode:
    name = "integrate"

    def __init__(self, integrator: str):
        if integrator not in INTEGRATORS:
            raise ValueError(f"unknown integrator {integrator!r}: choose from {', '.join(INTEGRATORS)}")
        self.integrate = INTEGRATORS[integrator]

    def __call__(self, frame: Frame) -> Frame:
        frame.data["depth"] = self.integrate(frame.data["normals"], frame.data["model"].mask)
        return frame


class ShadowNode:
    name = "shadow"

    def __init__(self, mode: str, dark_threshold: float):
        if mode not in ("confirmed", "geometric"):
            raise ValueError(f"unknown shadow mode {mode!r}: confirmed or geometric")
        self.mode, self.dark_threshold = mode, dark_threshold

    def __call__(self, frame: Frame) -> Frame:
        d = frame.data
        dark = far_dark = None
        if self.mode == "confirmed":
            shading = np.nan_to_num(d["normals"]) @ np.asarray(d["grid_light"], np.float64)
            far_dark = far_darker(d["remapped"], shading, np.isfinite(d["depth"]))
            dark = (d["remapped"] <= self.dark_threshold) | far_dark
        # a confirmed cast shadow is dark in the image: only dark pixels need a ray traced
        maps = shadow_maps(d["depth"], d["normals"], d["grid_light"], candidates=dark)
        if self.mode == "confirmed":
            maps = confirm_with_image(maps, d["remapped"], self.dark_threshold, far_dark)
            kept_out = near_cast_kept_out(d.get("placement"), d.get("grid_covered"), d["depth"].shape,
                                          d["model"].iod)
            maps = near_cast(maps, d["depth"], d["grid_light"], d["remapped"], self.dark_threshold, far_dark, kept_out)
        frame.data["shadow"] = maps
        return frame


def near_cast_kept_out(placement: FacePlacement | None, covered: np.ndarray | None, grid: tuple[int, int],
                       iod: float) -> np.ndarray | None:
    """(Hm, Wm) bool: what a near miss of the ray (``shadow.near_cast``) must not make shadow, being dark by
    its albedo: the face mesh's eyes and brows, its lips and the mouth's surroundings within ``NEAR_CAST_MOUTH``
    interocular distances (``iod`` model pixels; a moustache, a goatee: under a light from above the lower lip
    nearly shades the chin, and a goatee's middle came back a patch of skin), and hair over the face (``covered``:
    a fringe lit from the side took patches of skin). None when there is nothing to keep out."""
    out = None if covered is None else np.asarray(covered, bool)
    if placement is None:
        return out
    features = features_on_grid(placement, grid, ("eyes", "brows"))
    lips = features_on_grid(placement, grid, ("lips",))
    if lips is not None:
        mouth = grown_region(lips, NEAR_CAST_MOUTH * iod)
        features = mouth if features is None else features | mouth
    if features is None:
        return out
    return features if out is None else features | out


class AlbedoNode:
    name = "albedo"

    def __init__(self, fill: str = "ceiling"):
        if fill not in ("ceiling", "mirror"):
            raise ValueError(f"albedo fill must be 'ceiling' or 'mirror', not {fill!r}")
        self.ceiling = FILL_CEILING if fill == "ceiling" else None

    def __call__(self, frame: Frame) -> Frame:
        model = frame.data["model"]
        # a frontal face's mirror image is across the eyes' midpoint column; a turned one's, the model's own map
        mirror = float(np.mean(model.eyes[:, 0])) if model.mirror is None else model.mirror
        # measured only where the photo shows the face: past its outline (hair, background), past the photo's
        # frame (its edge repeated) or under hair, a pixel's brightness is not the face's albedo; there it is
        # mirrored or filled, as under shadow
        frame.data["albedo"], frame.data["albedo_source"] = estimate_albedo(
            frame.data["grid_image"], shading_normals(frame), frame.data["grid_light"],
            frame.data["shadow"].lit & model.to_image(fitted_pixels(frame, model), fill=False).astype(bool),
            model.mask, mirror, fill_ceiling=self.ceiling)
        return frame


class RelightNode:
    name = "relight"

    def __init__(self, options: MethodOptions):
        self.options = options

    def __call__(self, frame: Frame) -> Frame:
        al: Alignment = frame.data["alignment"]
        light = al.vector_to_model(self.options.relight_light)
        frame.data["relit"] = relight(frame.data["albedo"], np.nan_to_num(shading_normals(frame)), light,
                                      frame.data["depth"])
        return frame


class QualityNode:
    """Is there a face and did the fit work (``quality``): ``meta["quality"]`` holds the score,
    flags and signals; a frame with no face fails with that reason."""

    name = "quality"

    def __init__(self, huber_k: float = FitConfig.huber_k):
        self.huber_k = huber_k

    def __call__(self, frame: Frame) -> Frame:
        d = frame.data
        m = d["model"]
        seen = seen_pixels(frame, m)
        r = d["fit"]
        shading = np.clip(r.model_normals @ np.asarray(d["grid_light"], np.float64), 0.0, None)
        saturated = d["saturated"]
        use = seen & d["shadow"].lit[m.mask] & (shading > 0.1) & ~saturated
        placement: FacePlacement | None = d.get("placement")
        eyes = None if placement is None else features_on_grid(placement, m.grid, ("eyes",))
        if eyes is not None:  # the eyes and around them are albedo (lashes, sunglasses): no shape explains them
            use &= ~grown_region(eyes, EYEWEAR_MARGIN * m.iod)[m.mask]
        unread = covered_mask(frame, m)  # the fit left them out; its quality counts them as it would have
        weights = np.where(unread, unread_weights(d["remapped"][m.mask], r.model_normals, d["grid_light"],
                                                  self.huber_k * r.sigma), r.weights)
        q = assess(eyes=d.get("eyes_found", "given"),
                   explained=explained_variance(d["remapped"][m.mask], shading, use, weights),
                   downweighted=float(np.mean(weights[seen] < 0.5)) if seen.any() else 1.0,
                   clipped=float(np.mean(saturated[seen])) if seen.any() else 0.0,
                   # the frame's share of the core, not the fit's: a turned face's far cheek lies past its fit's oval
                   inside=float(np.mean(inside_input(d["alignment"], d["image"].shape, m.grid)[core_face(m)])),
                   doubts=placement.doubts if placement is not None else (),
                   plausible=placement.plausible if placement is not None else True,
                   presence=placement.presence if placement is not None else None,
                   detection=placement.face.score if placement is not None and placement.face is not None else None,
                   even=evenly_lit(photo_channels(frame), None if placement is None else placement.eyes))
        q.signals["covered"] = float(np.mean(unread[seen])) if seen.any() else 0.0  # hair the fit left out
        frame.meta["quality"] = q.record()
        age = frame.meta.get("track_age", 0)
        if q.no_face and age < TRACKED_FACE:
            raise FrameFailed(f"{frame.source}: {NO_FACE} ({'; '.join(q.flags)})")
        if q.no_face:  # a clip's face found where it was on the frames before is that face, however its fit went
            frame.meta["quality"]["flags"] = [*q.flags, f"no face by its fit, yet tracked {age} frames"]
        return frame


def method_nodes(options: MethodOptions, observer: FitObserver | None = None, with_views: bool = True) -> list:
    """The method's nodes after loading, in order: remap .. quality, then the model grid's relit face
    (``with_views=False`` stops after the quality);
    ``observer`` goes to the fit node."""
    nodes = [
        RemapNode(options.fit.solver != "paper", options.fit.saturation, scale=options.remap),
        SfsInitNode(options.fit),
        RobustFitNode(options.fit, observer),
        CombineNode(options.fit.cone_trust),
        IntegrateNode(options.integrator),
        ShadowNode(options.shadows, options.fit.dark_threshold),
        AlbedoNode(options.albedo_fill),
        # before the relighting: a frame with no face fails without paying for it
        QualityNode(options.fit.huber_k),
    ]
    if with_views:  # the model grid's relit face; the photo's is the relighting's (``relight.nodes``)
        nodes.append(RelightNode(options))
    return nodes
