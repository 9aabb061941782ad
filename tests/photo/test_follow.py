"""A clip's faces followed from frame to frame (``nodes/photo/follow.py``): on scikit-image's public-domain
``astronaut`` moved a few pixels a frame, her face is followed where the detector would find it, the detector runs on
a clip's first frame, every ``DETECT_EVERY``th after, after a gap and when the face is lost, and a photo's faces are
always found afresh."""
import numpy as np
import pytest
from shadowflow.nodes.photo import faces as F
from shadowflow.nodes.photo import follow


@pytest.fixture(scope="module")
def frames() -> list[np.ndarray]:
    """Twelve frames of the astronaut, her photo moved 3 px right and 2 px down a frame (its edge repeated)."""
    data = pytest.importorskip("skimage.data")
    photo = np.ascontiguousarray(data.astronaut())
    out = []
    for k in range(12):
        moved = np.roll(photo, (2 * k, 3 * k), axis=(0, 1))
        out.append(np.ascontiguousarray(moved))
    return out


@pytest.fixture
def found_afresh(monkeypatch) -> list[int]:
    """The frames (by call) on which the follower asked the detector (``find_faces``)."""
    calls: list[int] = []

    def counted(rgb):
        calls.append(len(calls))
        return F.find_faces(rgb)

    monkeypatch.setattr(follow, "find_faces", counted)
    return calls


def test_a_clips_face_is_followed_where_the_detector_finds_it(frames, found_afresh):
    follower = follow.FaceFollower(every=5)
    asked = []
    for k, rgb in enumerate(frames):
        before = len(found_afresh)
        faces = follower(rgb, {"stem": "talk", "index": k})
        asked.append(len(found_afresh) > before)
        (found,) = F.find_faces(rgb)
        assert len(faces) == 1
        # within 3 % of the eye distance of where the detector and its meshes place her eyes on that frame
        assert np.abs(faces[0].eyes - found.eyes).max() < 0.03 * found.iod, k
        assert faces[0].score == pytest.approx(found.score, abs=1e-6) or not asked[-1]
    assert [k for k, a in enumerate(asked) if a] == [0, 5, 10]  # the first frame, then every 5th


def test_a_gap_a_lost_face_and_a_photo_are_found_afresh(frames, found_afresh):
    follower = follow.FaceFollower(every=10)
    follower(frames[0], {"stem": "talk", "index": 0})
    follower(frames[1], {"stem": "talk", "index": 1})
    assert len(found_afresh) == 1
    follower(frames[3], {"stem": "talk", "index": 3})  # a frame left out (unreadable): found afresh
    assert len(found_afresh) == 2
    follower(frames[4], {"stem": "other", "index": 4})  # another clip
    assert len(found_afresh) == 3
    blank = np.full_like(frames[5], 128)
    assert follower(blank, {"stem": "other", "index": 5}) == []  # lost: the detector asked, and finds none
    assert len(found_afresh) == 4
    follower(frames[6], {"stem": "other", "index": 6})  # no face before: nothing to follow
    assert len(found_afresh) == 5
    follower(frames[7], None)  # a photo
    follower(frames[8], None)
    assert len(found_afresh) == 7
