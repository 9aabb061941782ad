"""The frame contract (``nodes/method/keys.py``): every entry a node writes is in the table, under
that node's name, and the two ways in (a photo through ``LoadNode`` and ``FacesNode``, an image
already on the model grid through ``on_model_grid``) give the method the same entries."""
import numpy as np
from shadowflow.flow.frame import Frame
from shadowflow.nodes.evaluation.scenes import render_scene, write_shadowed_face
from shadowflow.nodes.geometry.reflectance import light_from_angles
from shadowflow.nodes.method import keys
from shadowflow.nodes.method.nodes import FacesNode, LoadNode, on_model_grid
from shadowflow.nodes.method.options import MethodOptions
from shadowflow.nodes.relight.nodes import face_nodes
from shadowflow.nodes.model.sources import procedural


def _run_node_by_node(frame, nodes):
    """Call each node in turn; returns {node name: entries it added to data / meta}."""
    added = {}
    for node in nodes:
        data, meta = set(frame.data), set(frame.meta)
        frame = node(frame)
        added[node.name] = (set(frame.data) - data, set(frame.meta) - meta)
    return frame, added


def _check(added):
    for name, (data, meta) in added.items():
        for key in data:
            assert key in keys.DATA, f"{name} writes data[{key!r}], missing from keys.DATA"
            assert name in keys.DATA[key][1], f"keys.DATA[{key!r}] does not name {name} as its writer"
        for key in meta:
            assert key in keys.META, f"{name} writes meta[{key!r}], missing from keys.META"
            assert name in keys.META[key][1], f"keys.META[{key!r}] does not name {name} as its writer"


def test_every_entry_a_node_writes_is_in_the_table(tmp_path, procedural_model):
    model = procedural_model
    options = MethodOptions()  # cone trust 0.5: both normals entries
    photo = write_shadowed_face(tmp_path / "face.png", np.random.default_rng(3), light_from_angles(40))
    photo_frame, added = _run_node_by_node(Frame(0, str(photo)), [LoadNode(options), FacesNode(model, options)])
    _check(added)
    assert len(photo_frame.parts) == 1
    frame, added = _run_node_by_node(photo_frame.parts[0], face_nodes(options))
    _check(added)
    assert {"image", "grid_valid", "saturated", "shading_normals", "relit", "photo_layers"} <= set(frame.data)

    depth, _ = procedural(1, seed=5)
    s = light_from_angles(40)
    scene = render_scene(depth[0], 1.0, s, model.mask)
    grid_frame, grid_added = _run_node_by_node(on_model_grid(1, "render", scene.image, s, model), face_nodes(options))
    _check(grid_added)
    # the render's way in gives the method every entry the photo's does, bar the photo's bounds, what covers the
    # face in it and its placement
    assert set(frame.data) - set(grid_frame.data) == {"grid_valid", "grid_covered", "eyes_found", "placement"}


def _frame_keys_in_code(path):
    """{("data" | "meta", key)} of every string key the code at ``path`` reads or writes on a frame: on
    ``<x>.data`` / ``<x>.meta`` directly, and on a local name bound to one (``d = frame.data``)."""
    import ast

    tree = ast.parse(path.read_text())

    def which(node, aliases):
        if isinstance(node, ast.Attribute) and node.attr in ("data", "meta"):
            return node.attr
        if isinstance(node, ast.Name):
            return aliases.get(node.id)
        return None

    found = set()
    for fn in ast.walk(tree):
        if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        aliases = {}
        for node in ast.walk(fn):
            if isinstance(node, ast.Assign):
                pairs = [(node.targets[0], node.value)]
                if isinstance(node.targets[0], ast.Tuple) and isinstance(node.value, ast.Tuple):
                    pairs = list(zip(node.targets[0].elts, node.value.elts))
                for target, value in pairs:
                    if isinstance(target, ast.Name) and isinstance(value, ast.Attribute) and value.attr in ("data", "meta"):
                        aliases[target.id] = value.attr
        for node in ast.walk(fn):
            if isinstance(node, ast.Subscript) and isinstance(node.slice, ast.Constant) and \
                    isinstance(node.slice.value, str) and (kind := which(node.value, aliases)):
                found.add((kind, node.slice.value))
            elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and \
                    (kind := which(node.func.value, aliases)):
                if node.func.attr in ("get", "setdefault", "pop") and node.args and \
                        isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str):
                    found.add((kind, node.args[0].value))
                elif node.func.attr == "update":
                    found.update((kind, kw.arg) for kw in node.keywords if kw.arg)
    return found


def test_every_frame_key_the_code_names_is_in_the_table():
    """A key is followed from the table to the code and back: no node, writer or reader uses a frame
    entry the table does not list (a typo in a bare string would otherwise read as absent)."""
    from pathlib import Path

    root = Path(keys.__file__).resolve().parents[1]
    unknown = set()
    for path in sorted(root.rglob("*.py")):
        for kind, key in _frame_keys_in_code(path):
            table = keys.DATA if kind == "data" else keys.META
            if key not in table:
                unknown.add(f"{path.relative_to(root)}: {kind}[{key!r}]")
    assert not unknown, sorted(unknown)
