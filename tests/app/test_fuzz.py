"""Property-based fuzzing of the two readers of untrusted bytes: the image loader and the
recording reader. Any input gives a result or the reader's own one-line error; never another
exception, never a large allocation. Bounded and derandomised, so CI runs the same cases."""
import io
import tempfile
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from shadowflow.flow.recording import Event, McapSink, OnMask, Recorder, RecordingError, read_mcap
from shadowflow.nodes.photo.input_error import InputError
from shadowflow.nodes.photo.loader import IMAGE_SUFFIXES, load_image

FUZZ = settings(max_examples=120, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
WORK = Path(tempfile.mkdtemp(prefix="shadowflow-fuzz-"))
MAX_GROWTH = 300 << 20  # bytes of peak resident memory any one fuzz run may add


def _peak_rss() -> int:
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) << 10 for line in f if line.startswith("VmHWM"))


def _reset_peak() -> bool:
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")  # resets VmHWM to the current resident size (Linux >= 4.0)
        return True
    except OSError:
        return False


def _image_seeds() -> dict[str, bytes]:
    rng = np.random.default_rng(1)
    img = (rng.random((40, 48)) * 255).astype(np.uint8)
    seeds = {ext: cv2.imencode(ext, img)[1].tobytes() for ext in (".png", ".jpg", ".tif", ".bmp", ".pgm")}
    seeds[".png16"] = cv2.imencode(".png", img.astype(np.uint16) * 257)[1].tobytes()
    buf = io.BytesIO()
    np.save(buf, img / 255.0)
    seeds[".npy"] = buf.getvalue()
    return seeds


IMAGE_SEEDS = _image_seeds()


def _mutate(seed: bytes, edits: list[tuple[int, int]], cut: float | None) -> bytes:
    """Overwrite bytes (position fraction -> value) and maybe cut the tail."""
    data = bytearray(seed)
    for pos, value in edits:
        data[pos % len(data)] = value
    if cut is not None:
        data = data[: int(len(data) * cut)]
    return bytes(data)


edits = st.lists(st.tuples(st.integers(0, 1 << 20), st.integers(0, 255)), max_size=12)
cuts = st.none() | st.floats(0.0, 1.0)


def _read_or_refuse(name: str, data: bytes, read, error):
    """``read`` the bytes from a file; its own ``error`` (one line naming the file) -> None."""
    path = WORK / name
    path.write_bytes(data)
    try:
        return read(path)
    except error as exc:
        assert str(exc).startswith(str(path)) and "\n" not in str(exc)
        return None


def _check_image(name: str, data: bytes) -> None:
    img = _read_or_refuse(name, data, load_image, InputError)
    if img is None:
        return
    assert img.dtype == np.float32 and img.ndim == 2 and min(img.shape) >= 32
    assert np.all(np.isfinite(img)) and img.min() >= 0.0 and img.max() <= 1.0


@FUZZ
@given(kind=st.sampled_from(sorted(IMAGE_SEEDS)), edits=edits, cut=cuts)
def test_loader_survives_mutated_images(kind, edits, cut):
    suffix = ".png" if kind == ".png16" else kind
    _check_image(f"mutant{suffix}", _mutate(IMAGE_SEEDS[kind], edits, cut))


@FUZZ
@given(data=st.binary(max_size=4096), suffix=st.sampled_from(sorted(IMAGE_SUFFIXES)))
def test_loader_survives_random_bytes(data, suffix):
    _check_image(f"random{suffix}", data)


def _recording_seed() -> bytes:
    """A small recording with every message kind the reader takes."""
    path = WORK / "seed.mcap"
    rec = Recorder([McapSink(path)])
    rng = np.random.default_rng(2)
    for frame in range(2):
        for it in (1, 2):
            rec.emit(Event(frame, "fit/weights", "image", rng.random((8, 8)).astype(np.float32), it))
            rec.emit(Event(frame, "fit/convergence", "scalars", {"sigma": 0.1 / it}, it))
            mask = rng.random((8, 8)) < 0.5  # a masked array message: bit mask + values
            rec.emit(Event(frame, "fit/residuals", "array", OnMask(rng.random(int(mask.sum())).astype(np.float32), mask), it))
        rec.emit(Event(frame, "fit/normals", "normals", rng.random((8, 8, 3)).astype(np.float32)))
        rec.frame_done(frame, {"source": f"f{frame}", "status": "ok"})
    rec.close()
    return path.read_bytes()


