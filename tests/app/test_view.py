"""``view.html``: the photo before and after, its faces marked, each face relit live in the browser.
The live relighting (``render_live``, which the page's script follows) is checked against the
product's own relit files; the page itself in headless Chromium, when the machine has it."""
import base64
import json
import re
import shutil
import subprocess
import zlib

import cv2
import numpy as np
import pytest
from conftest import LAMP, NEW_LIGHT, ROOM, brimmed_face, side_lit_face
from shadowflow.flow.frame import Frame
from shadowflow.nodes.app.cli import main
from shadowflow.nodes.app.view import view_html
from shadowflow.nodes.geometry.reflectance import light_from_angles
from shadowflow.nodes.method.options import MethodOptions
from shadowflow.nodes.relight.live import BEYOND, FACE, render_live
from shadowflow.nodes.relight.nodes import live_face
from shadowflow.nodes.relight.products import relit_photos

LIGHTS = {"frontal": np.array([0.0, 0.0, 1.0]), "30,10": light_from_angles(30, 10),
          "-45,0": light_from_angles(-45, 0)}
# grey levels: the live face against the product's relit photo, mean over the face's inside, the ring around it and
# its own skin past the model (measured at these lights: the astronaut 0.3-2.0, 0.1-0.4 and 0.1-0.3; the side-lit
# render 2.5-3.5 inside, where a third of its shadowed side is painted: the preview tells what to paint at its own
# resolution, and leaves out the colour a lifted pixel takes and what is not skin held over a second scale)
MAX_MEAN_LEVELS = 4.0
# ... and over the face's own skin past the model (the astronaut's jaw, 238 preview pixels), which takes the rim's
# change of light in full: there the live face's one albedo is 0.9-3.6 levels brighter than the product's at the rim
# under a side light (measured: 0.2-2.9 by ``render_live``, 0.4-3.0 in Chromium, whose page draws it the same)
MAX_BEYOND_LEVELS = 4.0


@pytest.fixture(scope="module")
def astronaut_png(tmp_path_factory):
    data = pytest.importorskip("skimage.data")
    path = tmp_path_factory.mktemp("astronaut") / "astronaut.png"
    cv2.imwrite(str(path), data.astronaut()[..., ::-1])
    return path


@pytest.fixture(scope="module")
def side_lit_png(tmp_path_factory):
    """A rendered face lit from 50 degrees to the image's left (linear grey, cast shadows), its eyes and
    light in a sidecar."""
    from shadowflow.nodes.evaluation.scenes import write_shadowed_face

    folder = tmp_path_factory.mktemp("side")
    return write_shadowed_face(folder / "side.png", np.random.default_rng(3), light_from_angles(50), source="ict")


@pytest.fixture(scope="module")
def brimmed_png(tmp_path_factory):
    """A rendered face lit from 20 degrees with a hat's brim's shadow over its brow and eyes (``brimmed_face``)."""
    return brimmed_face(tmp_path_factory.mktemp("brimmed"))[0]


def _product_in_preview(image: np.ndarray, box, size) -> np.ndarray:
    """The product's relit photo (H, W[, C]) seen as a face's preview (h, w, C) is: its box, scaled."""
    y0, y1, x0, x1 = box
    h, w = size
    crop = np.atleast_3d(image)[y0:y1, x0:x1]
    return cv2.resize(crop, (w, h), interpolation=cv2.INTER_AREA).reshape(h, w, -1)


