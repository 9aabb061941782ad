"""Shared fixtures. Evaluation data from ../shared is used only when present."""
from __future__ import annotations

import os
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from shadowflow.nodes.geometry.reflectance import light_from_angles

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("SHADOWFLOW_SHARED", REPO.parent / "shared"))
SFM_MODEL = SHARED / "data" / "sfm" / "sfm_shape_3448.bin"


@pytest.fixture(autouse=True, scope="session")
def _private_cache(tmp_path_factory, pytestconfig):
    """Keep the default-model cache of the test run away from the user's: in pytest's own cache folder
    (``.pytest_cache``, so a second run does not build the model again: 14 s), else a fresh folder. The
    built-in models are deterministic and a damaged entry is rebuilt, so sharing it between runs and
    between ``-n`` workers is safe."""
    old = os.environ.get("SHADOWFLOW_CACHE")
    cache = getattr(pytestconfig, "cache", None)
    folder = cache.mkdir("shadowflow-models") if cache is not None else tmp_path_factory.mktemp("cache")
    os.environ["SHADOWFLOW_CACHE"] = str(folder)
    yield
    if old is None:
        os.environ.pop("SHADOWFLOW_CACHE", None)
    else:
        os.environ["SHADOWFLOW_CACHE"] = old


@pytest.fixture(scope="session")
def sfm_path() -> Path:
    if not SFM_MODEL.exists():
        pytest.skip(f"evaluation data absent: {SFM_MODEL} (needs ../shared beside the repo)")
    pytest.importorskip("eos", reason="eos-py not installed (pip install 'shadowflow[eos]')")
    return SFM_MODEL


@pytest.fixture(scope="session")
def procedural_model():
    """A model trained on 100 procedural faces (seed 0), as in the accuracy criteria."""
    from shadowflow.nodes.model.shape_model import train_shape_model
    from shadowflow.nodes.model.sources import procedural

    depths, _ = procedural(100, seed=0)
    return train_shape_model(depths, 60, source="procedural")


def brimmed_face(folder: Path) -> tuple[Path, np.ndarray]:
    """A rendered face (its eyes 72 px apart) lit from 20 degrees, a hat's brim's shadow laid over its brow and eyes
    (0.35 of the light left, a penumbra of 2 px), written as ``folder/face.png`` (a linear grey file) with its
    sidecar; and the shadow (H, W) in [0, 1]."""
    import json

    import cv2
    from shadowflow.nodes.evaluation.occluders import brim, lay_shadow
    from shadowflow.nodes.evaluation.scenes import write_shadowed_face
    from shadowflow.nodes.geometry.reflectance import light_from_angles

    photo = write_shadowed_face(folder / "face.png", np.random.default_rng(4), light_from_angles(20), grid=(256, 256))
    eyes = np.asarray(json.loads(photo.with_suffix(".json").read_text())["eyes"], np.float64)
    image = cv2.imread(str(photo), cv2.IMREAD_GRAYSCALE).astype(np.float32) / 255.0
    blocked = brim(image.shape, eyes, np.random.default_rng(1))
    cv2.imwrite(str(photo), np.round(np.clip(lay_shadow(image, blocked, 0.35, 2.0), 0, 1) * 255).astype(np.uint8))
    return photo, cv2.GaussianBlur(blocked, (0, 0), 2.0)


# ``side_lit_face``: the rendered face's grid, its corner in the photo, the photo's size, its skin, the room's share
GRID = (128, 128)
TOP, LEFT = 40, 50  # the model grid's corner in the photo
FRAME = (210, 230)
SKIN = np.array([0.75, 0.55, 0.42], np.float32)
AMBIENT = 0.2
PHOTO_LIGHT = light_from_angles(-40.0)  # from the image's right
NEW_LIGHT = light_from_angles(40.0)  # from its left
# a warm lamp in a room lit blue (a sunlit face's shade under the sky), linear RGB
LAMP, ROOM = (1.1, 1.0, 0.85), (0.75, 0.95, 1.3)


