"""Clips in a run (issue 61, first slice): a clip decoded frame by frame through the photo's chain, relit clips of
the input's size, frame rate and frame count (audio kept), frames.jsonl, a clip beside a still, a clip that cannot
be read, --resume, and the light carried and smoothed over a clip's frames. Tiny clips of rendered faces, made here."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

av = pytest.importorskip("av")

from shadowflow.nodes.app.clip_io import ClipReader, is_clip  # noqa: E402
from shadowflow.nodes.app.steady import CONFIRM, LightSmoother, angle_deg  # noqa: E402
from shadowflow.nodes.evaluation.scenes import draw_face, render_scene, write_shadowed_face  # noqa: E402
from shadowflow.nodes.geometry.reflectance import light_from_angles  # noqa: E402

SIZE, RATE = 128, 10
FAST = ["--max-iterations", "8", "--record", "none", "--quiet"]


def make_clip(path: Path, lights, audio: bool = False, noise: float = 0.0, seed: int = 7) -> Path:
    """A clip of one rendered ICT face, one frame per light, H.264 at RATE fps; with ``audio`` a tone in AAC."""
    depth, mask, albedo = draw_face(np.random.default_rng(seed), (SIZE, SIZE), "ict")
    rng = np.random.default_rng(seed + 1)
    out = av.open(str(path), "w")
    video = out.add_stream("libx264", rate=RATE)
    video.width = video.height = SIZE
    video.pix_fmt, video.options = "yuv420p", {"crf": "10"}
    sound = out.add_stream("aac", rate=16000) if audio else None
    for i, light in enumerate(lights):
        image = render_scene(depth, albedo, np.asarray(light), mask).image + rng.normal(0, noise, (SIZE, SIZE))
        grey = (np.clip(image, 0, 1) * 255 + 0.5).astype(np.uint8)
        frame = av.VideoFrame.from_ndarray(np.repeat(grey[..., None], 3, axis=2), format="rgb24")
        frame.pts = i
        out.mux(video.encode(frame))
    out.mux(video.encode(None))
    if sound is not None:
        n = 16000 * len(lights) // RATE
        for t in range(0, n, 1024):
            samples = (np.sin(np.arange(t, min(t + 1024, n)) / 7.0) * 8000).astype(np.int16)[None]
            chunk = av.AudioFrame.from_ndarray(samples, format="s16", layout="mono")
            chunk.sample_rate, chunk.pts = 16000, t
            out.mux(sound.encode(chunk))
        out.mux(sound.encode(None))
    out.close()
    return path


def run(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p)}
    return subprocess.run([sys.executable, "-m", "shadowflow.nodes.app.cli", "run", *args], capture_output=True,
                          text=True, env=env, timeout=600)


def lines(folder: Path) -> list[dict]:
    return [json.loads(line) for line in (folder / "frames.jsonl").read_text().splitlines()]


def jumps(vectors) -> np.ndarray:
    """The angle (degrees) between each frame's light and the next's."""
    return np.array([angle_deg(np.array(a), np.array(b)) for a, b in zip(vectors, vectors[1:])])


SWITCHED = [light_from_angles(30, 0)] * 5 + [light_from_angles(-30, 0)] * 5


@pytest.fixture(scope="module")
def clip_run(tmp_path_factory):
    """One run of a switched-light clip with audio beside a still, a clip that cannot be read, --relight."""
    root = tmp_path_factory.mktemp("clips")
    src = root / "in"
    src.mkdir()
    make_clip(src / "talk.mp4", SWITCHED, audio=True)
    write_shadowed_face(src / "still.png", np.random.default_rng(3), light_from_angles(30, 0), source="ict")
    (src / "broken.mov").write_bytes(b"\x00\x00\x00\x18ftypmp42" + os.urandom(2000))
    out = root / "out"
    done = run(str(src), "--out", str(out), "--relight=-60,10", *FAST)
    return src, out, done


@pytest.mark.slow  # (whole CLI runs)
def test_relit_clips_keep_size_rate_count_and_audio(clip_run):
    src, out, _ = clip_run
    source = ClipReader(src / "talk.mp4")
    for name in ("relit.mp4", "relit_A-060E+10.mp4"):
        relit = ClipReader(out / "talk" / name)
        assert (relit.info.width, relit.info.height) == (source.info.width, source.info.height)
        assert float(relit.info.rate) == pytest.approx(float(source.info.rate))
        frames = list(relit)
        assert len(frames) == len(SWITCHED)
        assert relit.info.audio  # the input's AAC remuxed
        relit.close()
    source.close()
    with av.open(str(out / "talk" / "relit.mp4")) as relit, av.open(str(src / "talk.mp4")) as given:
        assert relit.streams.audio[0].codec_context.name == "aac"
        assert relit.streams.audio[0].frames == given.streams.audio[0].frames


@pytest.mark.slow  # (whole CLI runs)
def test_relit_clip_differs_from_the_input(clip_run):
    """The relit frames are the relighting's, not the input's copied through."""
    src, out, _ = clip_run
    given = [f.rgb.astype(float) for f in ClipReader(src / "talk.mp4")]
    relit = [f.rgb.astype(float) for f in ClipReader(out / "talk" / "relit.mp4")]
    assert np.mean([np.abs(a - b).mean() for a, b in zip(given, relit)]) > 3.0


@pytest.mark.slow  # (whole CLI runs)
def test_frames_jsonl_has_a_line_per_frame(clip_run):
    _, out, _ = clip_run
    got = lines(out / "talk")
    assert [line["index"] for line in got] == list(range(len(SWITCHED)))
    assert [line["time"] for line in got] == pytest.approx([i / RATE for i in range(len(SWITCHED))])
    for line in got:
        assert line["status"] == "ok"
        (face,) = line["faces"]
        assert {"box", "eyes", "pose", "status", "light"} <= set(face)
        assert len(face["box"]) == 4 and len(face["eyes"]) == 2 and len(face["light"]) == 3
    assert not (out / "talk" / "frames").exists()  # (only with --frames)


@pytest.mark.slow  # (whole CLI runs)
def test_clip_beside_a_still_and_a_broken_clip(clip_run):
    _, out, done = clip_run
    records = {r["stem"]: r for r in json.loads((out / "summary.json").read_text())}
    assert set(records) == {"talk", "still", "broken"}
    assert records["still"]["status"] == "ok" and (out / "still" / "relit.png").is_file()
    clip = records["talk"]
    assert clip["status"] == "ok" and clip["clip"]["frames"] == len(SWITCHED)
    assert clip["clip"]["faces_per_frame"] == {"1": len(SWITCHED)} and clip["clip"]["audio"] is True
    assert records["broken"]["status"].startswith(f"{Path(records['broken']['source'])}: cannot read as a clip")
    errors = [line for line in done.stderr.splitlines() if "broken.mov" in line]
    assert len(errors) == 1 and errors[0].startswith("error: ") and "cannot read as a clip" in errors[0]
    assert (out / "report.html").is_file()


@pytest.mark.slow  # (whole CLI runs)
def test_a_switched_light_is_followed_within_a_few_frames(clip_run):
    _, out, _ = clip_run
    got = lines(out / "talk")
    light = [line["faces"][0]["light"] for line in got]
    raw = [line["faces"][0]["light_raw"] for line in got]
    assert angle_deg(np.array(raw[0]), np.array(raw[-1])) > 40  # the estimates see the switch
    for k in range(5 + CONFIRM - 1, len(got)):  # CONFIRM frames after the switch, the light is the new one
        assert angle_deg(np.array(light[k]), np.array(raw[k])) < 5


@pytest.mark.slow  # (whole CLI runs)
def test_resume_skips_a_finished_clip(clip_run):
    src, out, _ = clip_run
    before = (out / "talk" / "relit.mp4").stat().st_mtime_ns
    again = run(str(src), "--out", str(out), "--relight=-60,10", "--resume", *FAST)
    assert (out / "talk" / "relit.mp4").stat().st_mtime_ns == before
    assert len(lines(out / "talk")) == len(SWITCHED)
    records = {r["stem"]: r for r in json.loads((out / "summary.json").read_text())}
    assert records["talk"]["clip"]["frames"] == len(SWITCHED), again.stderr


@pytest.mark.slow  # (whole CLI runs)
def test_resume_redoes_an_unfinished_clip(tmp_path):
    """A clip whose files are not all there is redone whole."""
    clip = make_clip(tmp_path / "c.mp4", SWITCHED[:4])
    out = tmp_path / "out"
    assert run(str(clip), "--out", str(out), *FAST).returncode == 0
    (out / "c" / "frames.jsonl").unlink()
    assert run(str(clip), "--out", str(out), "--resume", *FAST).returncode == 0
    assert len(lines(out / "c")) == 4
    assert sum(1 for _ in ClipReader(out / "c" / "relit.mp4")) == 4


@pytest.mark.slow  # (whole CLI runs)
def test_smoothing_steadies_a_noisy_light_and_follows_a_switch(tmp_path):
    """The light jittering by a few degrees from frame to frame (as an estimate on a real clip does) comes out
    steadier; switched, it is followed, and CONFIRM frames after the switch steadied again about the new light."""
    rng = np.random.default_rng(11)
    jitter = [light_from_angles(a + rng.normal(0, 4), rng.normal(0, 4)) for a in [30] * 8 + [-35] * 8]
    clip = make_clip(tmp_path / "noisy.mp4", jitter, noise=0.01)
    out = tmp_path / "out"
    done = run(str(clip), "--out", str(out), *FAST)
    assert done.returncode == 0, done.stderr
    got = lines(out / "noisy")
    assert all(line["status"] == "ok" for line in got)
    light = [line["faces"][0]["light"] for line in got]
    raw = [line["faces"][0]["light_raw"] for line in got]
    before, after = slice(0, 8), slice(8 + CONFIRM, 16)
    for part in (before, after):
        steady, given = jumps(light[part]).mean(), jumps(raw[part]).mean()
        print(f"frames {part.start}-{part.stop - 1}: mean frame-to-frame jump {given:.2f} deg estimated, "
              f"{steady:.2f} smoothed")
        assert steady < 0.6 * given
    assert np.mean([angle_deg(np.array(a), np.array(b)) for a, b in zip(light[after], raw[after])]) < 8
    assert angle_deg(np.array(light[7]), np.array(light[8 + CONFIRM])) > 40  # (the switch itself)


def test_light_smoother_holds_an_outlier_and_follows_a_change():
    """A departing estimate is the frame's own ("departed"; one that agrees with the departure before it "alone": its
    relit face is its own too, the running one carried past it), a lone one is not followed, CONFIRM in a row are
    ("confirmed"), a change the photo shows is taken at once ("changed"), and an estimate near the running light is
    averaged in ("carried")."""
    s = LightSmoother()
    a, b = light_from_angles(30, 0), light_from_angles(-30, 0)
    s.update(a)
    assert s.state == "changed"  # the first: nothing before it
    for _ in range(4):
        s.update(a)
    assert s.state == "carried"
    assert angle_deg(s.update(b), b) < 1e-3 and s.state == "departed"  # a departing frame: fitted under its own
    assert angle_deg(s.update(a), a) < 1e-3 and angle_deg(s.light, a) < 1e-3  # a lone outlier: not followed
    assert s.state == "carried"
    states = []
    for _ in range(CONFIRM):
        s.update(b)
        states.append(s.state)
    assert angle_deg(s.light, b) < 1e-3  # CONFIRM frames in a row: a real change, followed
    assert states == ["departed"] + ["alone"] * (CONFIRM - 2) + ["confirmed"]
    s.update(light_from_angles(-20, 0), shown=True)
    assert s.state == "changed"
    # departures that do not agree with each other (a webcam face's estimates, 5-13 degrees apart): each the frame's
    # own light, none relit alone, the running light their mean
    states = []
    for azimuth in (20, 28, 12):
        s.update(light_from_angles(azimuth, 0))
        states.append(s.state)
    assert states == ["departed", "departed", "confirmed"]
    assert angle_deg(s.light, light_from_angles(20, 0)) < 1.0


def test_a_change_of_light_the_photo_shows_is_taken_at_once():
    """A light moved by 12 degrees (under ``JUMP_DEG``: an estimate so near is averaged in) is followed at once when
    the photo shows that the light moved (``temporal.light_shown_changed``): a rendered face lit from +30 then -30
    degrees; not when the same face comes again, a little noisier or a fifth darker all over (an exposure)."""
    from shadowflow.nodes.model.canonical import canonical_eyes
    from shadowflow.nodes.relight.temporal import light_shown_changed, photo_on_grid

    a, b = light_from_angles(30, 0), light_from_angles(18, 0)
    averaged, shown = LightSmoother(), LightSmoother()
    for _ in range(5):
        averaged.update(a)
        shown.update(a)
    assert angle_deg(averaged.update(b), b) > 6.0
    assert angle_deg(shown.update(b, shown=True), b) < 1e-3

    depth, mask, albedo = draw_face(np.random.default_rng(3), (SIZE, SIZE), "ict")
    eyes = canonical_eyes((SIZE, SIZE))
    rng = np.random.default_rng(4)

    def grid(light, gain=1.0, noise=0.0):
        image = gain * render_scene(depth, albedo, light, mask).image + rng.normal(0, noise, (SIZE, SIZE))
        return photo_on_grid(np.clip(image, 0.0, 1.0).astype(np.float32), eyes)

    left = grid(light_from_angles(30, 0))
    assert light_shown_changed(left, grid(light_from_angles(-30, 0)))
    assert not light_shown_changed(left, grid(light_from_angles(30, 0), noise=0.01))
    assert not light_shown_changed(left, grid(light_from_angles(30, 0), gain=0.8))


def test_what_is_a_clip(tmp_path):
    assert is_clip(tmp_path / "a.MP4") and is_clip(tmp_path / "a.webm") and not is_clip(tmp_path / "a.png")
    from PIL import Image

    still, moving = tmp_path / "still.gif", tmp_path / "moving.gif"
    Image.new("L", (40, 40)).save(still)
    frames = [Image.new("L", (40, 40), v) for v in (0, 128, 255)]
    frames[0].save(moving, save_all=True, append_images=frames[1:], duration=100)
    assert is_clip(moving) and not is_clip(still)


@pytest.mark.slow  # (whole CLI runs)
def test_an_animated_gif_with_frames(tmp_path):
    """An animated GIF is a clip; --frames writes each frame's own files too."""
    from PIL import Image

    depth, mask, albedo = draw_face(np.random.default_rng(7), (SIZE, SIZE), "ict")
    images = [Image.fromarray((np.clip(render_scene(depth, albedo, light, mask).image, 0, 1) * 255).astype(np.uint8))
              for light in (light_from_angles(a, 0) for a in (30, 0, -30))]  # (a GIF merges equal frames)
    gif = tmp_path / "wave.gif"
    images[0].save(gif, save_all=True, append_images=images[1:], duration=100, loop=0)
    out = tmp_path / "out"
    done = run(str(gif), "--out", str(out), "--frames", *FAST)
    assert done.returncode == 0, done.stderr
    relit = ClipReader(out / "wave" / "relit.mp4")
    assert (relit.info.width, relit.info.height) == (SIZE, SIZE) and sum(1 for _ in relit) == 3
    assert len(lines(out / "wave")) == 3
    for k in range(3):
        assert (out / "wave" / "frames" / f"{k:06d}" / "relit.png").is_file()


