"""Make the golden recordings the tests diff against (run from the repository root):

    python recordings/make_golden.py            # rewrites recordings/golden-64.mcap

Everything comes from the project's own code: a 64x64 model trained on 30 procedural faces
(seed 0, 12 modes), two held-out procedural faces (seed 77) lit from 45 degrees left and 60
degrees right, 6 fit iterations (stopping rule 0.05 degrees), MCAP only. ``golden_inputs`` and ``golden_run`` are shared
with ``tests/app/test_recordings.py`` so the test re-runs exactly this.
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
GOLDEN = HERE / "golden-64.mcap"
GRID = (64, 64)


def golden_model():
    from shadowflow.nodes.model.shape_model import train_shape_model
    from shadowflow.nodes.model.sources import procedural

    depths, _ = procedural(30, seed=0, grid=GRID)
    return train_shape_model(depths, 12, source="golden")


def golden_inputs(folder: Path) -> list[str]:
    from shadowflow.nodes.evaluation.scenes import write_shadowed_face
    from shadowflow.nodes.geometry.reflectance import light_from_angles

    rng = np.random.default_rng(77)
    return [str(write_shadowed_face(folder / f"golden-{i}.png", rng, light_from_angles(az), GRID))
            for i, az in enumerate((45, -60))]


def golden_run(out: Path, fit_workers: int = 1) -> Path:
    """Run the golden inputs into ``out``; returns the MCAP recording's path."""
    from shadowflow.nodes.app.runner import RunOptions, run_stream
    from shadowflow.nodes.method.options import MethodOptions
    from shadowflow.nodes.method.robust_fit import FitConfig

    inputs = out / "inputs"
    inputs.mkdir(parents=True, exist_ok=True)
    paths = golden_inputs(inputs)
    # its own stopping rule, so the recordings it is diffed against (and an older release's) stay the
    # golden run whatever the default becomes: six iterations, the albedo round after a change under 0.05
    options = MethodOptions(fit=FitConfig(max_iterations=6, tolerance_deg=0.05))
    run_stream(paths, out / "result", golden_model(), options,
               RunOptions(record=("mcap",), fit_workers=fit_workers, quiet=True))
    return out / "result" / "run.mcap"


if __name__ == "__main__":
    sys.path.insert(0, str(HERE.parent))
    with tempfile.TemporaryDirectory() as tmp:
        rec = golden_run(Path(tmp))
        GOLDEN.write_bytes(rec.read_bytes())
    print(f"wrote {GOLDEN} ({GOLDEN.stat().st_size} bytes)")
