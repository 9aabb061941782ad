"""The frame contract: every entry the method's nodes read or write, in one table.

``Hm, Wm`` = the model grid, ``N`` = the model's face pixels, ``H, W`` = the input photo.
A node reads only entries of the nodes before it; ``tests/method/test_frame_contract.py`` runs a photo
and a render through every node and checks that each entry a node writes is listed here, and reads the
code of ``nodes/`` for every key it names on a frame (``frame.data["..."]``, ``d.get("...")``...): a
key the table does not list, a typo included, fails it.
"""
from __future__ import annotations

# frame.data: key -> (what it holds, the node that writes it)
DATA: dict[str, tuple[str, str]] = {
    # the photo's frame (its faces are its parts, ``Frame.parts``; a face's frame holds the entries below these)
    "clip_rgb": ("(H, W, 3) uint8 a clip's frame as decoded, written as it is when the frame fails", "intake (app.clips)"),
    "clip_relit": ("[(H, W, 3) uint8] a clip's frame relit by each of the run's lights, for its relit clips",
                   "clip (app.clips)"),
    "samples": ("(H, W) or (H, W, 3) an array given for the photo (the API's), read as a file's samples are; "
                "taken off by load", "given"),
    "image": ("(H, W) float32 input brightness in [0, 1]", "load, or given; faces (a face's, the photo's)"),
    "colour": ("(H, W, 3) float32 linear RGB in [0, 1], when the input is in colour: an array, or for 8-bit sRGB "
               "a ``Decoded8`` of ``rgb8`` (index it: only that part is decoded)", "load, or given; faces"),
    "given_eyes": ("(2, 2) eye centres given for the photo, photo pixels (sidecar, --eyes)", "load"),
    "rgb8": ("(H, W, 3) uint8 RGB, the file's own values, when it was decoded from sRGB (``image`` and ``colour`` "
             "are linear light)", "load, or given; faces"),
    "light": ("(3,) unit light, input camera frame: known before the faces (photo), or the face's", "load, faces"),
    # a face's frame
    "model": ("``ShapeModel`` the face is fitted with: the model turned to its view (``turned.face_model``), chosen "
              "once when the face's frame is made", "faces, or on_model_grid"),
    "alignment": ("``Alignment``: model pixel -> input pixel", "faces, or given"),
    "placement": ("``FacePlacement``: the face's alignment, eyes, box, pose, outlines and doubts", "faces"),
    "eyes_found": ("how the face was placed: detected | mesh only | given | centre asked", "faces"),
    "view_candidates": ("list of ``FacePlacement``: a turned face's placements for the views near its pose, one "
                        "to be chosen (taken off by view_choice)", "faces"),
    "grid_image": ("(Hm, Wm) the input resampled to the model grid", "faces, or on_model_grid"),
    "grid_valid": ("(Hm, Wm) bool, model pixels inside the photo and the face's outline (absent: all)", "faces"),
    "grid_covered": ("(Hm, Wm) bool, the ``grid_valid`` pixels hair or a dark head covers, which the fit, the "
                     "brightness scale and the albedo do not read (absent: none)", "faces"),
    "grid_light": ("(3,) the light in the model's camera frame", "faces, or on_model_grid"),
    "saturated": ("(N,) bool, face pixels clipped by over-exposure", "remap"),
    "remapped": ("(Hm, Wm) brightness on the Lambertian scale", "remap"),
    "initial": ("(N, 3) starting normals", "sfs_init"),
    "fit": ("``FitResult``: on-cone and model normals, weights, residuals, history", "robust_fit"),
    "normals": ("(Hm, Wm, 3) output normals, camera frame, NaN off the face", "combine"),
    "shading_normals": ("(Hm, Wm, 3) the paper's blend, when ``normals`` is not it", "combine"),
    "depth": ("(Hm, Wm) heights in model pixels, NaN off the face", "integrate"),
    "shadow": ("``ShadowMaps``: cast and attached, (Hm, Wm) bool, for the input light", "shadow"),
    "albedo": ("(Hm, Wm) float32 albedo, NaN off the face", "albedo"),
    "albedo_source": ("(Hm, Wm) uint8: 0 off-face, 1 measured, 2 mirrored, 3 filled", "albedo"),
    "relit": ("(Hm, Wm) the face under ``MethodOptions.relight_light``", "relight"),
    "novel_view": ("(Hm, Wm) or (Hm, Wm, 3) (colour photo) the surface turned about the vertical axis, linear",
                   "novel_view"),
    "photo_box": ("(y0, y1, x0, x1) the face's own box in the photo (the face and a few pixels), which the next "
                  "three cover", "relight_photo"),
    "photo_albedo": ("(h, w, C) albedo in the face's box of the photo grid, C = 3 for a colour photo, NaN off "
                     "the face", "relight_photo"),
    "photo_shadow": ("(h, w) bool, the face's cast and attached shadows in its box, at the photo's resolution",
                     "relight_photo"),
    "photo_foreign": ("(h, w) float32 in [0, 1], with ``foreign_shadows``: how far each pixel of the face's box is in "
                      "shadows the face does not cast", "relight_photo"),
    "photo_layers": ("list of (light (3,), ``FaceLayer``): the face relit, to compose into the photo (a clip's "
                     "steadied over its frames)", "relight_photo, steady_relight"),
    "photo_layers_relit": ("``photo_layers`` as relit, of a face left as it was: a clip's track may relight it "
                           "again", "relight_photo, steady_relight"),
    "live": ("``LiveFace``, or what makes it when called: what relights the face for any light in view.html (a "
             "preview of its box); read it with ``relight.nodes.live_face``",
             "relight_photo"),
    "relit_8bit": ("(H, W, C) uint8 RGB the photo relit by the first light, as ``relit.png`` holds it: kept by the "
                   "writer for the report's pictures (``report.CardNode``), composed once", "write"),
}

