"""The run's on-disk store of records and input entries, and the streamed JSON written from it."""
import json
import threading

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from shadowflow.flow.files import json_array_chunks
from shadowflow.flow.manifest import InputEntry, RunManifest
from shadowflow.flow.runstore import STORE_NAME, RunStore

json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False) | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=5), inner, max_size=3),
    max_leaves=12)


@settings(max_examples=150, deadline=None)
@given(st.lists(json_values, max_size=5), st.sampled_from([1, 2, 4]))
def test_streamed_json_array_is_byte_equal_to_json_dumps(items, indent):
    assert b"".join(json_array_chunks(iter(items), indent)).decode() == json.dumps(items, indent=indent)
    # nested one level down, as the manifest's "inputs" is
    doc = {"a": 1, "inputs": items}
    head = json.dumps({"a": 1, "inputs": []}, indent=indent)[:-len("[]\n}")]
    streamed = head + b"".join(json_array_chunks(iter(items), indent, level=1)).decode() + "\n}"
    assert streamed == json.dumps(doc, indent=indent)


def _entry(i: int, frame: int) -> InputEntry:
    return InputEntry(f"/in/{i:05d}.png", 100 + i, 10**18 + i, f"face{i}", frame, "c0ffee",
                      {"status": "ok", "stem": f"face{i}", "x": [i, 0.5]}, "ab" * 32)


def test_records_keep_input_order_and_a_replaced_record_keeps_its_place(tmp_path):
    store = RunStore(tmp_path)
    n = 1300  # more than two pages of reading
    for i in range(n):
        store.put_record(f"f{i}", {"stem": f"f{i}", "i": i})
    store.put_record("f7", {"stem": "f7", "i": -7})  # taken again: the newer record, same place
    got = list(store.records)
    assert len(store.records) == n and [r["i"] for r in got] == [-7 if i == 7 else i for i in range(n)]
    assert list(store.records) == got  # re-iterable: the report reads it twice
    store.close()
    assert not (tmp_path / STORE_NAME).exists()


def test_entries_behave_as_a_mapping_and_come_by_frame(tmp_path):
    store = RunStore(tmp_path)
    frames = list(range(1200))[::-1]  # put in reverse frame order
    for i, f in enumerate(frames):
        store.entries[f"/in/{i:05d}.png"] = _entry(i, f)
    e = store.entries["/in/00003.png"]
    assert e == _entry(3, frames[3]) and "/in/00003.png" in store.entries and "/in/x.png" not in store.entries
    assert store.entries.get("/in/x.png") is None and len(store.entries) == 1200
    assert [x.frame for x in store.entries.values()] == list(range(1200))
    assert sorted(store.entries) == sorted(f"/in/{i:05d}.png" for i in range(1200))
    store.entries["/in/00003.png"] = _entry(3, 5000)  # replaced, not added
    assert len(store.entries) == 1200 and store.entries["/in/00003.png"].frame == 5000
    del store.entries["/in/00003.png"]
    assert len(store.entries) == 1199
    with pytest.raises(KeyError):
        store.entries["/in/00003.png"]
    store.close()


def test_manifest_saved_from_the_store_equals_one_saved_from_memory(tmp_path):
    entries = {e.path: e for e in (_entry(i, (i * 37) % 600) for i in range(600))}
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir()
    b.mkdir()
    RunManifest({"k": [1, 2]}, ["run.mcap"], entries).save(a)
    store = RunStore(b)
    store.entries.update(entries)
    RunManifest({"k": [1, 2]}, ["run.mcap"], store.entries).save(b)
    store.close()
    assert (a / "manifest.json").read_bytes() == (b / "manifest.json").read_bytes()
    loaded = RunManifest.load(b)
    assert loaded is not None and loaded.entries == entries


def test_a_link_or_stale_store_in_the_folder_is_replaced_never_followed(tmp_path):
    outside = tmp_path / "precious.txt"
    outside.write_text("keep me")
    out = tmp_path / "out"
    out.mkdir()
    (out / STORE_NAME).symlink_to(outside)
    store = RunStore(out)
    store.put_record("a", {"stem": "a"})
    store.close()
    assert outside.read_text() == "keep me" and not (out / STORE_NAME).exists()
    (out / STORE_NAME).write_bytes(b"not a database")  # a killed run's leftover
    store = RunStore(out)
    assert len(store.records) == 0
    store.close()


def test_names_taken_and_what_the_run_gave_each_input(tmp_path):
    from shadowflow.nodes.app.outputs import safe_stem

    store = RunStore(tmp_path)
    taken = store.names
    taken |= {"face", "a_b"}
    assert [safe_stem(p, taken) for p in ("/x/face.png", "/y/face.jpg", "/x/a b.png", "/x/other.png")] == \
        ["face-2", "face-3", "a_b-2", "other"]
    assert sorted(taken) == ["a_b", "a_b-2", "face", "face-2", "face-3", "other"] and "FACE" not in taken
    assert store.assigned.get("/x/face.png") is None
    store.assigned.put("/x/face.png", "face-2", 7, (120, 10**18 + 3))
    store.assigned.put("/x/gone.png", "gone", 8, None)
    assert store.assigned.get("/x/face.png") == ("face-2", 7, (120, 10**18 + 3))
    assert store.assigned.get("/x/gone.png") == ("gone", 8, None)
    store.assigned.put("/x/face.png", "face-2", 7, (121, 5))  # changed while watched: the newer identity
    assert store.assigned.get("/x/face.png") == ("face-2", 7, (121, 5))
    store.close()


def test_a_path_that_is_not_utf8_is_a_key_like_any_other(tmp_path):
    """A Linux file name may hold any bytes; Python gives them as lone surrogates."""
    key = b"/in/caf\xe9 \xff.png".decode("utf-8", "surrogateescape")
    store = RunStore(tmp_path)
    store.entries[key] = _entry(1, 3)
    store.assigned.put(key, "caf", 3, (10, 20))
    store.names.add(key)
    store.put_record(key, {"source": key})
    assert list(store.entries) == [key] and key in store.entries and store.entries[key].frame == 3
    assert store.assigned.get(key) == ("caf", 3, (10, 20)) and list(store.names) == [key] and key in store.names
    assert [r["source"] for r in store.records] == [key]
    store.close()


def test_writers_and_a_reader_on_other_threads(tmp_path):
    store = RunStore(tmp_path)

    def put(base):
        for i in range(400):
            store.put_record(f"{base}-{i}", {"i": i})

    threads = [threading.Thread(target=put, args=(b,)) for b in "ab"]
    for t in threads:
        t.start()
    seen = sum(1 for _ in store.records)  # reading pages while they write
    for t in threads:
        t.join()
    assert 0 <= seen <= 800 and len(store.records) == 800
    store.close()
