"""Docstrings are contracts; the history and the results live in docs/engines/."""

import ast
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
MOST_LINES = 40


def test_no_module_docstring_in_the_engines_is_a_lab_notebook():
    long = {}
    for path in sorted((REPO / "engines").rglob("*.py")):
        doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8")), clean=False) or ""
        if len(doc.splitlines()) > MOST_LINES:
            long[str(path.relative_to(REPO))] = len(doc.splitlines())
    assert not long, f"module docstrings over {MOST_LINES} lines (move the history to docs/engines/): {long}"


def test_each_engine_page_gives_the_commands_of_its_tables():
    pages = sorted((REPO / "docs" / "engines").glob("*.md"))
    assert {p.stem for p in pages} >= {"cae", "mssa", "kalman"}
    for page in pages:
        text = page.read_text(encoding="utf-8")
        assert "```bash" in text and "workbench " in text, page.name
