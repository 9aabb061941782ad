"""The README and the docs: every relative link and anchor resolves inside the repository."""
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ["README.md", "CONTRIBUTING.md", "LICENSES/README.md", "recordings/README.md",
        *sorted(str(p.relative_to(ROOT)) for p in (ROOT / "docs").glob("*.md"))]


def _anchors(text: str) -> set[str]:
    """GitHub's heading anchors: lower case, punctuation dropped, spaces to hyphens."""
    return {re.sub(r"[^\w\- ]", "", h.strip().lower()).replace(" ", "-") for h in re.findall(r"^#+ (.+)$", text, re.M)}


@pytest.mark.parametrize("doc", DOCS)
def test_every_link_resolves(doc):
    text = (ROOT / doc).read_text()
    links = re.findall(r"\]\(([^)\s]+)\)", text)
    assert links or doc != "README.md"
    broken = []
    for target in links:
        if target.startswith(("http://", "https://", "mailto:")):
            continue
        path, _, anchor = target.partition("#")
        file = (ROOT / doc).parent / path if path else ROOT / doc
        if not file.exists() or not file.resolve().is_relative_to(ROOT):
            broken.append(target)
        elif anchor and file.suffix == ".md" and anchor not in _anchors(file.read_text()):
            broken.append(target)
    assert broken == []


def test_the_readme_is_a_page_and_opens_with_a_real_photo():
    """About 200 lines (at most 250), its first figure the astronaut's, and that figure made by
    docs/make_figures.py."""
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 250
    figures = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text)
    assert figures[0] == "docs/astronaut.png"
    made = (ROOT / "docs" / "make_figures.py").read_text()
    assert all(Path(f).name in made for f in figures if f.startswith("docs/") and "viewer" not in f)


def test_the_readme_commands_name_options_the_command_line_has():
    """Every ``shadowflow <command> --option`` in the README is one the parser knows."""
    from shadowflow.nodes.app.cli import build_parser

    blocks = "\n".join(re.findall(r"```sh\n(.*?)```", (ROOT / "README.md").read_text(), re.S))
    parser = build_parser()
    subparsers = next(a for a in parser._actions if a.dest == "command").choices
    for line in re.findall(r"shadowflow (\w+) (.*)$", blocks, re.M):
        command, rest = line
        assert command in subparsers, command
        known = {opt for a in subparsers[command]._actions for opt in a.option_strings}
        for opt in re.findall(r"(--[a-z][a-z-]*)", rest):
            assert opt in known, (command, opt)


def test_every_repository_path_the_code_and_docs_name_exists():
    """A path like ``nodes/method/light.py`` or ``docs/tuning.md`` named in a docstring, comment or doc is a
    file of the repository (tests are named from tests/, modules also from nodes/); a stale one fails here."""
    named = re.compile(r"\b((?:flow|nodes|tests|benchmarks|docs|recordings|app|method|photo|model|geometry|"
                       r"evaluation)/[\w/]+\.(?:py|md))\b")
    sources = [p for top in ("flow", "nodes", "tests", "benchmarks", "recordings") for p in (ROOT / top).rglob("*.py")]
    sources += [ROOT / d for d in DOCS]
    missing = set()
    for source in sources:
        for path in named.findall(source.read_text()):
            if not any((base / path).exists() for base in (ROOT, ROOT / "tests", ROOT / "nodes")):
                missing.add(f"{source.relative_to(ROOT)}: {path}")
    # a removed module the accuracy notes name as removed
    assert sorted(m for m in missing if "mouth.py" not in m) == []
