"""The distribution installs one import name, ``shadowflow``, mapped from the repository's folders."""
import re
import tomllib
from pathlib import Path

import shadowflow

REPO = Path(__file__).resolve().parents[2]


def test_every_package_folder_is_installed_under_shadowflow_and_nothing_else():
    """pyproject lists the packages by hand (the root is mapped to ``shadowflow``): a new folder
    that is not listed would be missing from a wheel, so the list must match the tree."""
    tool = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert tool["package-dir"] == {"shadowflow": "."}
    listed = set(tool["packages"])
    on_disk = {"shadowflow"} | {"shadowflow." + ".".join(p.parent.relative_to(REPO).parts)
                                for top in ("flow", "nodes") for p in (REPO / top).rglob("__init__.py")}
    assert listed == on_disk
    assert all(name == "shadowflow" or name.startswith("shadowflow.") for name in listed)


def test_no_module_imports_the_folders_by_their_bare_names():
    """``import flow`` or ``from nodes...`` works from a checkout but not once installed: inside
    the package every import is relative."""
    bare = re.compile(r"^\s*(from|import)\s+(flow|nodes)\b", re.M)
    offenders = [str(p.relative_to(REPO)) for top in ("flow", "nodes") for p in (REPO / top).rglob("*.py")
                 if bare.search(p.read_text())]
    assert offenders == []


def test_the_api_is_at_the_top():
    assert {"fit", "run", "Products", "MethodOptions", "FitConfig"} <= set(shadowflow.__all__)
    assert callable(shadowflow.fit) and callable(shadowflow.run)
