"""Hostile files at the loader: plain PNMs of any depth, sidecars of any size or with a byte-order
mark, eyes that cannot place a face, and arrays given to the API that are too large, empty or on
another scale. Each case failed as described before its fix."""
import json

import numpy as np
import pytest
from shadowflow.nodes.photo.input_error import InputError
from shadowflow.nodes.photo.loader import read_photo
from shadowflow.nodes.photo.sidecar import read_sidecar


def _plain(path, magic, maxval, samples):
    h, w = samples.shape[:2]
    body = " ".join(str(int(v)) for v in samples.reshape(-1))
    path.write_text(f"{magic}\n# made by a test\n{w} {h}\n{maxval}\n{body}\n")
    return path


def test_plain_pnm_of_any_depth_is_read_on_its_own_scale(tmp_path):
    """A 12-bit P3 came out 16x too dark (and ``ok``); a 10-bit P2 failed with an internal error."""
    ramp = np.tile(np.linspace(0, 1, 48), (40, 1))
    p3 = _plain(tmp_path / "twelve.ppm", "P3", 4095, np.dstack([ramp, ramp / 2, ramp / 4]) * 4095)
    p2 = _plain(tmp_path / "ten.pgm", "P2", 1023, np.round(ramp * 1023))
    colour = read_photo(p3, encoding="linear").colour
    np.testing.assert_allclose(colour[0, -1], [1.0, 0.5, 0.25], atol=1e-3)
    grey = read_photo(p2).grey
    np.testing.assert_allclose(grey[5], ramp[5], atol=1e-3)
    (tmp_path / "short.pgm").write_text("P2\n40 40\n255\n1 2 3\n")
    with pytest.raises(InputError, match="short.pgm: corrupt or truncated plain PNM"):
        read_photo(tmp_path / "short.pgm")


def test_a_sidecar_is_read_with_a_byte_order_mark_and_refused_when_huge(tmp_path):
    """A sidecar with a UTF-8 BOM was "malformed"; a 300 MB one was read whole, a 4 GB sparse one until
    memory ran out."""
    photo = tmp_path / "face.png"
    photo.write_bytes(b"")
    (tmp_path / "face.json").write_bytes(b"\xef\xbb\xbf" + json.dumps({"light": [0, 0, 1]}).encode())
    assert read_sidecar(photo).light.tolist() == [0.0, 0.0, 1.0]
    with open(tmp_path / "face.json", "wb") as fh:  # sparse: 4 GB on the directory, nothing on disk
        fh.truncate(4 << 30)
    with pytest.raises(InputError, match="face.png: its sidecar face.json is .* over the 65536-byte limit"):
        read_sidecar(photo)
    (tmp_path / "face.json").write_text('{"light": ' + "[" * 100000 + "]" * 100000 + "}")
    with pytest.raises(InputError, match="face.png: its sidecar face.json is"):
        read_sidecar(photo)


def test_arrays_given_to_fit_are_checked_and_reduced_as_files_are():
    """``shadowflow.fit`` of a 10000 x 10000 array applied neither the 40 MP limit nor the 4 MP reduction
    (294 s, 8.6 GB, then MemoryError); an empty or 0-255 float array and NaN eyes gave internal errors."""
    import shadowflow
    from shadowflow.nodes.photo.loader import photo_from_samples

    with pytest.raises(InputError, match="exceeds the 40-megapixel limit"):
        shadowflow.fit(np.lib.stride_tricks.as_strided(np.zeros(1, np.uint8), (10000, 10000), (0, 0)))
    with pytest.raises(InputError, match="too small"):
        shadowflow.fit(np.zeros((0, 0)))
    photo = photo_from_samples("<array>", np.zeros((3000, 3000), np.uint8) + np.arange(3000, dtype=np.uint8)[None, :],
                               max_pixels=4_000_000)
    assert photo.scale == pytest.approx(2000 / 3000, abs=1e-3) and photo.grey.shape == (2000, 2000)
    photo = photo_from_samples("<array>", np.tile(np.linspace(0, 255, 64), (64, 1)))  # floats over 1: own range
    assert photo.grey.max() == pytest.approx(1.0) and photo.grey[0, 32] == pytest.approx(0.51, abs=0.02)
    for eyes in ([[np.nan, 1], [2, 3]], [[1e9, 1], [2e9, 3]], [[10, 10], [10.5, 10]]):
        with pytest.raises(InputError, match="given eyes"):
            shadowflow.fit(np.random.default_rng(0).random((100, 100)), eyes=eyes)
    for eyes in ("x", [[1, 2]], [1, 2, 3, 4, 5], {"a": 1}):  # Python's own messages before
        with pytest.raises(ValueError, match=r"give the two eye centres \[\[x1, y1\], \[x2, y2\]\]"):
            shadowflow.fit(np.random.default_rng(0).random((100, 100)), eyes=eyes)


