"""Hostile inputs and faults: every case ends in its documented outcome, good faces in the same
stream come out exactly as they do alone, nothing outside ``--out`` is touched.

The corpus is generated here (no committed blobs); README "Bad input" lists the outcomes.
"""
import io
import json
import os
import shutil
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest
from shadowflow.nodes.evaluation.scenes import write_shadowed_face
from shadowflow.nodes.geometry.normals import angle_deg
from shadowflow.nodes.geometry.reflectance import light_from_angles

from conftest import run_cli

CLI = [sys.executable, "-m", "shadowflow.nodes.app.cli"]
REPO = Path(__file__).resolve().parents[2]


def _png_header_only(width: int, height: int) -> bytes:
    """A PNG whose header declares ``width`` x ``height`` grey pixels, with no pixel data."""
    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"")) + chunk(b"IEND", b"")


def _npy_header_only(shape: tuple[int, ...]) -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": "<f4", "fortran_order": False, "shape": shape})
    return buf.getvalue() + b"\x00" * 64


def _good_faces(folder: Path) -> dict[str, Path]:
    """Good inputs with sidecar lights, including awkward names and two with one stem."""
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(5)
    base = write_shadowed_face(folder / "face.png", rng, light_from_angles(40, 0))
    image = cv2.imread(str(base), cv2.IMREAD_GRAYSCALE)
    side = base.with_suffix(".json").read_text()
    faces = {"face.png": base}
    for name in ("a face.png", "ünïcødé.png", "-rf.png", "x..y.png"):
        shutil.copy(base, folder / name)
        (folder / name).with_suffix(".json").write_text(side)
        faces[name] = folder / name
    cv2.imwrite(str(folder / "face.jpg"), image, [cv2.IMWRITE_JPEG_QUALITY, 98])  # same stem as face.png
    faces["face.jpg"] = folder / "face.jpg"
    return faces


def _variants(folder: Path, image: np.ndarray, side: str) -> dict[str, str]:
    """The same face stored in other ways the loader must read: name -> its expected status ('ok', or how a
    doubtful one begins)."""
    from PIL import Image

    out = {}

    def put(name: str, write) -> None:
        write(folder / name)
        (folder / name).with_suffix(".json").write_text(side)
        out[name] = "ok"

    put("sixteen.png", lambda p: cv2.imwrite(str(p), image.astype(np.uint16) * 257))
    grey3 = np.dstack([image] * 3)
    put("colour.png", lambda p: cv2.imwrite(str(p), grey3))
    put("alpha.png", lambda p: cv2.imwrite(str(p), np.dstack([grey3, np.full_like(image, 128)])))
    put("palette.png", lambda p: Image.fromarray(image).convert("P").save(p))

    def exif_rotated(p: Path) -> None:  # stored rotated; the EXIF tag says how to show it upright
        from shadowflow.nodes.photo.encoding import linear_to_srgb

        encoded = (linear_to_srgb(image / 255.0) * 255 + 0.5).astype(np.uint8)  # a JPEG is sRGB, as a camera's
        im = Image.fromarray(np.ascontiguousarray(np.rot90(encoded, 1)))
        exif = im.getexif()
        exif[0x0112] = 6  # "rotate 90 degrees clockwise to display"
        im.save(p, "JPEG", quality=98, exif=exif.tobytes())

    put("exif.jpg", exif_rotated)
    put("saturated.png", lambda p: cv2.imwrite(str(p), np.clip(image.astype(np.float32) * 1.6, 0, 255).astype(np.uint8)))
    # read and fitted, then given back as it was: relit, a quarter of its face the file cut at 255 would be darkened
    # into one flat tone (``relight.harm.flattened``)
    out["saturated.png"] = "doubtful: relit it would darken"
    return out


