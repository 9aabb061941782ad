"""What a run writes of the shadows a face does not cast (``--foreign-shadows``): ``foreign_shadow.png`` beside the
face's other files, their count and share of the face in ``summary.json``, a line on the report's card, their map in
the recording (``shadow/foreign``); and, without the option, none of these (a run's files as they were)."""
import json

import cv2
import numpy as np
import shadowflow
from conftest import brimmed_face
from shadowflow.flow.recording.reader import read_mcap
from shadowflow.nodes.method.options import MethodOptions


def test_a_run_with_foreign_shadows_writes_their_map_count_and_line(tmp_path, procedural_model):
    photo, blocked = brimmed_face(tmp_path)
    run = shadowflow.run([photo], tmp_path / "out", model=procedural_model,
                         options=MethodOptions(foreign_shadows=True), record=("mcap",))
    record = run.records[0]
    face = record["faces"][0]
    assert face["foreign_shadows"]["count"] >= 1 and face["foreign_shadows"]["area"] > 0.2, face
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary[0]["faces"][0]["foreign_shadows"] == face["foreign_shadows"]
    found = cv2.imread(str(tmp_path / "out" / "face" / "foreign_shadow.png"), cv2.IMREAD_UNCHANGED)
    mask = cv2.imread(str(tmp_path / "out" / "face" / "mask.png"), cv2.IMREAD_UNCHANGED) > 0
    assert found.shape == mask.shape and found.dtype == np.uint8
    assert np.all(found[~mask] == 0)
    assert np.mean(found[mask & (blocked < 0.01)] > 25) < 0.05  # the lit face is in none
    assert np.mean(found[mask & (blocked > 0.99)] > 128) > 0.5  # the brim's core mostly in
    page = (tmp_path / "out" / "report.html").read_text()
    assert f"shadows from elsewhere: {face['foreign_shadows']['count']}, over" in page
    # the recording has their map on the model grid, the face's share in them as the summary gives it, the brim's
    # shadow over the brow and eyes (the grid's upper half), none over the mouth and chin
    recorded = read_mcap(tmp_path / "out" / "run.mcap").finished_frames()[0].arrays
    grid, fit_face = recorded["shadow/foreign"][None], np.isfinite(recorded["albedo/albedo"][None])
    on_face = np.isfinite(grid)
    assert grid.dtype == np.float32 and np.nanmax(grid) <= 1.0
    assert np.mean(on_face & fit_face) / np.mean(on_face | fit_face) > 0.95  # the fit's face
    assert abs(np.mean(grid[on_face] > 0.5) - face["foreign_shadows"]["area"]) < 0.05
    lower = on_face & (np.arange(grid.shape[0])[:, None] > 0.65 * grid.shape[0])
    assert np.mean(grid[lower] > 0.5) < 0.05


def test_a_run_without_it_writes_none_of_them(tmp_path, procedural_model):
    photo, _ = brimmed_face(tmp_path)
    run = shadowflow.run([photo], tmp_path / "out", model=procedural_model, record=("mcap",))
    face = run.records[0]["faces"][0]
    assert "foreign_shadows" not in face
    # what the honesty step measured of the relit face is written either way (``relight.nodes.harm_flag``)
    assert {"added_edges", "colour_blotches"} <= set(face["harm"]) and 0.0 <= face["harm"]["added_edges"] < 100.0
    assert not (tmp_path / "out" / "face" / "foreign_shadow.png").exists()
    assert "shadows from elsewhere" not in (tmp_path / "out" / "report.html").read_text()
    recorded = read_mcap(tmp_path / "out" / "run.mcap").finished_frames()[0].arrays
    assert "shadow/cast" in recorded and "shadow/foreign" not in recorded