@pytest.mark.slow  # (whole CLI runs)
def test_an_unreadable_frame_is_one_line_and_the_clip_goes_on(tmp_path):
    """A clip whose third frame's data is damaged: that frame fails with one line, the others are relit, and the
    relit clip keeps every frame (the damaged one as the last frame written)."""
    depth, mask, albedo = draw_face(np.random.default_rng(7), (SIZE, SIZE), "ict")
    path = tmp_path / "damaged.avi"
    with av.open(str(path), "w") as out:
        video = out.add_stream("mjpeg", rate=RATE)
        video.width = video.height = SIZE
        video.pix_fmt = "yuvj420p"
        for i, light in enumerate(SWITCHED[:5]):
            grey = (np.clip(render_scene(depth, albedo, light, mask).image, 0, 1) * 255 + 0.5).astype(np.uint8)
            frame = av.VideoFrame.from_ndarray(np.repeat(grey[..., None], 3, axis=2), format="rgb24")
            frame.pts = i
            for packet in video.encode(frame):
                if i == 2:  # a JPEG's start and nothing that decodes
                    bad = av.Packet(b"\xff\xd8" + bytes(300))
                    bad.pts, bad.dts, bad.time_base, bad.stream = packet.pts, packet.dts, packet.time_base, video
                    packet = bad
                out.mux(packet)
        out.mux(video.encode(None))
    done = run(str(path), "--out", str(tmp_path / "out"), *FAST[:-1])  # (not --quiet: the notes are said)
    got = lines(tmp_path / "out" / "damaged")
    assert [line["index"] for line in got] == list(range(5))
    assert [line["status"] == "ok" for line in got] == [True, True, False, True, True]
    assert "unreadable frame" in got[2]["status"]
    said = [line for line in done.stderr.splitlines() if "unreadable frame" in line]
    assert len(said) == 1 and said[0].startswith("error: ") and "frame 2" in said[0]
    assert sum(1 for _ in ClipReader(tmp_path / "out" / "damaged" / "relit.mp4")) == 5


