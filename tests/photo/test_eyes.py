"""Finding the eyes."""
import numpy as np
from conftest import SHARED
from shadowflow.nodes.photo.eyes import merge_overlapping, pick_eyes

YALEB = SHARED / "data" / "yaleb"


def test_eye_pairing_merges_nested_boxes_and_mirrors_a_lost_eye():
    # two boxes on the left eye (nested), one on the right, one on the nose, one in the hair
    c = np.array([[30, 48, 36], [34, 47, 24], [128, 47, 30], [84, 95, 22], [20, 5, 25]], float)
    eyes, how = pick_eyes(merge_overlapping(c), (192, 168))
    assert how == "eyes found"
    np.testing.assert_allclose(eyes, [[32, 47.5], [128, 47]], atol=1.5)
    eyes, how = pick_eyes(np.array([[128.0, 47, 30]]), (192, 168))  # the left eye lost in shadow
    assert "mirrored" in how and np.allclose(eyes, [[39, 47], [128, 47]])
    assert pick_eyes(np.zeros((0, 3)), (192, 168)) == (None, "no eyes found")