@pytest.mark.parametrize("photo_name", ["astronaut_png", "side_lit_png", "brimmed_png"])
def test_the_live_relighting_is_the_products_inside_the_face(photo_name, request):
    """For the astronaut (colour, lit nearly from the front), a render lit from the side (grey, linear) and a render
    with a brim's shadow relit with ``foreign_shadows`` (the shadow lifted under any light), relit from the front, 30
    deg left and up, and 45 deg right, the live face (``render_live``, its arrays as the page receives them) differs
    from the product's relit photo by under three grey levels on average inside the face, and around it, where the
    face's change of light runs on into the photo over the feather (four on the face's own skin past the model)."""
    import shadowflow

    options = MethodOptions(extra_lights=(LIGHTS["30,10"], LIGHTS["-45,0"]),
                            foreign_shadows=photo_name == "brimmed_png")
    # the brimmed render is a procedural face: the built-in ICT model refuses it (it explains 18 % of its shading)
    model = request.getfixturevalue("procedural_model") if photo_name == "brimmed_png" else None
    photo = shadowflow.fit(request.getfixturevalue(photo_name), options=options, model=model).photo
    face = photo.parts[0]
    live = live_face(face)
    inside = (live.alpha8 == 255) & ((live.flags & FACE) > 0)
    ring = live.fade8 > 0  # around the face, where its change of light runs on into the photo
    beyond = (live.flags & BEYOND) > 0  # the face's own skin past the model: its change of light in full
    assert inside.sum() > 5000 and ring.sum() > 2000
    shown = np.atleast_3d(live.photo8).astype(np.float32) / 255
    moved = 0.0
    for light, product in relit_photos(photo):
        mine = render_live(live, light)
        theirs = _product_in_preview(product, live.box, live.size)
        levels = np.abs(mine - theirs).max(axis=-1)
        assert levels[inside].mean() * 255 < MAX_MEAN_LEVELS, (light, levels[inside].mean() * 255)
        assert levels[ring].mean() * 255 < MAX_MEAN_LEVELS, (light, levels[ring].mean() * 255)
        if beyond.any():
            assert levels[beyond].mean() * 255 < MAX_BEYOND_LEVELS, (light, levels[beyond].mean() * 255)
        moved = max(moved, np.abs(mine - shown).max(axis=-1)[ring].mean() * 255)
    # the ring is not the photo left as it was (which ended the relit face on a cut at its border)
    assert moved > 2.0, moved
    # the lights differ: a live face that ignored the light would pass the above only by chance
    frontal, side = (render_live(live, LIGHTS[k]) for k in ("frontal", "-45,0"))
    assert np.abs(frontal - side).max(axis=-1)[inside].mean() * 255 > 10


def _page_faces(view: str) -> list[dict]:
    """The faces' data embedded in a view.html, with its alpha8 and flags decoded."""
    data = json.loads(re.search(r'<script id=data type=application/json>(.*?)</script>', view, re.S).group(1))
    for f in data["faces"]:
        for name, dtype in (("alpha8", np.uint8), ("flags", np.uint8), ("fade8", np.uint8)):
            raw = zlib.decompress(base64.b64decode(f["arrays"][name]))
            f[name] = np.frombuffer(raw, dtype).reshape(f["h"], f["w"])
    return data["faces"]


