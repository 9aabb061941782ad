"""Photometric stereo and registration, the ground truth of real photos."""
import numpy as np
from conftest import SHARED
from shadowflow.nodes.evaluation.photometric_stereo import photometric_stereo, register_translation
from shadowflow.nodes.evaluation.scenes import render_scene
from shadowflow.nodes.geometry.normals import angle_deg
from shadowflow.nodes.geometry.reflectance import light_from_angles
from shadowflow.nodes.model.faces.facegen import render_face, sample_face

YALEB = SHARED / "data" / "yaleb"


def test_photometric_stereo_recovers_a_rendered_face_despite_shadows_and_shine():
    rng = np.random.default_rng(4)
    depth, mask, albedo = render_face(sample_face(rng))
    lights = np.stack([light_from_angles(a, e) for a in (-70, -45, -20, 0, 20, 45, 70) for e in (-20, 0, 25)])
    images = []
    for k, s in enumerate(lights):
        img = render_scene(depth, albedo, s, mask).image.copy()  # cast and attached shadows included
        if k % 4 == 0:  # specular-like highlights on a few exposures
            img[40:46, 50:70] = 1.0
        images.append(img)
    truth = render_scene(depth, albedo, lights[0], mask).normals
    res = photometric_stereo(np.stack(images), lights)
    inner = mask & res.valid
    assert inner.sum() > 0.9 * mask.sum()
    assert np.median(angle_deg(res.normals[inner], truth[inner])) < 1.0
    assert np.mean(angle_deg(res.normals[inner], truth[inner])) < 3.0
    np.testing.assert_allclose(np.median(res.albedo[inner] / albedo[inner]), 1.0, atol=0.02)


def test_register_translation_undoes_a_subpixel_shift():
    import cv2

    rng = np.random.default_rng(0)
    a = cv2.GaussianBlur(rng.random((192, 168)).astype(np.float32), (0, 0), 3)
    b = cv2.warpAffine(a, np.float32([[1, 0, 2.5], [0, 1, -1.5]]), (168, 192), borderMode=cv2.BORDER_REPLICATE)
    moved, (dx, dy) = register_translation(b, a)
    assert abs(dx - 2.5) < 0.35 and abs(dy + 1.5) < 0.35
    assert np.abs(moved - a)[8:-8, 8:-8].mean() < 0.2 * np.abs(b - a)[8:-8, 8:-8].mean()
