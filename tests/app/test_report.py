"""``OUT/report.html``: every frame in the contact sheet, failures with their reasons, the
convergence plot; hostile names escaped; and a real browser renders it (skipped without one)."""
import re
import shutil
import subprocess
from urllib.parse import quote, unquote

import cv2
import numpy as np
import pytest
from shadowflow.nodes.app.cli import main


@pytest.fixture(scope="module")
def run_with_a_failure(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("report")
    bad = tmp / "a<b>&c.png"
    bad.write_bytes(b"not an image at all")
    out = tmp / "out"
    assert main(["run", "--demo", str(bad), "--out", str(out), "--quiet", "--record", "mcap"]) == 1
    return out


def test_the_report_shows_every_frame_and_says_why_one_failed(run_with_a_failure):
    out = run_with_a_failure
    page = (out / "report.html").read_text()
    stems = sorted(p.name for p in out.iterdir() if p.is_dir() and p.name != "demo-inputs")
    assert len(stems) == 3
    for stem in stems:  # a row per frame, its pictures linked where they are
        for name in ("relit.png", "shadow.png", "novel_view.png", "albedo.png"):
            assert f'src="{quote(stem)}/{name}"' in page and (out / stem / name).is_file()
    assert page.count('alt="input" src="data:image/jpeg;base64,') == 3
    assert page.count('alt="weights" src="data:image/jpeg;base64,') == 3
    assert "4 photos (3 ok, 0 doubtful, 1 failed); 3 faces (3 ok, 0 doubtful, 0 refused)" in page
    assert "a&lt;b&gt;&amp;c.png" in page and "<b>&c" not in page  # the file name is text, never markup
    assert "not a recognised image" in page
    assert 'alt="convergence of the fit" src="data:image/png;base64,' in page
    for src in re.findall(r'src="([^"]+)"', page):  # every relative link resolves inside --out
        if not src.startswith("data:"):
            path = out / unquote(src)  # a URL: "+" in a name is %2B there
            assert path.resolve().is_relative_to(out.resolve()) and path.is_file()


def test_without_a_recording_the_report_says_there_is_nothing_to_plot(tmp_path):
    assert main(["run", "--demo", "--out", str(tmp_path / "o"), "--quiet", "--record", "none"]) == 0
    page = (tmp_path / "o" / "report.html").read_text()
    assert "No recording to plot" in page and page.count("<tr>") >= 3


BROWSER = next((b for b in ("chromium", "chromium-browser", "google-chrome") if shutil.which(b)), None)


@pytest.mark.skipif(BROWSER is None, reason="no headless browser (apt-get install chromium)")
def test_a_real_browser_renders_the_report(run_with_a_failure, tmp_path):
    shot = tmp_path / "report.png"
    subprocess.run([BROWSER, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                    f"--screenshot={shot}", "--window-size=1300,1100", (run_with_a_failure / "report.html").as_uri()],
                   capture_output=True, timeout=120)
    img = cv2.imread(str(shot))
    assert img is not None and img.shape[:2] == (1100, 1300)
    grey = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    assert np.mean(grey < 200) > 0.10  # the plot and the pictures drawn, not a blank or broken page


@pytest.mark.skipif(BROWSER is None, reason="no headless browser (apt-get install chromium)")
def test_the_report_fits_a_laptops_window_and_its_sheet_scrolls_in_its_own_box(run_with_a_failure, tmp_path):
    """At 1000 px the page is no wider than its window (the contact sheet, 1,086 px wide with its margin, scrolls in its own box;
    it gave the whole page a horizontal scrollbar)."""
    probe = tmp_path / "probe.html"
    probe.write_text((run_with_a_failure / "report.html").read_text().replace(
        "</body>", '<script>document.body.dataset.width = document.documentElement.scrollWidth</script></body>'))
    dom = subprocess.run([BROWSER, "--headless", "--no-sandbox", "--disable-gpu", "--window-size=1000,800",
                          "--dump-dom", probe.as_uri()], capture_output=True, text=True, timeout=120).stdout
    width = re.search(r'data-width="(\d+)"', dom)
    assert width is not None and 0 < int(width.group(1)) <= 1000, width


def test_the_run_makes_its_cards_pictures_as_the_report_would_read_them_back(tmp_path, monkeypatch):
    """A colour photo's card: the run makes its before/after pictures while it holds the photo and its relit
    file, so the report reads neither back, and they are the pictures the report makes from the files."""
    import json

    from shadowflow.nodes.app import report
    from shadowflow.nodes.evaluation.scenes import write_shadowed_face
    from shadowflow.nodes.geometry.reflectance import light_from_angles

    # a face the product relights cleanly (an ok face, exit 0): tinted where drawn, its shadows too; lit from 40
    # degrees with its shadows taking the orange backdrop's colour, its rim glowed orange, and it came back as it was
    face = cv2.imread(str(write_shadowed_face(tmp_path / "f.png", np.random.default_rng(4), light_from_angles(20))))
    photo = np.full((300, 360, 3), (40, 90, 150), np.uint8)  # BGR
    drawn = face.max(axis=-1) > 0
    photo[100:228, 150:278][drawn] = face[drawn] * np.array([0.7, 0.85, 1.0])
    cv2.imwrite(str(tmp_path / "portrait.png"), photo)
    side = json.loads((tmp_path / "f.json").read_text())
    eyes = (np.array(side["eyes"]) + [150, 100]).tolist()
    (tmp_path / "portrait.json").write_text(json.dumps({"light": side["light"], "eyes": eyes}))
    out = tmp_path / "out"

    def no_reading(*args, **kwargs):
        raise AssertionError("the report read a photo back")

    with monkeypatch.context() as m:
        m.setattr(report, "_shown", no_reading)
        assert main(["run", str(tmp_path / "portrait.png"), "--out", str(out), "--quiet", "--record", "none"]) == 0
    page = (out / "report.html").read_text()
    made = re.findall(r'alt="(relit|photo|input)" src="data:image/jpeg;base64,([^"]+)"', page)
    (out / "report.html").unlink()
    report.write_report(out, json.loads((out / "summary.json").read_text()))  # from the files alone
    read_back = re.findall(r'alt="(relit|photo|input)" src="data:image/jpeg;base64,([^"]+)"',
                           (out / "report.html").read_text())
    assert [name for name, _ in made] == ["relit", "photo", "input"] and made == read_back


def test_the_reports_count_of_doubtful_photos_agrees_with_their_rows(tmp_path):
    """A photo whose largest face is ok but another face doubtful (a small face in a group photo) is counted
    doubtful in the report's first line, as its row says, not ok (a group photo read "0 doubtful" above a row
    marked doubtful)."""
    from shadowflow.nodes.app.report import write_report

    records = []
    for stem, faces in (("group", [{"status": "ok"}, {"status": "doubtful: the face is small"}]),
                        ("portrait", [{"status": "ok"}])):
        (tmp_path / stem).mkdir()
        img = np.full((40, 40, 3), 128, np.uint8)
        cv2.imwrite(str(tmp_path / stem / "relit.png"), img)
        cv2.imwrite(str(tmp_path / f"{stem}.png"), img)
        records.append({"stem": stem, "source": str(tmp_path / f"{stem}.png"), "status": "ok", "faces": faces})
    page = write_report(tmp_path, records).read_text()
    assert "2 photos (1 ok, 1 doubtful, 0 failed); 3 faces (2 ok, 1 doubtful, 0 refused)" in page
    assert page.count("<span class=doubtful>doubtful</span>") == 1


def test_the_terminal_and_the_report_count_the_same_faces_the_same_way(tmp_path):
    """A run's photos and faces are counted once (``counts.tally``) and said alike: the terminal said "17 of 23
    done" (photos whose largest face was ok) where the report said 14 ok and 8 doubtful (any face not ok). A
    refused face (turned too far) makes its photo doubtful; a candidate the fit found no face in beside a real
    face is no face at all; a photo with no face failed."""
    from shadowflow.nodes.app.counts import status_lines, tally, tally_text
    from shadowflow.nodes.app.report import write_report

    refused = "group.png (face 3): the head is turned -62 deg (yaw); faces turned up to 50 deg are fitted"
    specs = {"group": [{"status": "ok"}, {"status": "doubtful: the face is small"}, {"status": refused},
                       {"status": "group.png (face 4): no face found (a pattern)"}],
             "portrait": [{"status": "portrait.png: no face found (rings)"}, {"status": "ok"}],
             "wall": None}
    records = []
    for stem, faces in specs.items():
        img = np.full((40, 40, 3), 128, np.uint8)
        cv2.imwrite(str(tmp_path / f"{stem}.png"), img)
        if faces is None:
            records.append({"stem": stem, "source": str(tmp_path / f"{stem}.png"), "status": "no face found",
                            "failed_in": "faces", "faces": []})
            continue
        (tmp_path / stem).mkdir()
        cv2.imwrite(str(tmp_path / stem / "relit.png"), img)
        records.append({"stem": stem, "source": str(tmp_path / f"{stem}.png"), "status": "ok", "faces": faces})
    t = tally(records)
    assert tally_text(t) == "3 photos (1 ok, 1 doubtful, 1 failed); 4 faces (2 ok, 1 doubtful, 1 refused)"
    assert tally_text(t) in write_report(tmp_path, records).read_text()
    lines = [line for r in records for line in status_lines(r)]  # what the terminal names, one line each
    assert len(lines) == t["faces doubtful"] + t["refused"] + t["failed"] == 3


def test_a_faces_line_says_how_far_it_is_turned_and_tilted_and_which_view_fitted_it():
    """A face looking down and to the side: its card names both angles and the turned model it was fitted with
    (a tilt alone, fitted with a pitched view, was invisible: the line gave the yaw only); a frontal face's line
    names no view."""
    from shadowflow.nodes.app.report import _face_line

    tilted = _face_line(1, {"status": "ok", "found": "detected", "pose": {"yaw": 15.8, "pitch": -27.9, "roll": -3.1},
                            "model_view": {"yaw": 20.0, "pitch": -20.0}})
    assert "turned +16°, tilted -28°; fitted with heads at +20°, -20°" in tilted
    frontal = _face_line(2, {"status": "ok", "found": "detected", "pose": {"yaw": -1.6, "pitch": -13.4, "roll": 0.0}})
    assert "turned -2°, tilted -13°)" in frontal and "fitted with" not in frontal
    assert "turned" not in _face_line(3, {"status": "ok", "found": "given"})  # eyes given: no pose


def test_a_clip_is_counted_as_a_clip_of_frames_not_as_a_photo_without_faces(tmp_path):
    """A clip's record has no faces of its own (its frames have them, ``frames.jsonl``): the run said "1 photos
    (1 ok ...); 0 faces" of a relit clip. It is counted as a clip, its frames by their faces' status, and a run of
    clips only names no photos; the exit code's inputs count the clip once."""
    from shadowflow.nodes.app.counts import tally, tally_text

    clip = {"stem": "talk", "source": "talk.mp4", "status": "ok", "faces": [],
            "clip": {"frames": 30, "frame_status": {"ok": 27, "doubtful: the face is small": 2, "no face found": 1}}}
    lost = {"stem": "wall", "source": "wall.mp4", "status": "wall.mp4: no face in any of its 4 frames", "faces": [],
            "clip": {"frames": 4, "frame_status": {"no face found": 4}}}
    t = tally([clip, lost])
    assert tally_text(t) == ("2 clips (1 ok, 1 failed) of 34 frames (27 with a face ok, 2 doubtful, 5 without)")
    assert (t["inputs"], t["inputs ok"]) == (2, 1)
    still = {"stem": "still", "source": "still.png", "status": "ok", "faces": [{"status": "ok"}]}
    t = tally([clip, still])
    assert tally_text(t) == ("1 photo (1 ok, 0 doubtful, 0 failed); 1 face (1 ok, 0 doubtful, 0 refused); "
                             "1 clip (1 ok, 0 failed) of 30 frames (27 with a face ok, 2 doubtful, 1 without)")
    assert (t["inputs"], t["inputs ok"]) == (2, 2)