def side_lit_face(direct_colour=(1.0, 1.0, 1.0), room_colour=(1.0, 1.0, 1.0)) -> SimpleNamespace:
    """An ICT-FaceKit identity, skin-coloured, lit from ``PHOTO_LIGHT`` by a lamp of ``direct_colour`` with a room's
    light (``AMBIENT``) of ``room_colour`` (RGB, linear), its cast and attached shadows traced, in a coloured frame (a
    linear 8-bit file); its ``FaceRelight`` with the fit taken as exact (the render's normals, depth and shadows), and
    its truth under ``NEW_LIGHT``."""
    from shadowflow.nodes.evaluation.scenes import draw_face
    from shadowflow.nodes.geometry.integrate import fill_holes
    from shadowflow.nodes.geometry.normals import normals_from_depth
    from shadowflow.nodes.method.shadow import shadow_maps
    from shadowflow.nodes.model.canonical import canonical_eyes
    from shadowflow.nodes.photo.align import Alignment
    from shadowflow.nodes.relight.face import FaceRelight

    depth, mask, _ = draw_face(np.random.default_rng(3), GRID, "ict")
    depth = fill_holes(depth, mask)
    normals = normals_from_depth(depth)
    lamp, room = np.asarray(direct_colour, np.float32), np.asarray(room_colour, np.float32)

    def render(light):
        """(H, W, 3) the face under ``light`` with the room's light, in the frame (as a linear 8-bit file holds it);
        its shadows (``ShadowMaps``) on the grid."""
        shadows = shadow_maps(depth, normals, light)
        direct = np.clip(np.nan_to_num(normals) @ light, 0.0, None) * shadows.lit
        yy, xx = np.mgrid[0:FRAME[0], 0:FRAME[1]] / 200.0
        image = np.dstack([0.2 + 0.2 * xx, 0.3 - 0.1 * yy, np.full_like(xx, 0.25)])
        region = image[TOP:TOP + GRID[0], LEFT:LEFT + GRID[1]]
        region[mask] = SKIN * (AMBIENT * room + (1 - AMBIENT) * direct[mask][:, None] * lamp)
        return (np.round(np.clip(image, 0.0, 1.0) * 255) / 255).astype(np.float32), shadows

    photo, shadows = render(PHOTO_LIGHT)
    truth, new_shadows = render(NEW_LIGHT)
    new_cast = np.zeros(FRAME, bool)  # where the new light's cast shadow (the nose's) falls, in the photo
    new_cast[TOP:TOP + GRID[0], LEFT:LEFT + GRID[1]] = new_shadows.cast
    eyes = canonical_eyes(GRID)
    face = FaceRelight(photo=photo, alignment=Alignment(np.array([[1.0, 0, LEFT], [0, 1.0, TOP]]), "test"),
                       mask=mask, normals=normals, lit=shadows.lit, albedo=np.where(mask, 0.6, np.nan), depth=depth,
                       light=PHOTO_LIGHT, iod_px=float(eyes[1, 0] - eyes[0, 0]))
    return SimpleNamespace(face=face, photo=photo, truth=truth, new_cast=new_cast, eyes=eyes + [LEFT, TOP],
                           normals=normals, lit=shadows.lit)


def random_unit(n: int, rng: np.random.Generator, min_z: float = 0.05) -> np.ndarray:
    v = rng.standard_normal((n, 3))
    v[:, 2] = np.abs(v[:, 2]) + min_z
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def rrd_rows(path: Path, entity: str, component: str) -> dict[int, object]:
    """iteration -> the component's value in that row, for one entity of an .rrd file."""
    rc = pytest.importorskip("rerun.chunk")
    rows = {}
    for chunk in rc.RrdReader(path).store().stream():
        if chunk.entity_path != entity:
            continue
        rb = chunk.to_record_batch()
        if component in rb.schema.names and "iteration" in rb.schema.names:
            for it, value in zip(rb.column("iteration").to_pylist(), rb.column(component).to_pylist()):
                rows[int(it)] = value
    return rows


@pytest.fixture
def shadowed_faces():
    """``make(folder, count, seed)``: ``count`` rendered faces (a 45-degree light) with sidecars in a new
    ``folder``; returns the folder."""
    from shadowflow.nodes.evaluation.scenes import write_shadowed_face
    from shadowflow.nodes.geometry.reflectance import light_from_angles

    def make(folder: Path, count: int, seed: int) -> Path:
        folder.mkdir()
        rng = np.random.default_rng(seed)
        for i in range(count):
            write_shadowed_face(folder / f"f{i}.png", rng, light_from_angles(45, 0))
        return folder

    return make


@pytest.fixture
def unprivileged() -> list[str]:
    """A command prefix that makes file permissions bind even for root (CI runs as root)."""
    import shutil

    if os.geteuid() != 0:
        return []
    setpriv = shutil.which("setpriv")
    if setpriv is None:
        pytest.skip("running as root without setpriv: file permissions cannot be tested")
    return [setpriv, "--bounding-set", "-dac_override,-dac_read_search"]



def run_cli(args: list[str]):
    """``shadowflow ARGS`` run in this process (no interpreter start, no imports again): a
    ``subprocess.CompletedProcess`` with its exit status and what it printed. For commands that are not
    killed or signalled; those run as processes of their own."""
    import contextlib
    import io
    import subprocess

    from shadowflow.nodes.app.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in args])
    return subprocess.CompletedProcess(["shadowflow", *map(str, args)], code, out.getvalue(), err.getvalue())


@pytest.fixture
def cli():
    """``run_cli``: the command line in this process."""
    return run_cli