def test_a_light_given_to_fit_is_read_as_the_command_line_reads_it():
    """A light that is not unit length gave a different, failed fit (the command line normalises it);
    one given as a string ("0,0,1", "YALEB") was silently replaced by an estimate."""
    from shadowflow.nodes.app.api import _options

    assert np.allclose(_options(None, [0, 0, 2], None).light, [0, 0, 1])
    assert np.allclose(_options(None, "0,0,1", None).light, [0, 0, 1])
    assert np.allclose(_options(None, "30,10", None).light, _options(None, [30, 10], None).light)
    assert _options(None, "YALEB", None).light == "yaleb"
    with pytest.raises(ValueError, match="points away"):
        _options(None, [0, 0, -1], None)
    # huge or tiny components: a direction all the same (the norm of 1e308s overflowed to "away from the camera")
    assert np.allclose(_options(None, [1e308, 0, 1e308], None).light, [0.5**0.5, 0, 0.5**0.5])
    assert np.allclose(_options(None, [-1e300, 1e300, 1e300], None).light, np.array([-1, 1, 1]) / 3**0.5)
    with pytest.raises(ValueError, match="zero vector"):
        _options(None, [0, 0, 0], None)


def _jpeg_scans_cut(data: bytes) -> list[tuple[int, int]]:
    """(start, end) of each scan of a baseline-structured JPEG: its SOS segment and entropy-coded data."""
    out, i = [], 2
    while data[i + 1] != 0xD9:
        length = int.from_bytes(data[i + 2:i + 4], "big")
        j = i + 2 + length
        if data[i + 1] == 0xDA:
            while data[j] != 0xFF or data[j + 1] == 0 or 0xD0 <= data[j + 1] <= 0xD7:
                j += 1
            out.append((i, j))
        i = j
    return out


def test_a_jpeg_of_thousands_of_scans_is_refused_before_it_is_decoded(tmp_path):
    """Issue 39 #13: a progressive JPEG that repeats a scan thousands of times took 35-105 s of CPU to
    decode (each scan is a pass over the photo). A real progressive JPEG (10 scans) is still read."""
    import cv2
    from shadowflow.nodes.photo.loader import MAX_JPEG_SCANS, jpeg_scans

    rng = np.random.default_rng(0)
    img = cv2.GaussianBlur(rng.integers(0, 255, (480, 640, 3), dtype=np.uint8), (0, 0), 3)
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_PROGRESSIVE, 1])
    good = bytes(buf)
    scans = _jpeg_scans_cut(good)
    assert jpeg_scans(good) == len(scans) == 10
    (tmp_path / "progressive.jpg").write_bytes(good)
    assert read_photo(tmp_path / "progressive.jpg").grey.shape == (480, 640)
    start, end = scans[-1]  # the last refinement scan, repeated
    evil = good[:end] + good[start:end] * 3000 + good[end:]
    (tmp_path / "scans.jpg").write_bytes(evil)
    with pytest.raises(InputError, match=rf"scans.jpg: a progressive JPEG of 3010 scans, over the {MAX_JPEG_SCANS}-scan"):
        read_photo(tmp_path / "scans.jpg")  # counted, not decoded (decoding it takes seconds)


