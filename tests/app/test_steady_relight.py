"""A clip's relit faces held steady after relighting (``app.steady.SteadyRelightNode``), on frames made by hand: the
honesty step's verdict on single frames does not flip the face between relit and left as it was, a real change of
verdict is followed after ``HONEST_CONFIRM`` frames, and each frame's change of light is carried (its level
steadied)."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from shadowflow.flow.frame import Frame
from shadowflow.nodes.app.steady import HONEST_CONFIRM, HONEST_RAMP, SteadyRelightNode, SteadyYawNode
from shadowflow.nodes.relight.compose import FaceLayer
from shadowflow.nodes.relight.nodes import LEFT, left_as_it_was, left_flag, unchanged

H = W = 120
EYES = np.array([[45.0, 50.0], [75.0, 50.0]])
PHOTO = np.full((H, W, 3), 0.3, np.float32)
YY, XX = np.mgrid[:H, :W]
INSIDE = np.hypot(XX - 60, YY - 65) < 35


def relit_layer(k: float) -> FaceLayer:
    gain = np.where(INSIDE[..., None], k, 1.0).astype(np.float32)
    return FaceLayer((0, H, 0, W), INSIDE, PHOTO * np.float32(k), gain)


def clip_frame(index: int, left: bool, k: float = 2.0, track: int = 0) -> Frame:
    """A clip's frame of one tracked face relit ``k`` times brighter, or left as it was (as the honesty step leaves
    it: flagged, its relit layers kept)."""
    frame = Frame(index, f"clip frame {index}")
    frame.meta["clip"] = {"stem": "talk", "index": index}
    face = Frame(index, frame.source)
    face.meta.update(track=track, quality={"score": 0.8, "flags": []})
    face.data.update(colour=PHOTO, placement=SimpleNamespace(eyes=EYES),
                     photo_layers=[(np.array([0.0, 0.0, 1.0]), relit_layer(k))])
    if left:
        face.data["photo_layers_relit"] = face.data["photo_layers"]
        face.data["photo_layers"] = [(light, unchanged(layer, PHOTO)) for light, layer in face.data["photo_layers"]]
        face.meta["quality"] = {"score": 0.4, "flags": [left_flag(12.0)]}
    frame.parts.append(face)
    return frame


def level(face: Frame) -> float:
    return float(face.data["photo_layers"][0][1].relit[65, 60, 0] / PHOTO[65, 60, 0])


def test_single_frames_left_as_they_were_do_not_flip_the_face():
    node = SteadyRelightNode()
    verdicts = [False, False, True, False, True, False, False, True, False, True]
    faces = [node(clip_frame(i, left)).parts[0] for i, left in enumerate(verdicts)]
    assert not any(left_as_it_was(f) for f in faces)
    assert all(abs(level(f) - 2.0) < 1e-4 for f in faces)  # every frame relit, as the face's frames mostly say
    assert all(f.meta["quality"]["score"] == 0.8 and f.meta["quality"]["flags"] == [] for f in faces)


def test_a_lasting_verdict_is_followed_after_its_confirmation():
    """A relighting that harms is taken away after HONEST_CONFIRM[True] frames say so, blended out over
    HONEST_RAMP[True]; given back after HONEST_CONFIRM[False], over HONEST_RAMP[False]."""
    node = SteadyRelightNode()
    out_frames = HONEST_CONFIRM[True] + HONEST_RAMP[True] + 5
    back_frames = HONEST_CONFIRM[False] + HONEST_RAMP[False] + 5
    verdicts = [False] * 4 + [True] * out_frames + [False] * back_frames
    faces = [node(clip_frame(i, left)).parts[0] for i, left in enumerate(verdicts)]
    levels = np.array([level(f) for f in faces])
    leave = 4 + HONEST_CONFIRM[True] - 1
    back = 4 + out_frames + HONEST_CONFIRM[False] - 1
    expected = [False] * leave + [True] * (back - leave) + [False] * (len(faces) - back)
    assert [left_as_it_was(f) for f in faces] == expected
    for start, ramp, sign in ((leave, HONEST_RAMP[True], -1), (back, HONEST_RAMP[False], 1)):
        steps = sign * np.diff(levels[start - 1:start + ramp + 3])
        assert np.all(steps >= -1e-6) and steps.max() < 1.5 / ramp  # one way, in steps no larger than the ramp's
        assert 1.1 < levels[start + ramp // 2] < 1.9
    assert abs(levels[4 + out_frames - 1] - 1.0) < 0.05 and abs(levels[-1] - 2.0) < 0.05


def test_a_face_left_from_its_first_frames_stays_left_through_single_relit_frames():
    node = SteadyRelightNode()
    verdicts = [True, True, False, True, False, True, True]
    faces = [node(clip_frame(i, left)).parts[0] for i, left in enumerate(verdicts)]
    assert all(left_as_it_was(f) for f in faces)
    assert all(f.meta["quality"]["flags"][-1].endswith(LEFT) for f in faces)
    assert all(abs(level(f) - 1.0) < 1e-4 for f in faces)


def test_the_level_of_a_jittering_relit_face_is_steadied():
    node = SteadyRelightNode()
    ks = [2.0 * (1.15 if i % 2 else 1 / 1.15) for i in range(12)]
    levels = [level(node(clip_frame(i, False, k)).parts[0]) for i, k in enumerate(ks)]
    assert np.abs(np.diff(np.log(levels[4:]))).mean() < 0.3 * np.abs(np.diff(np.log(ks[4:]))).mean()


def test_a_face_seen_again_after_a_gap_starts_afresh():
    node = SteadyRelightNode()
    for i in range(3):
        node(clip_frame(i, False, 2.0))
    after_gap = node(clip_frame(10, False, 3.0)).parts[0]
    assert abs(level(after_gap) - 3.0) < 1e-4
    photo = Frame(11, "photo.png")
    photo.parts.append(clip_frame(11, False, 5.0).parts[0])
    assert abs(level(node(photo).parts[0]) - 5.0) < 1e-4  # a photo passes untouched


def yaw_frame(index: int, landmarks: float, refresh: bool | str, fit: float | None = None, track: int = 0) -> Frame:
    """A clip's frame of one tracked face whose landmarks read ``landmarks`` degrees of yaw; read by the fit too
    (``fit``), its pose's yaw the two's mean, as ``turned.ViewChoiceNode`` leaves it."""
    frame = Frame(index, f"clip frame {index}")
    frame.meta["clip"] = {"stem": "talk", "index": index}
    face = Frame(index, frame.source)
    yaw = landmarks if fit is None else 0.5 * (landmarks + fit)
    face.meta.update(track=track, view_refresh=refresh, placement={"pose": {"yaw": yaw, "pitch": 0.0, "roll": 0.0}})
    if fit is not None:
        face.meta["yaw_read"] = {"landmarks": landmarks, "fit": fit}
    frame.parts.append(face)
    return frame


def test_the_yaw_the_fit_read_is_carried_to_the_frames_between():
    node = SteadyYawNode()
    first = node(yaw_frame(0, 2.0, True, fit=-6.0)).parts[0]  # read 4 deg less than the landmarks say
    assert first.meta["placement"]["pose"]["yaw"] == -2.0
    between = [node(yaw_frame(i, 2.0 + i, False)).parts[0] for i in range(1, 4)]
    assert [f.meta["placement"]["pose"]["yaw"] for f in between] == [-1.0, 0.0, 1.0]
    assert all(f.meta["yaw_read"]["carried"] == -4.0 for f in between)
    again = node(yaw_frame(4, 3.0, True, fit=3.0)).parts[0]  # read anew: its own, and carried from then on
    assert again.meta["placement"]["pose"]["yaw"] == 3.0
    # the carried share the two readings' mean: a single fit's yaw varies
    assert node(yaw_frame(5, 1.0, False)).parts[0].meta["placement"]["pose"]["yaw"] == -1.0
    moved = yaw_frame(6, -5.0, "light", fit=5.0)  # read under a light moved since: the readings before are not
    node(moved)  # averaged in
    assert node(yaw_frame(7, -5.0, False)).parts[0].meta["placement"]["pose"]["yaw"] == 0.0
    other = node(yaw_frame(6, 5.0, False, track=1)).parts[0]  # a face never read: as its landmarks say
    assert other.meta["placement"]["pose"]["yaw"] == 5.0 and "yaw_read" not in other.meta


class _Aged:
    """Marks each face of a photo as tracked ``age`` frames, as ``SteadyLightNode`` marks a clip's."""

    name = "aged"

    def __init__(self, age: int):
        self.age = age

    def __call__(self, frame: Frame) -> Frame:
        for face in frame.parts:
            face.meta["track_age"] = self.age
        return frame


