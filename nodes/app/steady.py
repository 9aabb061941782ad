"""A clip's faces kept steady from frame to frame: each face tracked by where its box is, and the light estimated on
it carried and smoothed over the frames of one person under one light (``LightSmoother``), a real change (a light
switched, a cut) followed within ``CONFIRM`` frames. ``SteadyLightNode`` gives the fit the smoothed light as the
face's light. Frames of a clip reach it in order: it runs on one thread, after the faces are found (one thread too)."""
from __future__ import annotations

import numpy as np

from ...flow.frame import Frame
from ..method.products import photo_channels
from ..relight.nodes import LEFT, face_eyes, leave, left_as_it_was, relight_again, shown_share
from ..relight.temporal import light_shown_changed, photo_on_grid, steady_layer

# The constants of the steadying, in one place (measured on tests/app/test_clips.py's clips, docs/usage.md "Clips"):
# ALPHA: the weight of a frame's own estimate in the running light (an exponential moving average of the unit
# vector): 0.3 keeps about a sixth of a frame's noise after a few frames (the noise's variance shrinks by
# ALPHA / (2 - ALPHA)) while a drift of the light is followed within a few frames;
ALPHA = 0.3
# JUMP_DEG: an estimate further than this from the running light is not averaged in: the estimator's own error is
# 6-8 degrees (README, "How well"), so twice that is a departure, not noise;
JUMP_DEG = 15.0
# CONFIRM: that many departing frames in a row are a real change (a light switched on, a cut): the running light
# is then their mean, so a change is followed within CONFIRM frames and a lone outlier never moves it (a departing
# frame is fitted under its own estimate meanwhile); a change of light the photo itself shows
# (``temporal.LIGHT_SHOWN``: three quarters of the face brighter or darker by an eighth against the rest) is taken
# at once;
CONFIRM = 3
# AGREE_DEG: a departure within this of the departure before it is the light that moved, not the estimate's noise:
# the frame's relit face is its own, not the running one made under the light before (a light held two frames read
# 0.0-0.2 degrees apart; a webcam clip's departures under a still light, 5-13 degrees apart, relit alone flickered 2.6
# times as much; consecutive frames' estimates under a still light: 1-2 degrees apart on median)
AGREE_DEG = 3.0
# TRACK_MATCH: a face is the same as one of the frame before when its box's centre moved less than this many of
# its box's sides; TRACK_MEMORY: a face unseen this many frames is forgotten (its light starts afresh).
TRACK_MATCH = 0.5
TRACK_MEMORY = 5
# VIEW_EVERY: a tracked face read near frontal reads its view with the fit (``turned.ViewChoiceNode``: a fit of each
# candidate view, two thirds of a frame's time) on its first frame and every this many frames after, and carries the
# yaw read so to the frames between (``SteadyYawNode``); the view itself is frontal on each of them either way.
# VIEW_LIGHT_DEG: ... and reads it again when its light moved this far since (the landmarks lean away from a side
# light: a switch of the light from +30 to -30 deg moved their yaw by 10 deg, and the share carried from before it
# then added to that lean instead of taking it away)
VIEW_EVERY = 10
VIEW_LIGHT_DEG = 10.0


def angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """The angle between two vectors, in degrees."""
    c = float(np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b) + 1e-12))
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def _unit(v: np.ndarray) -> np.ndarray:
    return v / max(float(np.linalg.norm(v)), 1e-12)


