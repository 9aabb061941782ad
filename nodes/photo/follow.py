"""A clip's faces followed from frame to frame (``FaceFollower``): a face moves little between frames, so its last mesh
says where to look for it, and the detector's 30-odd looks at a frame (a seventh of a 720p frame's time, with the meshes
it asks for) are spent only on a clip's first frame, every ``DETECT_EVERY``th after, and when a face is lost."""
from __future__ import annotations

from .faces import MAX_ROLL, FoundFace, confirmed_face, find_faces, part_of
from .mediapipe import roi_from_mesh

# a clip's faces are found afresh at least every this many frames (a face that comes into the frame is met within them)
DETECT_EVERY = 10


def followed_faces(rgb, previous: list[FoundFace]) -> list[FoundFace] | None:
    """The faces of a clip's frame ``rgb`` (H, W, 3) uint8 where the frame before showed ``previous`` (largest first):
    each meshed again from the crop its last mesh implies and followed until that crop stays put
    (``faces.confirmed_face``, as a found face's own crop is), keeping its detector's score; None when any of them is
    lost there (not confirmed, turned past ``MAX_ROLL``, or become a part of another: ``faces.part_of``)."""
    faces = []
    for before in previous:
        face = confirmed_face(rgb, roi_from_mesh(before.mesh), before.score)
        if face is None or abs(face.roll) > MAX_ROLL:
            return None
        faces.append(face)
    faces.sort(key=lambda f: -f.iod)
    if any(part_of(f, g) for k, f in enumerate(faces) for g in faces[:k]):
        return None
    return faces


class FaceFollower:
    """``follower(rgb, clip)``: the faces of a frame (``faces.find_faces``), or of a clip's frame (``clip``: its
    ``meta["clip"]``, with ``stem`` and ``index``) followed from the frame before it (``followed_faces``) when that
    frame came just before, was not the ``DETECT_EVERY``th since the faces were found and showed faces. Frames must
    come in order (one caller)."""

    def __init__(self, every: int = DETECT_EVERY):
        self.every = every
        self.last: tuple[str, int] | None = None  # the clip and index of the frame before
        self.faces: list[FoundFace] = []
        self.followed = 0  # frames followed since the faces were found

    def __call__(self, rgb, clip: dict | None = None) -> list[FoundFace]:
        at = (clip["stem"], int(clip["index"])) if clip and "index" in clip else None
        faces = None
        if at is not None and self.faces and self.last == (at[0], at[1] - 1) and self.followed + 1 < self.every:
            faces = followed_faces(rgb, self.faces)
        self.followed = 0 if faces is None else self.followed + 1
        if faces is None:
            faces = find_faces(rgb)
        self.last, self.faces = at, faces if at is not None else []
        return faces