def test_a_face_tracked_over_frames_is_not_refused_as_no_face_by_its_fit():
    """Concentric rings, which the face mesh takes for a face and its fit explains nothing of, are no face; on a clip
    whose frames before had that face where it is, they are the face, doubtful and relit (one bad fit of a webcam
    face had left its frame unrelit between relit ones)."""
    from shadowflow.flow.chain import Chain
    from shadowflow.nodes.app.api import _model
    from shadowflow.nodes.method.quality import TRACKED_FACE
    from shadowflow.nodes.method.options import MethodOptions
    from shadowflow.nodes.relight.nodes import photo_nodes

    yy, xx = np.mgrid[0:256, 0:256]
    rings = (np.clip(0.5 + 0.4 * np.cos(np.hypot(xx - 128, yy - 128) / 5), 0, 1) * 255).astype(np.uint8)
    model, options = _model(None), MethodOptions()

    def faces(age: int) -> list[Frame]:
        chain = Chain(photo_nodes(model, options, after_faces=(_Aged(age),)))
        return chain.process(Frame(0, "rings.png", data={"samples": rings})).parts

    refused = faces(TRACKED_FACE - 1)
    assert refused and all(not f.ok and "no face found" in f.status for f in refused)
    kept = [f for f in faces(TRACKED_FACE) if f.ok]
    assert kept and all("photo_layers" in f.data for f in kept)
    assert any("tracked" in flag for flag in kept[0].meta["quality"]["flags"])
