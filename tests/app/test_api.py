"""The Python API (``shadowflow.fit``, ``shadowflow.run``) and the README's example of it."""
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import shadowflow
from shadowflow.nodes.evaluation.scenes import write_shadowed_face
from shadowflow.nodes.geometry.reflectance import light_from_angles
from shadowflow.nodes.photo.loader import InputError

README = Path(__file__).resolve().parents[2] / "README.md"


def _readme_python_example() -> str:
    text = README.read_text()
    section = text[text.index("\n## Python\n"):]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def test_the_readme_python_example_runs(tmp_path):
    """Run as a user would paste it, in a fresh interpreter, in an empty folder."""
    proc = subprocess.run([sys.executable, "-c", _readme_python_example()], cwd=tmp_path, capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert (tmp_path / "out" / "face" / "normals.npy").is_file()
    assert (tmp_path / "out" / "stream" / "summary.json").is_file()
    assert "converged True" in proc.stdout, proc.stdout


def test_fit_gives_what_shadowflow_run_writes(tmp_path, procedural_model):
    """The API and the command line run the same nodes: the saved files are byte-identical."""
    photo = write_shadowed_face(tmp_path / "face.png", np.random.default_rng(4), light_from_angles(50))
    result = shadowflow.fit(photo, model=procedural_model)
    result.save(tmp_path / "api")
    run = shadowflow.run([photo], tmp_path / "run", model=procedural_model, record=())
    assert [r["status"] for r in run.records] == ["ok"]
    for name in ("normals.npy", "depth.npy", "albedo.png", "shadow.png", "relit.png", "mesh.ply"):
        assert (tmp_path / "api" / name).read_bytes() == (tmp_path / "run" / "face" / name).read_bytes(), name
    assert result.iterations == run.records[0]["iterations"] == len(result.history)
    assert result.history[-1]["change_deg"] < 0.05 and result.converged
    # the products on the photo's grid: unit normals on the face, NaN off it, shadows where lit is not
    face = result.mask
    assert face.mean() > 0.2 and np.allclose(np.linalg.norm(result.normals[face], axis=1), 1, atol=1e-4)
    assert np.isnan(result.depth[~face]).all() and not result.shadow[~face].any()
    assert len(result.mesh["triangles"]) > 1000


def test_fit_takes_an_array_as_the_file_loader_reads_it(tmp_path, procedural_model):
    """An RGB uint8 array is the file's luminance: same light and eyes, same normals."""
    import cv2

    photo = write_shadowed_face(tmp_path / "face.png", np.random.default_rng(5), light_from_angles(-40))
    from_file = shadowflow.fit(photo, model=procedural_model)
    grey = cv2.imread(str(photo), cv2.IMREAD_GRAYSCALE)
    rgb = np.dstack([grey, grey, grey])
    eyes = np.array([[46.0, 48.0], [82.0, 48.0]])  # the sidecar's: where the generator put them
    from_array = shadowflow.fit(rgb, light=from_file.light, eyes=eyes, model=procedural_model)
    np.testing.assert_allclose(from_array.normals, from_file.normals, atol=1e-5)
    with pytest.raises(InputError, match="shape"):
        shadowflow.fit(np.zeros((4, 4, 4, 4)), model=procedural_model)
    with pytest.raises(InputError, match="no contrast"):
        shadowflow.fit(np.full((200, 200), 0.5), model=procedural_model)
