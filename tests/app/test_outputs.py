"""What a photo of several face candidates reports (``outputs``): the photo's face is the first that came
through, a larger candidate the fit found no face in does not make the photo an error."""
import numpy as np
from shadowflow.flow.frame import Frame
from shadowflow.nodes.app.outputs import face_folder, faces_of, status_lines, summary_record


def _photo(*statuses):
    """A photo's frame whose parts (largest first) end with ``statuses``: "ok", or a failure's reason."""
    photo = Frame(0, "group.jpg", meta={"stem": "group"})
    for k, status in enumerate(statuses, start=1):
        source = "group.jpg" if k == 1 else f"group.jpg (face {k})"
        part = Frame(0, source, data={"fit": object()}, meta={"face": k, "quality": {"score": 0.8, "flags": []},
                                                              "placement": {"eyes": [[k, 0], [k + 5, 0]]}})
        if status != "ok":
            part.fail("quality" if "no face" in status else "robust_fit", f"{source}: {status}")
        photo.parts.append(part)
    return photo


def test_a_refused_larger_candidate_gives_its_place_to_the_first_real_face():
    photo = _photo("no face found (the fitted face explains 17 % of the image's shading)", "ok", "ok")
    first, second = faces_of(photo)
    assert first is photo.parts[1] and face_folder(photo, first) == "" and face_folder(photo, second) == "face-3"
    rec = summary_record(photo)
    assert rec["status"] == "ok"
    assert [f.get("dir") for f in rec["faces"]] == [None, "group", "group/face-3"]
    assert "no face found" in rec["faces"][0]["status"]  # listed, with its reason
    assert status_lines(rec) == []  # not the photo's error: it has its faces


def test_a_real_face_that_failed_is_still_named_and_no_face_at_all_is_the_photos_error():
    rec = summary_record(_photo("ok", "timed out after 120 s in robust_fit"))
    assert rec["status"] == "ok" and [f.get("dir") for f in rec["faces"]] == ["group", None]
    assert status_lines(rec) == ["error: group.jpg (face 2): timed out after 120 s in robust_fit"]
    alone = _photo("ok")
    assert face_folder(alone, faces_of(alone)[0]) == "" and summary_record(alone)["faces"][0]["dir"] == "group"
    none = _photo("no face found (a pattern)", "no face found (noise)")
    none.fail("quality", "group.jpg: no face found (a pattern)")
    rec = summary_record(none)
    assert rec["status"].startswith("group.jpg: no face found") and faces_of(none) == []
    assert status_lines(rec) == ["error: group.jpg: no face found (a pattern)"]
    assert np.all([f.get("dir") is None for f in rec["faces"]])