RECORDING_SEED = _recording_seed()


def _check_recording(data: bytes) -> None:
    rec = _read_or_refuse("mutant.mcap", data, read_mcap, RecordingError)
    if rec is None:
        return
    for fr in rec.frames.values():
        for by_it in fr.arrays.values():
            assert all(isinstance(a, np.ndarray) and a.dtype.kind in "fiub" for a in by_it.values())


@FUZZ
@given(edits=edits, cut=cuts)
def test_recording_reader_survives_mutated_recordings(edits, cut):
    _check_recording(_mutate(RECORDING_SEED, edits, cut))


@FUZZ
@given(position=st.integers(0, 1 << 20), value=st.sampled_from([2**31 - 1, 2**32 - 1, 2**62, 2**64 - 1]))
def test_recording_reader_refuses_huge_declared_lengths(position, value):
    """Any 8 bytes (a length, an offset, a size) replaced by a huge number."""
    data = bytearray(RECORDING_SEED)
    pos = 8 + position % (len(data) - 16)
    data[pos:pos + 8] = value.to_bytes(8, "little")
    _check_recording(bytes(data))


def test_fuzzing_stays_within_a_memory_bound():
    """Re-run a sample of the hostile cases with the peak resident size reset and measured."""
    if not _reset_peak():
        pytest.skip("/proc/self/clear_refs is not writable here: peak memory cannot be reset")
    start = _peak_rss()
    rng = np.random.default_rng(3)
    for _ in range(60):
        kind = sorted(IMAGE_SEEDS)[rng.integers(len(IMAGE_SEEDS))]
        pos = [(int(p), int(v)) for p, v in zip(rng.integers(0, 1 << 20, 6), rng.integers(0, 256, 6))]
        _check_image(f"mem{'.png' if kind == '.png16' else kind}", _mutate(IMAGE_SEEDS[kind], pos, None))
        data = bytearray(RECORDING_SEED)
        p = 8 + int(rng.integers(0, len(data) - 16))
        data[p:p + 8] = (2**62).to_bytes(8, "little")
        _check_recording(bytes(data))
    assert _peak_rss() - start < MAX_GROWTH


def _model_seed() -> bytes:
    from shadowflow.nodes.model.default_model import train_from_recipe
    from shadowflow.nodes.model.shape_model import save_model

    model = train_from_recipe({"source": "procedural", "n": 8, "seed": 0, "modes": 4, "size": [32, 32]})
    path = WORK / "seed-model.npz"
    save_model(model, path)
    return path.read_bytes()


MODEL_SEED = _model_seed()


def _check_model(data: bytes) -> None:
    from shadowflow.nodes.model.shape_model import load_model

    model = _read_or_refuse("mutant-model.npz", data, load_model, ValueError)
    if model is None:
        return
    for a in (model.mean_normals, model.mean_proj, model.modes, model.eigenvalues, model.eyes):
        assert np.all(np.isfinite(a))
    assert model.modes.shape[0] == 2 * model.n_pixels == 2 * int(model.mask.sum())


@FUZZ
@given(edits=edits, cut=cuts)
def test_model_loader_survives_mutated_model_files(edits, cut):
    """A damaged --model (any bytes changed, any tail cut): a model whose arrays are sound, or
    ``PATH: why`` on one line; never another exception."""
    _check_model(_mutate(MODEL_SEED, edits, cut))


def _manifest_seed() -> tuple[bytes, bytes]:
    from shadowflow.flow.manifest import InputEntry, Journal, RunManifest

    folder = WORK / "manifest-seed"
    folder.mkdir(exist_ok=True)
    man = RunManifest({"model": "abc", "options": {"fit": {"max_iterations": 8}}}, ["run.mcap"])
    man.entries["/in/a.png"] = InputEntry("/in/a.png", 10, 20, "a", 0, "c0", {"stem": "a", "status": "ok"}, "ff")
    man.save(folder)
    journal = Journal(folder)
    journal.append(InputEntry("/in/b.png", 11, 21, "b", 1, "c0", {"stem": "b", "status": "ok"}, "ee"))
    journal.close()
    return (folder / "manifest.json").read_bytes(), (folder / ".journal.jsonl").read_bytes()