def _plain_clip(path: Path, size: tuple[int, int], audio: str | None, codec: str = "libx264",
                pix_fmt: str = "yuv420p") -> Path:
    """A short clip of flat frames (no face: for the clip's reading and writing alone), with ``audio`` in that codec."""
    w, h = size
    with av.open(str(path), "w") as out:
        video = out.add_stream(codec, rate=RATE)
        video.width, video.height, video.pix_fmt = w, h, pix_fmt
        sound = out.add_stream(audio, rate=16000) if audio else None
        for i in range(4):
            frame = av.VideoFrame.from_ndarray(np.full((h, w, 3), 50 * i, np.uint8), format="rgb24")
            frame.pts = i
            out.mux(video.encode(frame))
        out.mux(video.encode(None))
        if sound is not None:
            for t in range(0, 6400, 1024):
                chunk = av.AudioFrame.from_ndarray(np.zeros((1, min(1024, 6400 - t)), np.int16), format="s16",
                                                   layout="mono")
                chunk.sample_rate, chunk.pts = 16000, t
                out.mux(sound.encode(chunk))
            out.mux(sound.encode(None))
    return path


def _copied(src: Path, dst: Path) -> Path:
    from shadowflow.nodes.app.clip_io import ClipEncoder

    reader = ClipReader(src)
    encoder = ClipEncoder(dst, reader.info, str(src))
    for frame in reader:
        encoder.write(frame.rgb, frame.pts, frame.time)
    encoder.finish()
    reader.close()
    return dst