class LightSmoother:
    """One face's light over a clip's frames: ``update(raw)`` takes the frame's estimate (a vector toward the light)
    and returns the running light (unit), as the constants above say. ``state`` says what the last frame's light
    was: "carried" (the running light), "departed" (a departure: the frame's own estimate, the running light left as
    it was), "alone" (the same, within ``AGREE_DEG`` of the departure before it), "confirmed" (the running light took
    the departures' mean) or "changed" (the running light started again: a change the photo shows, or the first
    frame)."""

    def __init__(self, alpha: float = ALPHA, jump_deg: float = JUMP_DEG, confirm: int = CONFIRM):
        self.alpha, self.jump_deg, self.confirm = alpha, jump_deg, confirm
        self.light: np.ndarray | None = None
        self.departed: list[np.ndarray] = []  # the estimates in a row that left the running light
        self.state = "changed"

    def update(self, raw, shown: bool = False) -> np.ndarray:
        """``shown``: the photo itself shows the light changed (``temporal.light_shown_changed``): the frame's
        estimate is taken at once, as a confirmed change is."""
        raw = _unit(np.asarray(raw, np.float64))
        if self.light is None or shown:
            self.light, self.departed, self.state = raw, [], "changed"
        elif angle_deg(raw, self.light) > self.jump_deg:
            # a departure: the frame is fitted under its own estimate (under the running light a switched light
            # fails the fit: "no face found"), and the running light is left as it is until it is confirmed
            self.departed.append(raw)
            agree = len(self.departed) > 1 and angle_deg(self.departed[-1], self.departed[-2]) < AGREE_DEG
            if len(self.departed) < self.confirm:
                self.state = "alone" if agree else "departed"
                return raw.copy()
            self.light, self.departed = _unit(np.mean(self.departed[-self.confirm:], axis=0)), []
            self.state = "confirmed"
        else:
            self.departed, self.state = [], "carried"
            self.light = _unit((1.0 - self.alpha) * self.light + self.alpha * raw)
        return self.light.copy()


class _Track:
    def __init__(self, box: list, index: int, number: int):
        self.box, self.seen, self.smoother, self.number, self.born = box, index, LightSmoother(), number, index
        self.read_at: tuple[int, np.ndarray] | None = None  # the frame and light its view was last read with the fit
        self.photo: tuple[np.ndarray, np.ndarray] | None = None  # its last frame's photo on its grid

    def shown_change(self, face: Frame, index: int) -> bool:
        """Whether this frame's photo shows the face's light changed since the track's last frame (the one just
        before: ``temporal.light_shown_changed``); the frame's photo kept for the next."""
        eyes, before = face_eyes(face), self.photo
        self.photo = None if eyes is None else photo_on_grid(face.data["image"], eyes)
        if before is None or self.photo is None or self.seen != index - 1:
            return False
        return light_shown_changed(before, self.photo)

    def view_refresh(self, index: int, light: np.ndarray) -> bool | str:
        """Whether this frame of the face reads its view with the fit (``VIEW_EVERY``): True, or "light" when its
        light moved (``VIEW_LIGHT_DEG``: the readings before are of another light); False when it does not."""
        moved = self.read_at is not None and angle_deg(light, self.read_at[1]) > VIEW_LIGHT_DEG
        if self.read_at is None or index - self.read_at[0] >= VIEW_EVERY or moved:
            self.read_at = (index, np.asarray(light, np.float64))
            return "light" if moved else True
        return False

    def near(self, box: list) -> float:
        """How far ``box``'s centre is from this track's, in this track's box sides (inf: too far to be it)."""
        (a0, b0, a1, b1), (x0, y0, x1, y1) = self.box, box
        side = max(a1 - a0, b1 - b0, 1.0)
        d = np.hypot((x0 + x1 - a0 - a1) / 2, (y0 + y1 - b0 - b1) / 2) / side
        return d if d < TRACK_MATCH else np.inf