MANIFEST_SEED, JOURNAL_SEED = _manifest_seed()
hostile_names = st.sampled_from(["", ".", "..", "../evil", "/abs/path", ".lock", "a/b", "run.mcap"])
json_values = st.recursive(st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8) | hostile_names,
                           lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner,
                                                                                      max_size=4), max_leaves=12)


def _check_manifest(manifest: bytes, journal: bytes) -> None:
    """RunManifest.load never raises: a manifest of well-typed entries, or None (all redone)."""
    from shadowflow.flow.manifest import RunManifest

    folder = WORK / "manifest-mutant"
    folder.mkdir(exist_ok=True)
    (folder / "manifest.json").write_bytes(manifest)
    (folder / ".journal.jsonl").write_bytes(journal)
    man = RunManifest.load(folder)
    if man is None:
        return
    assert isinstance(man.config, dict) and isinstance(man.config_id, str)
    assert all(isinstance(r, str) and "/" not in r for r in man.recordings)
    assert len({e.name.lower() for e in man.entries.values()}) == len({e.frame for e in man.entries.values()}) \
        == len(man.entries)  # no two inputs share an output folder or a frame id
    for key, e in man.entries.items():
        assert key == e.path and isinstance(e.size, int) and isinstance(e.frame, int) and e.frame >= 0
        assert isinstance(e.name, str) and e.name and "/" not in e.name and not e.name.startswith(".")
        assert e.record is None or isinstance(e.record, dict)
    assert man.next_frame() >= 0


@FUZZ
@given(m_edits=edits, m_cut=cuts, j_edits=edits, j_cut=cuts)
def test_run_manifest_survives_mutated_bytes(m_edits, m_cut, j_edits, j_cut):
    _check_manifest(_mutate(MANIFEST_SEED, m_edits, m_cut), _mutate(JOURNAL_SEED, j_edits, j_cut))


@FUZZ
@given(field=st.sampled_from(["format", "config", "recordings", "inputs", "path", "size", "mtime_ns", "name",
                              "frame", "config", "record", "sha256"]), value=json_values)
def test_run_manifest_survives_any_json_in_any_field(field, value):
    import json

    body = json.loads(MANIFEST_SEED)
    if field in body:
        body[field] = value
    else:
        body["inputs"][0][field] = value
    line = json.loads(JOURNAL_SEED)
    line[field] = value
    _check_manifest(json.dumps(body).encode(), (json.dumps(line) + "\n").encode())


def test_run_manifest_never_gives_two_inputs_one_output_folder_or_frame_id():
    import json

    from shadowflow.flow.manifest import RunManifest

    body = json.loads(MANIFEST_SEED)
    twin = dict(body["inputs"][0], path="/in/other.png")  # a second input under the same name and id
    body["inputs"].append(twin)
    body["inputs"].append(dict(twin, path="/in/third.png", name="c"))  # a new name, the same frame id
    folder = WORK / "manifest-twins"
    folder.mkdir(exist_ok=True)
    (folder / "manifest.json").write_text(json.dumps(body))
    (folder / ".journal.jsonl").write_bytes(JOURNAL_SEED)
    man = RunManifest.load(folder)
    assert sorted(man.entries) == ["/in/a.png", "/in/b.png"]


@pytest.mark.parametrize("field, value", [("name", n) for n in ["", ".", "..", "../evil", "/abs", ".lock", "a/b"]]
                         + [("frame", -1), ("frame", True), ("size", "10"), ("path", None), ("record", [1])])
def test_run_manifest_drops_entries_that_could_point_outside_out(field, value):
    """An entry's name becomes OUT/<name>/: one that is empty, hidden, absolute or has a slash is
    dropped (its input is then redone under a safe name), as is any field of the wrong type."""
    import json

    from shadowflow.flow.manifest import RunManifest

    body = json.loads(MANIFEST_SEED)
    body["inputs"][0][field] = value
    folder = WORK / "manifest-named"
    folder.mkdir(exist_ok=True)
    (folder / "manifest.json").write_text(json.dumps(body))
    (folder / ".journal.jsonl").write_bytes(b"")
    man = RunManifest.load(folder)
    entry = man.entries.get("/in/a.png")
    assert entry is None if field != "record" else entry.record is None