def test_audio_mp4_cannot_hold_is_made_aac(tmp_path):
    """PCM audio (a .mkv's, a .mov's) cannot go into MP4 as it is: it is encoded as AAC, the video as ever."""
    out = _copied(_plain_clip(tmp_path / "pcm.mkv", (64, 48), "pcm_s16le"), tmp_path / "relit.mp4")
    with av.open(str(out)) as got:
        assert got.streams.audio[0].codec_context.name == "aac"
        assert sum(1 for _ in got.decode(video=0)) == 4
        assert abs(float(got.streams.audio[0].duration * got.streams.audio[0].time_base) - 0.4) < 0.1


def test_odd_sided_clip_keeps_its_size(tmp_path):
    """4:2:0 needs even sides: an odd-sided clip (an MJPEG's, a GIF's) is written 4:4:4 at its own size."""
    out = _copied(_plain_clip(tmp_path / "odd.avi", (65, 47), None, "mjpeg", "yuvj444p"), tmp_path / "relit.mp4")
    relit = ClipReader(out)
    assert (relit.info.width, relit.info.height) == (65, 47) and sum(1 for _ in relit) == 4


@pytest.mark.slow  # (whole CLI runs)
def test_eval_clips_measures_a_relit_clip_against_its_input(tmp_path):
    """``eval clips --out`` runs a clip into a folder it keeps and measures its relit clip against it: one light
    each side of a switch, every frame with its face; asked again, the finished run is measured, not redone."""
    clip = make_clip(tmp_path / "talk.mp4", SWITCHED)
    out, report = tmp_path / "out", tmp_path / "clips.json"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p)}
    command = [sys.executable, "-m", "shadowflow.nodes.app.cli", "eval", "clips", "--data", str(clip), "--out",
               str(out), "--json", str(report)]
    done = subprocess.run(command, capture_output=True, text=True, env=env, timeout=600)
    assert done.returncode == 0, done.stderr
    assert "talk.mp4" in done.stdout and "flicker" in done.stdout
    (row,) = json.loads(report.read_text())["rows"]
    assert row["frames"] == len(SWITCHED) and row["with_face"] == len(SWITCHED) and row["pairs"] == len(SWITCHED) - 1
    assert 0.0 <= row["flicker"] < 10.0 and row["h_median"] is not None
    written = (out / "talk" / "relit.mp4").stat().st_mtime_ns
    again = subprocess.run(command, capture_output=True, text=True, env=env, timeout=600)
    assert again.returncode == 0, again.stderr
    assert (out / "talk" / "relit.mp4").stat().st_mtime_ns == written
    assert json.loads(report.read_text())["rows"][0]["flicker"] == pytest.approx(row["flicker"])