def test_a_turned_photo_reports_its_size_upright_as_its_reduction_does(tmp_path):
    """EXIF orientation 6 (turned a quarter): ``reduced`` gave the file's stored width and height "from" and
    the upright ones "to", so the two did not describe one turn."""
    from PIL import Image

    rng = np.random.default_rng(1)
    stored = (rng.integers(0, 255, (1500, 2400, 3))).astype(np.uint8)  # 2400 wide as stored
    exif = Image.Exif()
    exif[0x0112] = 6
    Image.fromarray(stored).save(tmp_path / "turned.jpg", exif=exif.tobytes())
    photo = read_photo(tmp_path / "turned.jpg", max_pixels=1_000_000)
    h, w = photo.grey.shape
    assert h > w  # upright: the turn applied
    assert photo.size == (1500, 2400)  # upright width, height
    assert abs(photo.size[0] * photo.scale - w) <= 1 and abs(photo.size[1] * photo.scale - h) <= 1


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float64, np.int32])
def test_a_planar_rgb_tiff_is_read_as_its_colours(tmp_path, dtype):
    """A planar (one plane a channel) RGB TIFF of a type OpenCV cannot read was refused as "not one grey or
    colour image"."""
    import tifffile

    rng = np.random.default_rng(2)
    rgb = rng.random((90, 70, 3))
    scale = {np.uint8: 255, np.uint16: 65535, np.float64: 1.0, np.int32: 65535}[dtype]
    tifffile.imwrite(tmp_path / "planar.tif", np.moveaxis(rgb * scale, -1, 0).astype(dtype), planarconfig="separate",
                     photometric="rgb")
    colour = read_photo(tmp_path / "planar.tif", encoding="linear").colour
    np.testing.assert_allclose(colour, rgb, atol=1.0 / 250)


def test_an_integer_npy_is_read_on_its_own_scale_as_an_image_file_is(tmp_path):
    """An 8- or 12-bit integer ``.npy`` was clipped to [0, 1] (every pixel above 0 full white); negative
    samples were taken."""
    ramp = np.tile(np.linspace(0.0, 1.0, 64), (72, 1))
    for dtype, top in ((np.uint8, 255), (np.int32, 4095), (np.float32, 1.0)):
        np.save(tmp_path / "ramp.npy", (ramp * top).astype(dtype))
        np.testing.assert_allclose(read_photo(tmp_path / "ramp.npy").grey, ramp, atol=1.0 / 250)
    np.save(tmp_path / "signed.npy", ramp - 0.5)
    with pytest.raises(InputError, match="signed.npy: .npy input holds negative"):
        read_photo(tmp_path / "signed.npy")


