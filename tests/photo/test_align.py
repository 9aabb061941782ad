"""Mapping between the photo and the model grid."""
import pytest
import numpy as np
from shadowflow.nodes.evaluation.scenes import render_scene
from shadowflow.nodes.geometry.normals import angle_deg
from shadowflow.nodes.geometry.reflectance import light_from_angles
from shadowflow.nodes.model.faces.facegen import render_face, sample_face
from shadowflow.nodes.photo.align import Alignment, eyes_alignment, normals_to_input, stretch_vertically

MOUTH = np.array([64.0, 87.0])
EYE_ROW = 48.0


def _save(model, folder):
    from shadowflow.nodes.model.shape_model import save_model

    return save_model(model, folder / "model.npz")


def test_a_stretched_alignment_keeps_the_eyes_moves_the_mouth_and_turns_vectors_only():
    eyes_in = np.array([[40.0, 60.0], [100.0, 66.0]])  # a tilted face
    model_eyes = np.array([[46.0, EYE_ROW], [82.0, EYE_ROW]])
    al = eyes_alignment(eyes_in, model_eyes, "eyes")
    st = stretch_vertically(al, 0.9, EYE_ROW, "stretched")
    assert stretch_vertically(al, 1.0, EYE_ROW, "x") is al

    def to_input(a: Alignment, p):
        return a.matrix @ np.array([p[0], p[1], 1.0])

    for e in model_eyes:  # the eyes stay where they were
        np.testing.assert_allclose(to_input(st, e), to_input(al, e), atol=1e-9)
    # the model's mouth lands 0.9 of the way down the eyes' perpendicular
    mid_in = to_input(al, model_eyes.mean(axis=0))
    drop = to_input(st, MOUTH) - mid_in
    np.testing.assert_allclose(np.linalg.norm(drop), 0.9 * np.linalg.norm(to_input(al, MOUTH) - mid_in), rtol=1e-9)
    # vectors follow the same rotation as without the stretch
    np.testing.assert_allclose(st.rotation, al.rotation, atol=1e-9)
    n = np.zeros((128, 128, 3), np.float32)
    n[..., 2] = 1.0
    n[..., 0] = 0.3
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    mask = np.zeros((128, 128), bool)
    mask[30:100, 30:100] = True
    a = normals_to_input(n, mask, al, (160, 150))
    b = normals_to_input(n, mask, st, (160, 150))
    both = np.isfinite(a[..., 0]) & np.isfinite(b[..., 0])
    np.testing.assert_allclose(a[both], b[both], atol=1e-5)


def test_an_off_grid_photo_is_aligned_by_its_eyes_and_mapped_back(procedural_model, tmp_path):
    """A face rendered at another scale, rotated and shifted inside a larger photo, with its
    eyes given: the normals must match the rendered truth on the model grid, in the photo's frame, and on
    the photo's grid, whether written there (``--arrays photo``) or brought there (``read_arrays``)."""
    import json

    import shadowflow
    import cv2
    from shadowflow.nodes.app.cli import main
    from shadowflow.nodes.model.canonical import canonical_eyes
    from shadowflow.nodes.photo.align import eyes_alignment

    rng = np.random.default_rng(11)
    depth, mask, albedo = render_face(sample_face(rng))
    s = light_from_angles(40, 0)
    scene = render_scene(depth, albedo, s, mask)
    eyes_photo = np.array([[70.0, 95.0], [128.0, 88.0]])  # scaled by ~1.6 and rotated ~7 degrees
    al = eyes_alignment(eyes_photo, canonical_eyes((128, 128)))
    shape = (240, 200)
    photo = cv2.warpAffine(scene.image.astype(np.float32), al.matrix, shape[::-1], flags=cv2.INTER_LINEAR)
    path = tmp_path / "photo.png"
    cv2.imwrite(str(path), (np.clip(photo, 0, 1) * 255 + 0.5).astype(np.uint8))
    light = al.vector_to_input(s)
    out = tmp_path / "out"
    args = ["run", str(path), "--record", "none", "--quiet", "--model", str(_save(procedural_model, tmp_path)),
            "--light=" + ",".join(f"{x:.6f}" for x in light), "--eyes=" + ",".join(f"{v:g}" for v in eyes_photo.ravel())]
    assert main([*args, "--out", str(out)]) == 0
    assert main([*args, "--out", str(tmp_path / "full"), "--arrays", "photo"]) == 0
    # on the model grid (the default): the fit's own pixels, its vectors in the photo's frame
    grid = np.load(out / "photo" / "normals.npy")
    place = json.loads((out / "photo" / "grid.json").read_text())
    assert grid.shape == (128, 128, 3) and place["grid"] == [128, 128] and place["photo"] == list(shape)
    np.testing.assert_allclose(place["to_photo"], al.matrix, atol=0.05)  # the eyes the run found, as given
    inner_model = cv2.erode(mask.astype(np.uint8), np.ones((7, 7))) > 0
    ok = inner_model & np.isfinite(grid[..., 0])
    assert ok.sum() > 3500
    assert np.mean(angle_deg(grid[ok], al.vector_to_input(scene.normals[ok]))) < 6.0
    # on the photo's grid
    truth_model = np.where(mask[..., None], scene.normals, 0).astype(np.float32)
    truth = np.stack([cv2.warpAffine(truth_model[..., i], al.matrix, shape[::-1]) for i in range(3)], -1)
    truth = al.vector_to_input(truth)
    truth /= np.maximum(np.linalg.norm(truth, axis=-1, keepdims=True), 1e-12)
    inner = cv2.warpAffine(cv2.erode(mask.astype(np.uint8), np.ones((7, 7))), al.matrix, shape[::-1]) > 0
    written = np.load(tmp_path / "full" / "photo" / "normals.npy")
    brought = shadowflow.read_arrays(out / "photo", on_photo_grid=True)["normals"]
    assert written.shape == brought.shape == shape + (3,)
    for n in (written, brought):
        ok = inner & np.isfinite(n[..., 0])
        assert ok.sum() > 10000
        assert np.mean(angle_deg(n[ok], truth[ok])) < 6.0
    both = np.isfinite(written[..., 0]) & np.isfinite(brought[..., 0])
    assert both.sum() > 0.97 * np.isfinite(written[..., 0]).sum()
    assert np.percentile(angle_deg(written[both], brought[both]), 99) < 0.5