def _hostile(folder: Path, good_png: bytes, unprivileged: bool) -> dict[str, str]:
    """Write the hostile corpus; returns name -> a piece of the expected one-line error."""
    cases: dict[str, str] = {}

    def put(name: str, data: bytes, expect: str, sidecar: str | None = None) -> None:
        (folder / name).write_bytes(data)
        if sidecar is not None:
            (folder / name).with_suffix(".json").write_text(sidecar)
        cases[name] = expect

    good_jpg = cv2.imencode(".jpg", cv2.imdecode(np.frombuffer(good_png, np.uint8), 0))[1].tobytes()
    crc = bytearray(good_png)
    crc[crc.find(b"IDAT") + 40] ^= 0xFF
    rng = np.random.default_rng(0)
    put("empty.png", b"", "is empty (0 bytes)")
    put("half.png", good_png[: len(good_png) // 2], "corrupt or truncated PNG")
    put("half.jpg", good_jpg[: len(good_jpg) // 2], "corrupt or truncated JPEG")
    put("badcrc.png", bytes(crc), "corrupt or truncated PNG")
    put("text.jpg", b"just some notes, not a picture\n", "not a recognised image")
    put("noise.tif", rng.integers(0, 256, 4096, dtype=np.uint8).tobytes(), "not a recognised image")
    put("tiny1.png", cv2.imencode(".png", np.full((1, 1), 100, np.uint8))[1].tobytes(), "too small for a face")
    put("tiny8.png", cv2.imencode(".png", rng.integers(0, 256, (8, 8), dtype=np.uint8))[1].tobytes(), "too small for a face")
    put("huge.png", _png_header_only(20000, 20000), "megapixel limit")
    put("big.png", _png_header_only(8000, 6000), "megapixel limit")
    put("black.png", cv2.imencode(".png", np.zeros((64, 64), np.uint8))[1].tobytes(), "no contrast")
    put("white.png", cv2.imencode(".png", np.full((64, 64), 255, np.uint8))[1].tobytes(), "no contrast")
    face = cv2.imdecode(np.frombuffer(good_png, np.uint8), 0) / 255.0
    for name, bad in (("nan.npy", np.nan), ("inf.npy", np.inf)):
        arr = face.copy()
        arr[60, 60] = bad
        buf = io.BytesIO()
        np.save(buf, arr)
        put(name, buf.getvalue(), "NaN or infinite")
    buf = io.BytesIO()
    np.save(buf, np.array([{"run": "code"}], dtype=object), allow_pickle=True)
    put("pickle.npy", buf.getvalue(), "2-D numeric")
    buf = io.BytesIO()
    np.save(buf, np.zeros((4, 4, 4)))
    put("cube.npy", buf.getvalue(), "2-D numeric")
    put("declared-huge.npy", _npy_header_only((100000, 100000)), "megapixel limit")
    put("badjson.png", good_png, "malformed sidecar", "{not json")
    put("zerolight.png", good_png, "zero vector", '{"light": [0, 0, 0]}')
    put("behind.png", good_png, "points away from the camera", '{"light": [0, 0, -1]}')
    put("nanlight.png", good_png, "finite", '{"light": [NaN, 0, 1]}')
    put("badeyes.png", good_png, "eyes must be", '{"light": [0, 0, 1], "eyes": [[1, 2]]}')
    put("listjson.png", good_png, "top level is not an object", "[1, 2, 3]")
    put("yaleB99_P00A+200E+00.png", good_png, "impossible Yale B angles")
    put("yaleB99_P00A+120E+00.png", good_png, "points away from the camera")
    put("portrait.png", good_png, "no Yale B light")
    (folder / "folder.png").mkdir()
    cases["folder.png"] = "is a directory"
    os.symlink(folder / "loop-b.png", folder / "loop-a.png")
    os.symlink(folder / "loop-a.png", folder / "loop-b.png")
    cases["loop-a.png"] = cases["loop-b.png"] = "symlink loop"
    os.symlink(folder / "gone.png", folder / "dangling.png")
    cases["dangling.png"] = "dangling symlink"
    os.mkfifo(folder / "pipe.png")
    cases["pipe.png"] = "not a regular file"
    if unprivileged:
        put("locked.png", good_png, "Permission denied", '{"light": [0, 0, 1]}')
        os.chmod(folder / "locked.png", 0)
    return cases


def _normals_by_source(out: Path) -> dict[str, np.ndarray]:
    summary = json.loads((out / "summary.json").read_text())
    return {Path(r["source"]).name: np.load(out / r["stem"] / "normals.npy", allow_pickle=False)
            for r in summary if r["status"] == "ok"}


@pytest.mark.slow
def test_a_stream_of_hostile_inputs_fails_each_alone_and_keeps_good_faces_exact(tmp_path, unprivileged):
    prefix = unprivileged
    good_dir = tmp_path / "good"
    faces = _good_faces(good_dir)
    mixed = tmp_path / "mixed"
    shutil.copytree(good_dir, mixed)
    base = faces["face.png"]
    expected = {name: "ok" for name in faces}
    expected.update(_variants(mixed, cv2.imread(str(base), 0), base.with_suffix(".json").read_text()))
    hostile = _hostile(mixed, base.read_bytes(), unprivileged=True)
    expected.update(hostile)
    (mixed / "notes.txt").write_text("not an image")
    assert len(hostile) >= 25
    before = {p: p.read_bytes() for p in mixed.rglob("*")
              if p.is_file() and not p.is_symlink() and os.access(p, os.R_OK)}

    opts = ["--light", "yaleb", "--max-iterations", "15", "--record", "mcap", "--quiet"]
    out = tmp_path / "out"
    proc = subprocess.run(prefix + CLI + ["run", str(mixed), "--out", str(out)] + opts,
                          capture_output=True, text=True, cwd=REPO, timeout=600)
    assert proc.returncode == 1, proc.stderr  # some frames failed, the stream finished
    summary = json.loads((out / "summary.json").read_text())
    by_name = {Path(r["source"]).name: r for r in summary}
    assert set(by_name) == set(expected), set(by_name) ^ set(expected)
    errors = [line for line in proc.stderr.splitlines() if line.startswith("error: ")]
    for name, expect in expected.items():
        status = by_name[name]["status"]
        if expect == "ok" or expect.startswith("doubtful"):  # read: relit, or given back saying why
            assert status == expect if expect == "ok" else status.startswith(expect), (name, status)
            continue
        assert expect in status and name in status and "\n" not in status, (name, status)
        assert any(name in e and expect in e for e in errors), name  # and it was said on stderr
    assert len(errors) == len(hostile), proc.stderr  # one line each (failed once in CI: 31, unexplained)

    # every output stays inside --out, one folder per input, none overwriting another
    stems = [r["stem"] for r in summary if r["status"] == "ok"]
    assert len(set(stems)) == len(stems) and {"face", "face-2"} <= set(stems)
    for stem in stems:
        assert (out / stem).resolve().parent == out.resolve() and not stem.startswith(("-", "."))
    # the inputs are untouched
    assert {p: p.read_bytes() for p in before} == before

    # the good faces come out exactly as in a run of the good faces alone
    alone = tmp_path / "alone"
    subprocess.run(CLI + ["run", str(good_dir), "--out", str(alone)] + opts, check=True, cwd=REPO, timeout=600)
    mixed_normals, alone_normals = _normals_by_source(out), _normals_by_source(alone)
    for name in faces:
        np.testing.assert_array_equal(mixed_normals[name], alone_normals[name])
    # and the other encodings of the same face are read as that face
    ref = mixed_normals["face.png"]
    for name in ("sixteen.png", "colour.png", "alpha.png", "palette.png", "exif.jpg"):
        n = mixed_normals[name]
        ok = np.isfinite(n[..., 0]) & np.isfinite(ref[..., 0])
        assert n.shape == ref.shape and np.mean(angle_deg(n[ok], ref[ok])) < 1.0, name


def test_frame_timeout_abandons_a_slow_fit_and_the_run_goes_on(tmp_path, shadowed_faces):
    src = shadowed_faces(tmp_path / "in", 2, seed=9)
    out = tmp_path / "out"
    proc = subprocess.run(CLI + ["run", str(src), "--out", str(out), "--frame-timeout", "0.01", "--record", "mcap"],
                          capture_output=True, text=True, cwd=REPO, timeout=300)
    assert proc.returncode == 1
    summary = json.loads((out / "summary.json").read_text())
    assert len(summary) == 2
    assert all("timed out after 0.01 s" in r["status"] for r in summary)
    assert not any((out / r["stem"] / "normals.npy").exists() for r in summary)
    from shadowflow.flow.replay import open_recording

    rec = open_recording(out / "run.mcap")
    assert [f.record["status"] for f in rec.finished_frames()] == [r["status"] for r in summary]


@pytest.mark.slow
def test_an_input_whose_name_is_not_utf8_runs_and_resumes(tmp_path, shadowed_faces):
    src = shadowed_faces(tmp_path / "in", 1, seed=4)
    for suffix in (".png", ".json"):  # bytes that are no UTF-8 in the name
        os.rename(src / f"f0{suffix}", os.fsencode(src) + b"/caf\xe9\xff" + suffix.encode())
    with open(os.fsencode(src) + b"/junk\xfe.png", "wb") as f:  # and one that fails
        f.write(b"not an image")
    out = tmp_path / "out"
    cmd = CLI + ["run", str(src), "--out", str(out), "--record", "mcap", "--max-iterations", "10"]
    first = subprocess.run(cmd, capture_output=True, text=True, cwd=REPO, timeout=300)
    assert first.returncode == 1 and "Traceback" not in first.stderr, first.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert [r["status"] == "ok" for r in summary] == [True, False]
    assert (out / summary[0]["stem"] / "relit.png").is_file() and "not a recognised image" in summary[1]["status"]
    report = (out / "report.html").read_text()  # valid UTF-8; the undecodable bytes shown as U+FFFD
    assert "junk\ufffd.png" in report and "1 failed" in report
    again = subprocess.run(cmd + ["--resume"], capture_output=True, text=True, cwd=REPO, timeout=300)
    assert again.returncode == 1 and "Traceback" not in again.stderr and "caf" not in again.stderr, again.stderr
    assert json.loads((out / "summary.json").read_text())[0] == summary[0]


@pytest.mark.parametrize("args, says", [
    (["--workers", "0"], "--workers must be 1 or more"),
    (["--max-iterations", "0"], "(--max-iterations) must be an integer of at least 1"),
    (["--frame-timeout", "inf"], "--frame-timeout must be a finite number"),
    (["--frame-timeout", "-1"], "--frame-timeout must be a finite number"),
    (["--record-every", "0"], "--record-every must be 1 or more"),
    (["--eyes", "nan,1,2,3"], "four finite numbers"),
    (["--eyes", "5,5,5,5"], "two distinct eye centres"),
    (["--view-angle", "120"], "--view-angle"),
    (["--eye-contrast", "1.5"], "--eye-contrast"),
])
def test_arguments_that_cannot_work_are_refused_before_any_work(tmp_path, args, says):
    """Each once hung (--workers 0), failed every frame (--frame-timeout inf, --max-iterations 0)
    or was taken (--eyes nan): now one line, exit 2, and nothing written."""
    out = tmp_path / "out"
    proc = subprocess.run(CLI + ["run", "--demo", "--out", str(out), "--quiet", *args], capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 2 and says in proc.stderr and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert not out.exists()


def test_frames_have_a_time_limit_unless_told_otherwise():
    """Issue 39 #13: no limit by default, so a file costing unbounded work held its frame for minutes."""
    from shadowflow.nodes.app.cli import build_parser, run_options
    from shadowflow.nodes.app.runner import DEFAULT_FRAME_TIMEOUT, RunOptions

    assert RunOptions().frame_timeout == DEFAULT_FRAME_TIMEOUT == 120.0
    parse = build_parser().parse_args
    assert run_options(parse(["run", "--demo", "--out", "o"])).frame_timeout == DEFAULT_FRAME_TIMEOUT
    assert run_options(parse(["run", "--demo", "--out", "o", "--frame-timeout", "0"])).frame_timeout is None
    assert run_options(parse(["run", "--demo", "--out", "o", "--frame-timeout", "2.5"])).frame_timeout == 2.5


@pytest.mark.parametrize("summary", ["null", "5", '[{"stem": ["a"], "status": "ok"}]', '{"stem": "x"}', '[null, 3]'])
def test_resume_over_a_mangled_summary_redoes_what_it_cannot_trust(tmp_path, summary):
    """--resume used to end in a traceback when summary.json held null, a number or a list stem."""
    src = tmp_path / "in"
    src.mkdir()
    face = src / "face.png"
    from shadowflow.nodes.evaluation.scenes import write_shadowed_face
    from shadowflow.nodes.geometry.reflectance import light_from_angles

    write_shadowed_face(face, np.random.default_rng(1), light_from_angles(30))
    out = tmp_path / "out"
    assert run_cli(["run", str(src), "--out", str(out), "--quiet", "--record", "none"]).returncode == 0
    (out / "summary.json").write_text(summary)  # (a summary.json no run wrote is refused: test_hostile_inputs)
    proc = subprocess.run(CLI + ["run", str(src), "--out", str(out), "--resume", "--quiet", "--record", "none"],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    records = json.loads((out / "summary.json").read_text())
    assert [r["status"] for r in records] == ["ok"] and (out / "face" / "normals.npy").is_file()


@pytest.mark.slow
def test_odd_images_are_read_on_their_real_scale_or_refused_with_the_reason(tmp_path):
    """A float TIFF in 0-255, 32-bit integer and 64-bit float TIFFs and a 40 x 40000 PNG gave
    internal errors or 'corrupt'; an output folder named like an input was listed on every run."""
    import tifffile

    src = tmp_path / "in"
    src.mkdir()
    face = write_shadowed_face(src / "face.png", np.random.default_rng(3), light_from_angles(30))
    grey = cv2.imread(str(face), cv2.IMREAD_GRAYSCALE)
    side = face.with_suffix(".json").read_text()
    variants = {"float255.tif": grey.astype(np.float32), "u32.tif": grey.astype(np.uint32) * 257,
                "f64.tif": grey.astype(np.float64) / 255.0, "i16.tif": grey.astype(np.int16) * 4}
    for name, arr in variants.items():
        tifffile.imwrite(src / name, arr)
        (src / name).with_suffix(".json").write_text(side)
    cv2.imwrite(str(src / "strip.png"), np.tile((np.arange(40, dtype=np.uint8) * 5)[:, None], (1, 40000)))
    cv2.imwrite(str(src / "thin.png"), np.tile((np.arange(40, dtype=np.uint8) * 5)[:, None], (1, 2000)))
    shutil.copy(face, src / "photo.png.png")
    shutil.copy(face.with_suffix(".json"), src / "photo.png.json")
    for _ in range(2):  # the second run sees OUT/photo.png/ beside its inputs (--out is the input folder)
        proc = subprocess.run(CLI + ["run", str(src), "--out", str(src), "--record", "none", "--quiet", "--resume"],
                              capture_output=True, text=True, timeout=300)
        assert proc.returncode == 1, proc.stderr
        records = {r["stem"]: r for r in json.loads((src / "summary.json").read_text())}
        assert set(records) == {"face", "float255", "u32", "f64", "i16", "strip", "thin", "photo.png"}
    assert "a side over 32000 pixels" in records["strip"]["status"]
    assert "too long and thin for a photo of a face" in records["thin"]["status"]
    normals = np.load(src / "face" / "normals.npy")
    for name in ("float255", "u32", "f64", "i16"):  # the same picture on another scale: the same fit
        assert records[name]["status"] == "ok", records[name]
        err = angle_deg(np.load(src / name / "normals.npy"), normals)
        assert np.nanmax(err) < 0.5, (name, np.nanmax(err))


@pytest.mark.slow
def test_a_33_megapixel_jpeg_is_read_reduced_and_memory_stays_bounded(tmp_path):
    """A 33 MP JPEG took 10.1 GB and 116 s: photos over --max-megapixels (4) are decoded reduced
    (libjpeg's 1/2 scale, then area-averaged), their sidecar eyes scaled with them."""
    face = write_shadowed_face(tmp_path / "face.png", np.random.default_rng(4), light_from_angles(40), source="ict")
    side = json.loads(face.with_suffix(".json").read_text())
    k = 44  # 128 px render -> 5632 px: a 5632 x 5632 frame, 31.7 MP, sRGB-encoded as a camera's JPEG is
    from shadowflow.nodes.photo.encoding import linear_to_srgb

    linear = cv2.resize(cv2.imread(str(face)) / np.float32(255.0), None, fx=k, fy=k, interpolation=cv2.INTER_LINEAR)
    big = (linear_to_srgb(linear) * 255 + 0.5).astype(np.uint8)
    del linear
    photo = tmp_path / "big.jpg"
    cv2.imwrite(str(photo), big, [cv2.IMWRITE_JPEG_QUALITY, 90])
    del big
    side["eyes"] = (np.array(side["eyes"]) * k + (k - 1) / 2).tolist()  # pixel centres scale about -0.5
    photo.with_suffix(".json").write_text(json.dumps(side))
    out = tmp_path / "out"
    code = ("import sys\nfrom shadowflow.nodes.app.cli import main\n"
            f"rc = main(['run', {str(photo)!r}, '--out', {str(out)!r}, '--record', 'none', '--quiet'])\n"
            "print([int(x.split()[1]) for x in open('/proc/self/status') if x.startswith('VmHWM')][0])\n"
            "sys.exit(rc)\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    peak_mib = int(proc.stdout.split()[-1]) / 1024  # VmHWM: this process's own peak, from its exec
    rec = json.loads((out / "summary.json").read_text())[0]
    assert rec["status"] == "ok" and rec["reduced"]["from"] == [5632, 5632], rec
    w, h = rec["reduced"]["to"]
    assert w * h <= 4_000_000 and w > 1900
    assert cv2.imread(str(out / "big" / "relit.png")).shape[:2] == (h, w)
    small = subprocess.run(CLI + ["run", str(face), "--out", str(tmp_path / "small"), "--record", "none", "--quiet"],
                           capture_output=True, text=True, timeout=300)
    assert small.returncode == 0
    # the same face: the fit of the reduced photo agrees with the 128 px original's
    ref = json.loads((tmp_path / "small" / "summary.json").read_text())[0]
    assert abs(rec["final_sigma"] - ref["final_sigma"]) < 0.01 and rec["quality"]["score"] > 0.7
    assert peak_mib < 1024, peak_mib  # measured 0.64 GiB; before: 10.1 GB