@pytest.mark.slow  # (whole CLI runs)
def test_a_clip_face_reads_its_view_with_the_fit_on_its_first_frame_and_carries_it(clip_run):
    """A near-frontal face under a side light reads its yaw with the fit (a fit of each candidate view) on its track's
    first frame, and carries the fit's share of the yaw to the frames after, fitted frontally without the trials,
    until its light moves."""
    _, out, _ = clip_run
    reads = [line["faces"][0].get("yaw_read") or {} for line in lines(out / "talk")]
    assert "fit" in reads[0]
    share = (reads[0]["fit"] - reads[0]["landmarks"]) / 2
    assert all(r.get("carried") == pytest.approx(share, abs=0.05) for r in reads[1:5])
    # the light switched sides (frame 5): the landmarks lean the other way, so the view is read again, afresh
    assert "fit" in reads[5]
    assert all(r.get("carried") == pytest.approx((reads[5]["fit"] - reads[5]["landmarks"]) / 2, abs=0.05)
               for r in reads[6:])


def test_a_clip_whose_first_frames_come_unevenly_is_written_whole(tmp_path):
    """A phone's clip (variable frame rate) whose first two frames come close together (read back, at one time): with
    the encoder's B-frames its packets' decode times ran backwards and the relit clip could not be written."""
    from fractions import Fraction

    src = tmp_path / "phone.mp4"
    with av.open(str(src), "w") as out:
        video = out.add_stream("libx264", rate=25)
        video.width = video.height = 64
        video.pix_fmt, video.time_base = "yuv420p", Fraction(1, 25000)
        video.options = {"bf": "0"}  # (as the phone wrote it: with B-frames this very writer fails the same way)
        for i, pts in enumerate([0, 275] + [1275 + 1000 * k for k in range(22)]):
            image = np.full((64, 64, 3), (7 * i) % 255, np.uint8)
            image[:, : 2 + 2 * i] = 255  # a moving edge: frames the encoder does not skip
            frame = av.VideoFrame.from_ndarray(image, format="rgb24")
            frame.pts, frame.time_base = pts, Fraction(1, 25000)
            out.mux(video.encode(frame))
        out.mux(video.encode(None))
    with av.open(str(src)) as raw:
        stamps = [f.time for f in raw.decode(video=0)]
    assert stamps[0] == stamps[1]  # (two frames at one time, as that phone's clip read back)
    given = [f.time for f in ClipReader(src)]
    assert given == sorted(set(given))  # (read one after the other: the second a frame period after the first)
    got = [f.time for f in ClipReader(_copied(src, tmp_path / "copy.mp4"))]
    assert len(got) == len(given) == 24 and got == sorted(got) and got[-1] == pytest.approx(given[-1], abs=0.05)