def test_a_mask_comes_to_the_photo_with_a_smooth_border_not_a_staircase_of_model_pixels():
    """A model-grid mask cut along a shallow slope (a row every four columns, as a jaw line runs),
    brought to a photo 4x finer: its border there lies within a pixel of a straight line
    (measured 0.83 px; unsmoothed, the model pixels' steps put it 1.86 px off)."""
    from shadowflow.nodes.photo.align import Alignment, mask_to_input

    rows, cols = np.mgrid[0:32, 0:32]
    mask = (rows >= cols / 4.0 + 5) & (rows < 28) & (cols > 2) & (cols < 29)
    al = Alignment(np.array([[4.0, 0.0, 0.0], [0.0, 4.0, 0.0]]), "x4")
    photo = mask_to_input(mask, al, (128, 128))
    top = np.argmax(photo, axis=0)[20:100]  # each column's first face pixel
    x = np.arange(20, 100)
    assert np.abs(top - np.polyval(np.polyfit(x, top, 1), x)).max() < 1.0
    assert photo.sum() == pytest.approx(mask.sum() * 16, rel=0.05)  # the face keeps its size


@pytest.mark.parametrize("eyes", [[[500.0, 400.0], [620.0, 410.0]], [[10.0, 5.0], [200.0, 30.0]],
                                  [[1150.0, 870.0], [1190.0, 880.0]], [[-30.0, 400.0], [60.0, 380.0]]])
def test_the_model_grid_is_sampled_from_the_photo_as_if_the_whole_photo_were_blurred(eyes):
    """``to_model_grid`` and ``inside_input`` touch only the photo's pixels the grid (and the blur)
    reach; what they give is the same, to the bit, as blurring and warping the whole photo, for a face
    in the middle, at a corner, small, and partly off the photo."""
    import cv2
    from shadowflow.nodes.photo.align import inside_input, to_model_grid

    rng = np.random.default_rng(0)
    photo = rng.random((900, 1200)).astype(np.float32)
    al = eyes_alignment(np.array(eyes), np.array([[40.0, 50.0], [88.0, 50.0]]))
    whole = cv2.GaussianBlur(photo, (0, 0), 0.5 * np.sqrt(al.scale**2 - 1.0)) if al.scale > 1.5 else photo
    flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    expected = cv2.warpAffine(whole, al.matrix, (128, 128), flags=flags, borderMode=cv2.BORDER_REPLICATE)
    np.testing.assert_array_equal(to_model_grid(photo, al, (128, 128)), expected)
    ones = cv2.warpAffine(np.ones(photo.shape, np.float32), al.matrix, (128, 128), flags=flags,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    np.testing.assert_array_equal(inside_input(al, photo.shape, (128, 128)), ones >= 0.999)


def test_a_faces_products_lie_inside_the_box_they_are_computed_on():
    """The fields and the mask a face's products hold, brought to the whole photo, are known only
    inside ``face_box(..., reach_margin)``: computing them on that box loses nothing (a box one model
    pixel short of the reach cut the mask's edge)."""
    from shadowflow.nodes.photo.align import face_box, mask_to_input, reach_margin, scalar_to_input

    mask = np.zeros((128, 128), bool)
    mask[20:110, 25:100] = True
    shape = (700, 900)
    for eyes in ([[300.0, 250.0], [420.0, 262.0]], [[500.0, 300.0], [520.0, 340.0]]):
        al = eyes_alignment(np.array(eyes), np.array([[46.0, 48.0], [82.0, 48.0]]))
        y0, y1, x0, x1 = face_box(mask, al, shape, margin=reach_margin(al))
        known = np.isfinite(scalar_to_input(np.ones((128, 128), np.float32), mask, al, shape)) | mask_to_input(mask, al, shape)
        outside = known.copy()
        outside[y0:y1, x0:x1] = False
        assert known.sum() > 1000 and not outside.any()
        boxed = mask_to_input(mask, al.cropped(x0, y0), (y1 - y0, x1 - x0))
        assert np.mean(boxed != mask_to_input(mask, al, shape)[y0:y1, x0:x1]) < 1e-3
