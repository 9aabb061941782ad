"""A clip's faces kept steady from frame to frame: each face tracked by where its box is, and the light estimated on
it carried and smoothed over the frames of one person under one light (``LightSmoother``), a real change (a light
switched, a cut) followed within ``CONFIRM`` frames. ``SteadyLightNode`` gives the fit the smoothed light as the
face's light. Frames of a clip reach it in order: it runs on one thread, after the faces are found (one thread too)."""
from __future__ import annotations

import numpy as np

from ...flow.frame import Frame

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
# frame is fitted under its own estimate meanwhile);
CONFIRM = 3
# TRACK_MATCH: a face is the same as one of the frame before when its box's centre moved less than this many of
# its box's sides; TRACK_MEMORY: a face unseen this many frames is forgotten (its light starts afresh).
TRACK_MATCH = 0.5
TRACK_MEMORY = 5


def angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """The angle between two vectors, in degrees."""
    c = float(np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b) + 1e-12))
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def _unit(v: np.ndarray) -> np.ndarray:
    return v / max(float(np.linalg.norm(v)), 1e-12)


class LightSmoother:
    """One face's light over a clip's frames: ``update(raw)`` takes the frame's estimate (a vector toward the light)
    and returns the running light (unit), as the constants above say."""

    def __init__(self, alpha: float = ALPHA, jump_deg: float = JUMP_DEG, confirm: int = CONFIRM):
        self.alpha, self.jump_deg, self.confirm = alpha, jump_deg, confirm
        self.light: np.ndarray | None = None
        self.departed: list[np.ndarray] = []  # the estimates in a row that left the running light

    def update(self, raw) -> np.ndarray:
        raw = _unit(np.asarray(raw, np.float64))
        if self.light is None:
            self.light = raw
        elif angle_deg(raw, self.light) > self.jump_deg:
            # a departure: the frame is fitted under its own estimate (under the running light a switched light
            # fails the fit: "no face found"), and the running light is left as it is until it is confirmed
            self.departed.append(raw)
            if len(self.departed) < self.confirm:
                return raw.copy()
            self.light, self.departed = _unit(np.mean(self.departed[-self.confirm:], axis=0)), []
        else:
            self.departed = []
            self.light = _unit((1.0 - self.alpha) * self.light + self.alpha * raw)
        return self.light.copy()


class _Track:
    def __init__(self, box: list, index: int):
        self.box, self.seen, self.smoother = box, index, LightSmoother()

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

    def __init__(self) -> None:
        self.clip: str | None = None
        self.tracks: list[_Track] = []

    def __call__(self, frame: Frame) -> Frame:
        clip = frame.meta.get("clip")
        if not clip:
            return frame
        if clip["stem"] != self.clip:  # a new clip: nothing carried over
            self.clip, self.tracks = clip["stem"], []
        index = int(clip["index"])
        self.tracks = [t for t in self.tracks if index - t.seen <= TRACK_MEMORY]
        free = list(self.tracks)
        for face in frame.parts:
            box = (face.meta.get("placement") or {}).get("box")
            if not face.ok or box is None or face.meta.get("light_source") != "estimated":
                continue
            track = min(free, key=lambda t: t.near(box), default=None)
            if track is None or not np.isfinite(track.near(box)):
                track = _Track(box, index)
                self.tracks.append(track)
            else:
                free.remove(track)
            track.box, track.seen = box, index
            self._steady(face, track.smoother.update(face.data["light"]))
        return frame

    @staticmethod
    def _steady(face: Frame, light: np.ndarray) -> None:
        face.meta["light_raw"] = face.meta.get("light")
        face.data["light"] = light
        face.data["grid_light"] = face.data["alignment"].vector_to_model(light)
        face.meta.update(light=[round(float(x), 6) for x in light], light_source="steadied")