def test_the_decoders_own_lines_are_dropped_and_nothing_else_is(capfd, tmp_path):
    """libpng and libjpeg printed their own lines ("libpng error: ...", "Corrupt JPEG data: ...") beside the
    one line the loader gives for the file."""
    import os

    import cv2
    from shadowflow.nodes.photo.native_messages import decoder_messages_dropped

    png = cv2.imencode(".png", np.random.default_rng(0).integers(0, 255, (64, 64), dtype=np.uint8))[1].tobytes()
    with decoder_messages_dropped():
        assert cv2.imdecode(np.frombuffer(png[:len(png) // 2], np.uint8), cv2.IMREAD_UNCHANGED) is None
        os.write(2, b"another thread's line\n")
    assert capfd.readouterr().err == "another thread's line\n"
    assert cv2.imdecode(np.frombuffer(png[:len(png) // 2], np.uint8), cv2.IMREAD_UNCHANGED) is None
    assert "PNG" in capfd.readouterr().err  # what is dropped, printed without it
    (tmp_path / "cut.png").write_bytes(png[:len(png) // 2])
    with pytest.raises(InputError, match="cut.png: corrupt or truncated PNG data"):
        read_photo(tmp_path / "cut.png")
    assert capfd.readouterr().err == ""


# -- the fourth round (issue 64) ------------------------------------------------------------------


def _traced_peak(fn) -> int:
    """The most bytes Python and numpy held at once while ``fn`` ran (``tracemalloc``)."""
    import tracemalloc

    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize("bits", [10, 12, 14, 16])
def test_a_binary_pgm_with_a_long_header_comment_is_read_on_its_own_scale(tmp_path, bits):
    """A 14-bit binary PGM with a 2,000-byte comment in its header was read at a quarter of its level (the header
    was looked for in its first 1,024 bytes, and OpenCV read the file instead); 10- and 12-bit ones as dark."""
    ramp = np.tile(np.linspace(0, 1, 64), (48, 1))
    top = 2**bits - 1
    path = tmp_path / f"deep{bits}.pgm"
    path.write_bytes(b"P5\n# " + b"a camera's notes " * 120 + b"\n64 48\n# and more\n" + str(top).encode() + b"\n"
                     + np.round(ramp * top).astype(">u2").tobytes())
    np.testing.assert_allclose(read_photo(path).grey, ramp, atol=1e-3)


def test_a_plain_pgm_followed_by_megabytes_of_numbers_is_read_in_bounded_memory(tmp_path):
    """A plain (ASCII) PGM of 100 x 100 followed by 66 MB of numbers took 1.3-1.4 GB (every number in the file was
    split out as an object; a 512 MB file would have taken about 11 GB). Its 10,000 samples are read, the rest
    never split."""
    ramp = np.round(np.tile(np.linspace(0, 255, 100), (100, 1)))
    path = tmp_path / "padded.pgm"
    body = " ".join(str(int(v)) for v in ramp.reshape(-1)).encode()
    path.write_bytes(b"P2\n100 100\n255\n" + body + b"\n" + b"123 45 6 7 " * 4_000_000)
    assert path.stat().st_size > 40_000_000
    photo = []
    peak = _traced_peak(lambda: photo.append(read_photo(path)))
    np.testing.assert_allclose(photo[0].grey, ramp / 255, atol=1e-6)
    assert peak < 150 << 20, peak  # the file's bytes (44 MB) and a few blocks of numbers


def _jpeg_with_mpf(jpeg: bytes) -> bytes:
    """``jpeg`` with the APP2 "MPF" segment of a two-image MPO (as a camera's), right after its start marker:
    Pillow calls such a file an "MPO", not a "JPEG"."""
    import io

    from PIL import Image

    im = Image.fromarray(np.zeros((40, 40), np.uint8))
    buf = io.BytesIO()
    im.save(buf, format="MPO", save_all=True, append_images=[im])
    mpo, i = buf.getvalue(), 2
    while mpo[i + 4:i + 8] != b"MPF\x00":  # walk the segments to the MPF one
        i += 2 + int.from_bytes(mpo[i + 2:i + 4], "big")
    segment = mpo[i:i + 2 + int.from_bytes(mpo[i + 2:i + 4], "big")]
    return jpeg[:2] + segment + jpeg[2:]


def test_a_jpeg_with_an_mpf_segment_is_a_jpeg(tmp_path):
    """A JPEG with an MPF segment (an "MPO", as many cameras write) was not taken for a JPEG: a grey one was read as
    linear, not sRGB, and a progressive one of thousands of scans got past the scan limit (13 s to decode)."""
    import cv2
    from PIL import Image

    from shadowflow.nodes.photo.loader import MAX_JPEG_SCANS

    grey = np.tile(np.linspace(0, 255, 96), (80, 1)).astype(np.uint8)
    ok, buf = cv2.imencode(".jpg", grey, [cv2.IMWRITE_JPEG_QUALITY, 100])
    path = tmp_path / "grey.jpg"
    path.write_bytes(_jpeg_with_mpf(bytes(buf)))
    assert Image.open(path).format == "MPO"
    photo = read_photo(path, encoding="auto")
    assert photo.encoding == "srgb" and photo.grey[40, 48] == pytest.approx(0.214, abs=0.01)  # sRGB 128: 0.216
    rng = np.random.default_rng(0)
    img = cv2.GaussianBlur(rng.integers(0, 255, (480, 640, 3), dtype=np.uint8), (0, 0), 3)
    good = bytes(cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_PROGRESSIVE, 1])[1])
    start, end = _jpeg_scans_cut(good)[-1]
    (tmp_path / "scans.jpg").write_bytes(_jpeg_with_mpf(good[:end] + good[start:end] * 3000 + good[end:]))
    with pytest.raises(InputError, match=rf"scans.jpg: a progressive JPEG of 3010 scans, over the {MAX_JPEG_SCANS}"):
        read_photo(tmp_path / "scans.jpg")


def _tiff_bomb(path, tile: int, rows: int) -> None:
    """A 64 x 64 float64 TIFF whose one segment is ``rows`` rows of zeros ``tile`` wide, deflated (a few hundred kB):
    a tile of ``tile`` x ``rows`` when ``tile`` > 64, else a strip of 64 x 64 whose data inflates to ``rows``."""
    import struct
    import zlib

    import tifffile

    tiled = tile > 64
    tifffile.imwrite(path, np.random.default_rng(0).random((64, 64)), compression="zlib",
                     **({"tile": (64, 64)} if tiled else {"rowsperstrip": 64}))
    data = bytearray(path.read_bytes())
    page = tifffile.TiffFile(path).pages[0]
    z = zlib.compressobj(9)
    blob = b"".join(z.compress(bytes(max(tile, 64) * 8)) for _ in range(rows)) + z.flush()
    fields = (("TileWidth", tile), ("TileLength", rows), ("TileOffsets", len(data)), ("TileByteCounts", len(blob))) \
        if tiled else (("StripOffsets", len(data)), ("StripByteCounts", len(blob)))
    for name, value in fields:
        tag = page.tags[name]
        struct.pack_into({3: "<H", 4: "<I", 16: "<Q"}[tag.dtype], data, tag.valueoffset, value)
    path.write_bytes(bytes(data) + blob)


@pytest.mark.parametrize("tile, rows, says", [(8192, 8192, "one TIFF tile of 67108864 pixels"),
                                              (64, 1 << 20, "inflates past the 32768 bytes")])
def test_a_tiff_whose_tile_or_strip_inflates_far_past_its_image_is_refused(tmp_path, tile, rows, says):
    """A 64 x 64 TIFF whose one tile was 16384^2 float64 took 4.3 GB (8192^2: 1.1 GB): the tile is decoded whole
    before it is cropped. A strip whose deflated data inflates to 512 MiB did the same (tifffile inflates it
    whole, its declared size unused)."""
    path = tmp_path / "bomb.tif"
    _tiff_bomb(path, tile, rows)
    assert path.stat().st_size < 1_000_000

    def refused():
        with pytest.raises(InputError, match=f"bomb.tif: .*{says}"):
            read_photo(path)

    assert _traced_peak(refused) < 40 << 20


def test_a_sidecar_with_a_400_digit_number_is_malformed_and_named(tmp_path):
    """A sidecar whose light or eye held a 400-digit integer failed its frame with ``OverflowError: int too large to
    convert to float``, naming neither the photo nor the sidecar."""
    photo = tmp_path / "face.png"
    photo.write_bytes(b"")
    huge = "9" * 400
    for text in (f'{{"light": [{huge}, 0, 1]}}', f'{{"eyes": [[{huge}, 0], [1, 2]]}}', f'{{"light": [0, -{huge}]}}'):
        (tmp_path / "face.json").write_text(text)
        with pytest.raises(InputError, match=r"face.png: malformed sidecar face.json \(.*\)$"):
            read_sidecar(photo)