class SteadyLightNode:
    """For a clip's frames (``meta["clip"]``): each face matched to a face of the frames before (``_Track``), and its
    estimated light replaced by its track's running light (``meta["light"]``, ``data["light"]`` and
    ``data["grid_light"]``; the frame's own estimate kept in ``meta["light_raw"]``; ``light_source`` "steadied",
    which a view chosen again carries as given). Photos, and faces whose light was given, pass untouched."""

    name = "steady"
    in_order = True  # its frames in input order, on one thread (``flow.pipeline.Stage.ordered``)

    def __init__(self) -> None:
        self.clip: str | None = None
        self.tracks: list[_Track] = []
        self.numbered = 0  # tracks begun in this clip: a track's number (``meta["track"]``) says which it is

    def __call__(self, frame: Frame) -> Frame:
        clip = frame.meta.get("clip")
        if not clip:
            return frame
        if clip["stem"] != self.clip:  # a new clip: nothing carried over
            self.clip, self.tracks, self.numbered = clip["stem"], [], 0
        index = int(clip["index"])
        self.tracks = [t for t in self.tracks if index - t.seen <= TRACK_MEMORY]
        free = list(self.tracks)
        for face in frame.parts:
            box = (face.meta.get("placement") or {}).get("box")
            if not face.ok or box is None or face.meta.get("light_source") != "estimated":
                continue
            track = min(free, key=lambda t: t.near(box), default=None)
            if track is None or not np.isfinite(track.near(box)):
                track = _Track(box, index, self.numbered)
                self.tracks.append(track)
                self.numbered += 1
            else:
                free.remove(track)
            shown = track.shown_change(face, index)
            track.box, track.seen = box, index
            light = track.smoother.update(face.data["light"], shown)
            # the relit face's running change (``SteadyRelightNode``) starts again where the photo shows the light
            # changed, and passes by a frame relit under a light of its own that agrees with the frame before's
            face.meta["light_changed"] = shown
            face.meta["light_alone"] = track.smoother.state == "alone"
            face.meta.update(track=track.number, track_age=index - track.born,
                             view_refresh=track.view_refresh(index, light))
            self._steady(face, light)
        return frame

    @staticmethod
    def _steady(face: Frame, light: np.ndarray) -> None:
        face.meta["light_raw"] = face.meta.get("light")
        face.data["light"] = light
        face.data["grid_light"] = face.data["alignment"].vector_to_model(light)
        face.meta.update(light=[round(float(x), 6) for x in light], light_source="steadied")


class _PerClip:
    """A node's state over one clip's frames, started afresh (``fresh``) when a frame of another clip comes."""

    def __init__(self) -> None:
        self.clip: str | None = None
        self.fresh()

    def fresh(self) -> None:
        raise NotImplementedError

    def clip_of(self, frame: Frame) -> dict | None:
        """The frame's clip (``meta["clip"]``), the state made afresh if it is a new one; None for a photo."""
        clip = frame.meta.get("clip")
        if clip and clip["stem"] != self.clip:
            self.clip = clip["stem"]
            self.fresh()
        return clip


class SteadyYawNode(_PerClip):
    """For a clip's frames, once each face is fitted: a tracked face that read its view with the fit on this frame
    (``meta["yaw_read"]``) gives its track the fit's share of the yaw read (the read yaw less the landmarks', averaged
    with the track's readings before, each new one weighing a half, unless its light moved since); one
    that did not (``meta["view_refresh"]`` False) is given the landmarks' yaw plus that share, as its track's last
    reading had it (``yaw_read``: ``landmarks`` and ``carried``). Frames of a clip reach it in order."""

    name = "steady_yaw"
    in_order = True  # its frames in input order, on one thread (``flow.pipeline.Stage.ordered``)

    def fresh(self) -> None:
        self.shares: dict[int, float] = {}

    def __call__(self, frame: Frame) -> Frame:
        if not self.clip_of(frame):
            return frame
        for face in frame.parts:
            pose = (face.meta.get("placement") or {}).get("pose")
            number = face.meta.get("track")
            if number is None or not pose:
                continue
            read = face.meta.get("yaw_read")
            if read is not None:  # each reading averaged with the ones before under that light (one fit's yaw
                # varies by several degrees)
                share = float(pose["yaw"]) - float(read["landmarks"])
                fresh = number not in self.shares or face.meta.get("view_refresh") == "light"
                self.shares[number] = share if fresh else 0.5 * (self.shares[number] + share)
            elif face.meta.get("view_refresh") is False and number in self.shares:
                share = self.shares[number]
                face.meta["yaw_read"] = {"landmarks": pose["yaw"], "carried": round(share, 2)}
                pose["yaw"] = round(float(pose["yaw"]) + share, 1)
        return frame


