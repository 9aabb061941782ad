"""The method's accuracy criteria (issue 2) on a CI-sized subset: 100 training faces, 8 held-out
test faces (the full 20-face tables come from ``shadowflow eval``, see README)."""
import pytest
from shadowflow.nodes.evaluation.synthetic import evaluate
from shadowflow.nodes.model.shape_model import train_shape_model
from shadowflow.nodes.model.sources import eos_model, procedural

N_TEST = 8
# issue 2: mean angular error of the final normals, degrees, by light angle
MAX_ERR = {"45": 3.5, "60": 5.0, "75": 7.0}
MIN_CAST_IOU = {"45": 0.75, "60": 0.75}


def _check(report):
    for angle, limit in MAX_ERR.items():
        assert report["per_angle"][angle]["err_all"] <= limit, (angle, report["per_angle"][angle])
    for angle, limit in MIN_CAST_IOU.items():
        assert report["per_angle"][angle]["cast_iou"] >= limit, (angle, report["per_angle"][angle])


@pytest.mark.slow
def test_procedural_source(procedural_model):
    test, _ = procedural(N_TEST, seed=1)
    report = evaluate(procedural_model, test, None, [45, 60, 75])
    _check(report)
    # light from the other side is no different
    mirrored = evaluate(procedural_model, test[:4], None, [-60])
    assert mirrored["per_angle"]["-60"]["err_all"] <= MAX_ERR["60"]


@pytest.fixture(scope="module")
def sfm_faces(sfm_path):
    train, _ = eos_model(sfm_path, 100, seed=0)
    test, _ = eos_model(sfm_path, N_TEST, seed=1)
    return train, test


@pytest.mark.slow
def test_sfm_source(sfm_faces):
    train, test = sfm_faces
    model = train_shape_model(train, 60, source="sfm")
    _check(evaluate(model, test, None, [45, 60, 75]))


@pytest.mark.slow
def test_built_in_models_on_sfm_faces(sfm_faces):
    """Cross-source: the two built-in models on faces of another real-scan model (SFM). The
    default, trained on ICT-FaceKit's real scans, does better than the procedural one although
    its floor on these faces is no lower (10.1 vs 9.3 deg): its mean face is closer to real ones.
    Measured on these 8 faces at 45 deg: ICT 12.4, procedural 14.7 deg."""
    from shadowflow.nodes.model.default_model import built_in_model

    _, test = sfm_faces
    err = {name: evaluate(built_in_model(name), test, None, [45])["per_angle"]["45"]["err_all"]
           for name in ("ict", "procedural")}
    assert err["ict"] <= 13.5 and err["ict"] < err["procedural"] - 1.0, err
