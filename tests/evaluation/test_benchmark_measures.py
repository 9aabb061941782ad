"""The Yale B benchmark's measures of a relit face (``nodes/evaluation/yaleb_benchmark.py``) on synthetic
images whose answer is known; no data needed."""
import numpy as np
from shadowflow.nodes.evaluation.yaleb_benchmark import nose_shadow_level


def _face():
    """A 200 x 200 'frontal photo': smooth skin with some texture, eyes at (70, 80) and (130, 80), and a side
    light's cast shadow beside the nose (a band at x 105-115, y 95-165) and one on the forehead, outside the
    nose's box."""
    rng = np.random.default_rng(2)
    yy, xx = np.mgrid[0:200, 0:200]
    frontal = 0.5 + 0.1 * np.cos(xx / 30.0) + 0.02 * rng.standard_normal((200, 200))
    cast = ((xx >= 105) & (xx <= 115) & (yy >= 95) & (yy <= 165)) | ((yy < 30) & (xx > 150))
    return frontal, cast, np.ones((200, 200), bool), np.array([[70.0, 80.0], [130.0, 80.0]])


def test_a_cast_shadow_kept_beside_the_nose_reads_under_the_frontal_level_and_one_removed_reads_one():
    frontal, cast, region, eyes = _face()
    assert abs(nose_shadow_level(frontal, frontal, region, cast, eyes) - 1.0) < 1e-9
    assert abs(nose_shadow_level(2.0 * frontal, frontal, region, cast, eyes) - 1.0) < 1e-9  # gain-corrected
    kept = np.where(cast, 0.6 * frontal, frontal)  # the band left at 60 % of the light
    assert 0.58 < nose_shadow_level(kept, frontal, region, cast, eyes) < 0.62
    # the forehead's shadow is not the nose's: kept there alone, the nose reads clean
    forehead = np.where(cast & (np.mgrid[0:200, 0:200][0] < 30), 0.3 * frontal, frontal)
    assert 0.99 < nose_shadow_level(forehead, frontal, region, cast, eyes) < 1.02
    # a turned face's box turns with its eyes (a quarter turn: the band now lies across, left of the nose)
    turned = np.rot90(kept)
    assert 0.58 < nose_shadow_level(turned, np.rot90(frontal), region, np.rot90(cast),
                                    np.array([[80.0, 130.0], [80.0, 70.0]])) < 0.62
    assert np.isnan(nose_shadow_level(frontal, frontal, region, cast & False, eyes))  # no cast shadow