def test_a_clip_whose_frames_all_say_time_zero_is_read_at_its_rate_and_written_whole(tmp_path):
    """A clip whose every frame says time 0 (as a tool that sets no frame times writes it; its average rate read off
    them as 8 times the codec's, a 40-frame cut's as 1000 a second): its frames are read one period apart at the
    codec's rate, and its relit clip is written whole (it failed with "Invalid argument": frames at one time cannot
    be muxed)."""
    src = tmp_path / "untimed.mp4"
    with av.open(str(src), "w") as out:
        video = out.add_stream("libx264", rate=RATE)
        video.width = video.height = 64
        video.pix_fmt = "yuv420p"
        for i in range(8):
            image = np.full((64, 64, 3), 30 * i, np.uint8)
            image[:, : 4 + 6 * i] = 255  # a moving edge: frames the encoder does not skip
            frame = av.VideoFrame.from_ndarray(image, format="rgb24")
            frame.pts = 0
            out.mux(video.encode(frame))
        out.mux(video.encode(None))
    with av.open(str(src)) as given:
        assert {f.pts for f in given.decode(video=0)} == {0}  # (as such a tool writes it)
    reader = ClipReader(src)
    assert reader.info.rate == RATE
    reader.close()
    got = [f.time for f in ClipReader(_copied(src, tmp_path / "copy.mp4"))]
    assert got == pytest.approx([i / RATE for i in range(8)], abs=1e-3)