# HONEST_CONFIRM: a tracked face's frames must say this many times in a row that it is to be left as it was (key
# True) or relit (False) before the clip's face changes to that: the honesty step's verdict on one frame flips on a
# face near its bound (a webcam clip's 158 frames: 25 left as they were, scattered), and each flip is a step of the
# face's light. HONEST_RAMP: ... and it changes over this many frames (its relit face blended with the photo), not at
# once: the two differ by 15 levels of that face's mean, a step no steadying of the change of light hides. Taken
# away soon when it harms (2 frames, over 8: held 5 and blended over 20, a harmed face showed orange blotches for 15
# frames), given back slowly
HONEST_CONFIRM = {True: 2, False: 5}
HONEST_RAMP = {True: 8, False: 20}


class _Relit:
    """What a track carries of its relit face: the honesty verdict it holds, the contrary verdicts in a row, the
    running coarse change of each light (``relight.temporal``), and the frame it was last seen in."""

    def __init__(self, left: bool, index: int):
        self.left, self.against, self.carried, self.seen = left, 0, {}, index
        self.share = 0.0 if left else 1.0  # how much of the relit face is shown (``HONEST_RAMP``)


class SteadyRelightNode(_PerClip):
    """For a clip's frames, after each face is relit: a tracked face (``meta["track"]``, ``SteadyLightNode``) is
    left as it was, or relit, as its track holds (``HONEST_CONFIRM``), and each of its layers' change of light is
    steadied by the running change of the frames before (``relight.temporal.steady_layer``). A face seen again
    after a gap starts afresh. Frames of a clip reach it in order: it runs on one thread. Photos pass untouched."""

    name = "steady_relight"
    in_order = True  # its frames in input order, on one thread (``flow.pipeline.Stage.ordered``)

    def fresh(self) -> None:
        self.tracks: dict[int, _Relit] = {}

    def __call__(self, frame: Frame) -> Frame:
        clip = self.clip_of(frame)
        if not clip:
            return frame
        index = int(clip["index"])
        for face in frame.parts:
            number = face.meta.get("track")
            if number is None or not face.ok or "photo_layers" not in face.data:
                continue
            left = left_as_it_was(face)
            track = self.tracks.get(number)
            if track is None or track.seen != index - 1:  # a new face, or one lost a while: nothing carried
                track = self.tracks[number] = _Relit(left, index)
            photo = photo_channels(face)
            self._honest(face, track, left, photo)
            eyes = face_eyes(face)
            if eyes is not None:
                layers = []
                for i, (light, layer) in enumerate(face.data["photo_layers"]):
                    y0, y1, x0, x1 = layer.box
                    layer, track.carried[i] = steady_layer(layer, np.atleast_3d(photo[y0:y1, x0:x1]), eyes,
                                                           track.carried.get(i),
                                                           light_changed=face.meta.get("light_changed", False),
                                                           alone=face.meta.get("light_alone", False))
                    layers.append((light, layer))
                face.data["photo_layers"] = layers
            track.seen = index
        return frame

    @staticmethod
    def _honest(face: Frame, track: _Relit, left: bool, photo) -> None:
        """The face left as it was or relit as its track holds; the track's verdict changed by ``HONEST_CONFIRM``
        frames in a row that say otherwise, and its pixels moving to it over ``HONEST_RAMP`` frames."""
        track.against = track.against + 1 if left != track.left else 0
        if track.against >= HONEST_CONFIRM[left]:
            track.left, track.against = left, 0
        if left and not track.left:
            relight_again(face)
        elif track.left and not left:
            leave(face, photo, f"the frames before of this face would change at a fine scale: {LEFT}")
        step = 1.0 / HONEST_RAMP[track.left]
        track.share = float(np.clip(track.share + (-step if track.left else step), 0.0, 1.0))
        if 0.0 < track.share < 1.0:  # on the way between the two: the relit face shown so much
            d = face.data
            relit = d.get("photo_layers_relit") or d["photo_layers"]
            d["photo_layers"] = [(light, shown_share(layer, photo, track.share)) for light, layer in relit]