# frame.meta: key -> (what it holds, who writes it); all JSON-friendly, summarised in summary.json
META: dict[str, tuple[str, str]] = {
    "stem": ("the output folder's name", "runner"),
    "previous": ("the summary record of a frame skipped by --resume", "runner"),
    "input_key": ("the input's absolute path, its key in the run manifest", "runner"),
    "identity": ("(size, mtime_ns) of the input file when the run took it", "runner"),
    "sha256": ("the input file's content hash, for a later --resume", "runner"),
    "reduced": ("{from: [w, h], to: [w, h]}: the photo was read smaller (``max_pixels``)", "load"),
    "eyes_source": ("where ``given_eyes`` came from: sidecar eyes | given eyes", "load"),
    "encoding": ("the photo's encoding: srgb (decoded to linear light, outputs encoded back) | linear", "load, faces"),
    "face": ("which face of its photo a face's frame is (1 the largest)", "faces"),
    "placement": ("the face's box, eyes, pose, presence (``FacePlacement.record``)", "faces"),
    "light": ("[x, y, z] the light used, input camera frame", "faces"),
    "light_source": ("sidecar | given | yaleb name | estimated | steadied (a clip's, app.steady)", "load, faces, steady"),
    "light_raw": ("[x, y, z] a clip's face's light estimated on its frame alone, before steadying", "steady"),
    "track": ("which face of a clip this is over its frames (a number, from 0 in each clip)", "steady"),
    "track_age": ("how many frames of its clip a face has been tracked before this one", "steady"),
    "light_changed": ("whether a clip's face's photo shows its light changed since the frame before "
                      "(``relight.temporal.light_shown_changed``)", "steady"),
    "light_alone": ("whether a clip's face is relit under its frame's own light, which left the running light as the "
                    "frame before's did (a departure that agrees with the one before: ``app.steady.LightSmoother``)",
                    "steady"),
    "view_refresh": ("whether a clip's face near frontal reads its view (and yaw) with the fit on this frame: True, "
                     "\"light\" (its light moved since the last reading), or False (the yaw read before is carried)",
                     "steady"),
    "alignment": ("how the face was aligned (landmarks, eyes, centred crop)", "faces"),
    "model_view": ("[yaw, pitch] degrees of the turned model the face is fitted with (absent: frontal)",
                   "faces, view_choice"),
    "models_built": ("[path] the turned models this face's views built (their first use), for the run to say",
                     "faces, view_choice"),
    "view_choice": ("{\"yaw,pitch\": misfit} of each view a turned face (or one near frontal under a side light) "
                    "was fitted with; the least fits it (``turned.misfits``)", "view_choice"),
    "yaw_read": ("{\"landmarks\", \"fit\"}: the two yaws (degrees) whose mean is the face's pose's yaw "
                 "(``turned.ViewChoiceNode``); a clip's face between its readings: {\"landmarks\", \"carried\"}, "
                 "the fit's share carried from its last reading (``app.steady.SteadyYawNode``)",
                 "view_choice, steady_yaw"),
    "remap_scale": ("the brightness scale divided out", "remap"),
    "clipped_fraction": ("share of the seen face clipped (over-exposed photos)", "remap"),
    "iterations": ("fit iterations", "robust_fit"),
    "converged": ("whether the fit met its stopping rule", "robust_fit"),
    "final_sigma": ("the fit's last residual scale, radians", "robust_fit"),
    "foreign_shadows": ("with ``foreign_shadows``: the shadows the face does not cast, their count and share of the "
                        "face", "relight_photo"),
    "relight": ("what the face's relighting did under the first light: exposure, painted share, lift's 95th percentile", "relight_photo"),
    "quality": ("score, flags and signals: is there a face, did the fit work (``quality``)", "quality"),
    "outputs": ("the folder the outputs were written to", "write"),
    "clip": ("a clip's frame: its clip's stem, index, time (s), pts, info (size, rate, ...), source, files "
             "(--frames); its end frame: end", "intake (app.clips)"),
    "card": ("``report.CardPictures``: the report's pictures of the photo, made while it was held (the run's first "
             "``report.LARGE_PHOTOS``); taken by the run when the frame is done", "card"),
    "recording_parts": ("the recording files a Dask worker wrote the frame into (taken off by the runner)",
                        "the Dask worker's finish"),
    "recording_error": ("why a Dask worker could not record the frame (taken off by the runner)",
                        "the Dask worker's finish"),
    "timings": ("seconds per node", "the flow engine"),
}