@pytest.mark.parametrize("refused", ["write", "finish"])
def test_a_clip_that_cannot_be_written_is_a_failed_clip_in_every_count(tmp_path, monkeypatch, capsys, refused):
    """A clip whose encoder refuses its frames (or its end) fails alone, said once, and is kept as a failed clip: in
    summary.json (why), in the terminal's count and the exit code; its half-written files and their folder are gone
    (it was left out of every count: "0 photos (0 ok, 0 doubtful, 0 failed)", and an empty folder was left; refused
    at its end, its temporary files stayed too)."""
    from shadowflow.nodes.app import clip_io
    from shadowflow.nodes.app.cli import main

    def refuse(self, *args):
        raise ValueError("the encoder refuses this frame")

    monkeypatch.setattr(clip_io.ClipEncoder, refused, refuse)
    src = _plain_clip(tmp_path / "plain.mp4", (64, 48), None)
    out = tmp_path / "out"
    code = main(["run", str(src), "--out", str(out), "--record", "none"])
    said = capsys.readouterr()
    assert code != 0
    (rec,) = json.loads((out / "summary.json").read_text())
    assert rec["stem"] == "plain" and rec["clip"]["frames"] == 4
    assert rec["status"] == f"{src}: cannot write its relit clip (the encoder refuses this frame)"
    assert "1 clip (0 ok, 1 failed)" in said.out + said.err
    assert (said.out + said.err).count("cannot write its relit clip") == 1
    assert not (out / "plain").exists()  # (its half-written files and the folder made for them are gone)


def test_a_clips_steadying_takes_its_frames_in_order_whatever_the_workers(tmp_path, procedural_model):
    """With ``--workers 2`` the fit and the relighting run two frames at once and finish them in either order; the
    steadying nodes, which carry a clip's light, view and honesty from frame to frame, still take them in order (one
    thread each, ``flow.pipeline.Stage.ordered``)."""
    from shadowflow.nodes.app.chain import run_nodes
    from shadowflow.nodes.app.engine import local_stages
    from shadowflow.nodes.method.options import MethodOptions

    stages = {s.node.name: s for s in local_stages(run_nodes(procedural_model, MethodOptions(), tmp_path, set()), 2)}
    assert all(stages[n].ordered and stages[n].workers == 1 for n in ("steady", "steady_yaw", "steady_relight"))
    assert stages["robust_fit"].workers == stages["relight_photo"].workers == 2
    assert not stages["robust_fit"].ordered and stages["load"].workers == 1