def _chromium(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    exe = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")
    if exe is None:
        pytest.skip("no Chromium on this machine (Debian: apt-get install chromium)")
    return subprocess.run([exe, "--headless=new", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                           "--virtual-time-budget=20000", *args], capture_output=True, text=True, timeout=timeout)


@pytest.mark.slow
def test_the_page_relights_each_face_as_the_product_does_in_chromium(astronaut_png, tmp_path):
    """The page opened in headless Chromium at three lights draws the face within three grey levels
    (mean, inside the face and around it; four on its skin past the model) of the product's relit files for those
    lights; its slider shows the
    photo at one end and the relit photo at the other."""
    out = tmp_path / "out"
    assert main(["run", str(astronaut_png), "--out", str(out), "--quiet", "--record", "none",
                 "--relight=30,10", "--relight=-45,0"]) == 0
    view = out / "astronaut" / "view.html"
    face = _page_against_product(view, {"frontal": "relit.png", "30,10": "relit_A+030E+10.png",
                                        "-45,0": "relit_A-045E+00.png"})
    beyond = (face["flags"] & BEYOND) > 0  # the astronaut's jaw past the model: 238 preview pixels
    assert beyond.sum() > 100
    shots = {}
    for cut in (0, 100):
        shot = tmp_path / f"cut{cut}.png"
        _chromium(f"--screenshot={shot}", "--window-size=1000,900", f"{view.as_uri()}#cut={cut}&light=-45,0")
        shots[cut] = cv2.imread(str(shot)).astype(np.int16)
    # the picture starts at the page's left margin below its title; the slider changes what it shows
    changed = np.abs(shots[0] - shots[100]).max(axis=-1) > 24
    assert changed[150:850, 40:960].mean() > 0.02  # the relit face against the photo's
    assert not changed[:80].any()  # the title above the picture stays


def _page_against_product(view, files: dict[str, str]) -> dict:
    """``view`` (a view.html) opened in headless Chromium at each light of ``files`` (name -> the product's relit file
    beside it) draws its first face within ``MAX_MEAN_LEVELS`` (mean, inside the face and around it;
    ``MAX_BEYOND_LEVELS`` on its skin past the model) of that file; the face's page data."""
    face = _page_faces(view.read_text())[0]
    inside = (face["alpha8"] == 255) & ((face["flags"] & FACE) > 0)
    for name, file in files.items():
        proc = _chromium("--dump-dom", f"{view.as_uri()}#light={name if name != 'frontal' else '0,0,1'}&dump")
        dump = re.search(r'<pre id="dump">(.*?)</pre>', proc.stdout, re.S)
        assert dump, proc.stderr[-2000:]
        dumped = json.loads(dump.group(1).replace("&quot;", '"'))[0]
        # the ring is opaque beneath the whole face: where the browser scales the face's canvas, its edge turns
        # half transparent, and the photo showed through as a light seam along the border (docs/view.png)
        assert dumped["ring_under_face"] == 1.0, dumped["ring_under_face"]
        drawn = dumped["png"]
        canvas = cv2.imdecode(np.frombuffer(base64.b64decode(drawn.split(",", 1)[1]), np.uint8), cv2.IMREAD_COLOR)
        product = cv2.imread(str(view.parent / file), cv2.IMREAD_COLOR).astype(np.float32)
        theirs = _product_in_preview(product, face["box"], (face["h"], face["w"]))
        levels = np.abs(canvas.astype(np.float32) - theirs).max(axis=-1)
        assert levels[inside].mean() < MAX_MEAN_LEVELS, (name, levels[inside].mean())
        assert levels[face["fade8"] > 0].mean() < MAX_MEAN_LEVELS, (name, levels[face["fade8"] > 0].mean())
        beyond = (face["flags"] & BEYOND) > 0
        if beyond.any():
            assert levels[beyond].mean() < MAX_BEYOND_LEVELS, (name, levels[beyond].mean())
    return face


@pytest.mark.slow
def test_the_page_lifts_a_brims_shadow_as_the_product_does_in_chromium(brimmed_png, tmp_path):
    """Run with --foreign-shadows, the page draws the brimmed face as the product's files have it under the photo's
    own light (where only the brim's shadow is lifted) and from the front."""
    out = tmp_path / "out"
    assert main(["run", str(brimmed_png), "--out", str(out), "--quiet", "--record", "none", "--model", "procedural",
                 "--foreign-shadows", "--relight=20,0"]) == 0
    _page_against_product(out / "face" / "view.html", {"frontal": "relit.png", "20,0": "relit_A+020E+00.png"})


@pytest.mark.slow
def test_the_page_gives_the_light_it_adds_the_lamps_colour_in_chromium(tmp_path):
    """A face lit by a warm lamp in a blue room (``conftest.side_lit_face``): the page opened in headless Chromium
    relights it toward the side turned from the lamp and from the front within one grey level (mean, inside the face)
    of ``render_live``, which gives the light it adds the lamp's colour (measured 0.4; the page without the colour,
    3.9 and 4.5)."""
    scene = side_lit_face(LAMP, ROOM)
    live = scene.face.live_data()
    assert live.tint is not None
    frame = Frame(0, "blue_room.png", data={"rgb8": np.round(scene.photo * 255).astype(np.uint8)},
                  meta={"stem": "blue_room", "encoding": "linear"})
    view = tmp_path / "view.html"
    view.write_bytes(view_html(frame, [({"status": "ok", "box": list(live.box)}, live)]))
    inside = (live.alpha8 == 255) & ((live.flags & FACE) > 0)
    for name, light in (("40,0", NEW_LIGHT), ("0,0,1", np.array([0.0, 0.0, 1.0]))):
        proc = _chromium("--dump-dom", f"{view.as_uri()}#light={name}&dump")
        dump = re.search(r'<pre id="dump">(.*?)</pre>', proc.stdout, re.S)
        assert dump, proc.stderr[-2000:]
        drawn = json.loads(dump.group(1).replace("&quot;", '"'))[0]["png"]
        canvas = cv2.imdecode(np.frombuffer(base64.b64decode(drawn.split(",", 1)[1]), np.uint8), cv2.IMREAD_COLOR)
        levels = np.abs(canvas[..., ::-1].astype(np.float32) - 255 * render_live(live, light)).max(axis=-1)
        assert levels[inside].mean() < 1.0, (name, levels[inside].mean())


def test_the_live_blur_is_a_gaussian_of_its_width():
    """``gaussian_blur`` (three boxes, as the page's running sums): a point spreads with the asked sigma (to
    half a pixel: the boxes are whole pixels wide), its weight kept; a constant stays constant away from
    the edges, beyond which is zero."""
    from shadowflow.nodes.relight.live import gaussian_blur

    point = np.zeros((101, 101), np.float32)
    point[50, 50] = 1.0
    for sigma in (2.0, 6.0, 12.0):
        out = gaussian_blur(point, sigma)
        assert out.sum() == pytest.approx(1.0, abs=1e-5)
        rows = np.arange(101) - 50
        spread = np.sqrt(np.sum(out.sum(axis=1) * rows**2))
        assert abs(spread - sigma) < 0.5, (sigma, spread)  # the box widths are whole pixels
    flat = gaussian_blur(np.ones((60, 80, 3), np.float32), 4.0)
    np.testing.assert_allclose(flat[20:40, 20:60], 1.0, atol=1e-6)
    assert flat[0, 0, 0] < 0.5  # zero beyond the edges
