"""The documentation's code examples run, and print what the pages say they print.

Every ```` ```python ```` block of ``README.md`` and ``docs/**/*.md`` is executed, page by
page, in one namespace per page (blocks in page order), from the repository root. A
```` ```text ```` block that follows a Python block (before the next Python block) is the
output that block prints: compared line by line, exactly. A page whose blocks fail, or print
something else, fails here, so the docs cannot go stale.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = sorted([ROOT / "README.md", *(ROOT / "docs").rglob("*.md")])
FENCE = re.compile(r"^```([a-z]*)[^\n]*\n(.*?)^```\s*$", re.S | re.M)
#: The README's length limit [lines]: what it is, the two commands, a figure, links.
README_LINES = 200


def examples(page: Path) -> list[tuple[str, str | None]]:
    """The page's Python blocks, each with the text block that shows its output (or None)."""
    out: list[tuple[str, str | None]] = []
    for lang, body in FENCE.findall(page.read_text()):
        if lang == "python":
            out.append((body, None))
        elif lang == "text" and out and out[-1][1] is None:
            out[-1] = (out[-1][0], body)
    return out


def test_the_fence_reader_pairs_code_and_output(tmp_path):
    page = tmp_path / "p.md"
    page.write_text(
        "a\n```python\nprint(1)\n```\nprints\n```text\n1\n```\n```bash\nls\n```\n"
        "```python\nx = 2\n```\n```python\nprint(x)\n```\n"
    )
    assert examples(page) == [("print(1)\n", "1\n"), ("x = 2\n", None), ("print(x)\n", None)]


@pytest.mark.parametrize(
    "page",
    [p for p in PAGES if examples(p)],
    ids=lambda p: str(p.relative_to(ROOT)),
)
def test_page_examples_run_and_print_what_the_page_says(page, tmp_path, monkeypatch):
    monkeypatch.chdir(ROOT)
    monkeypatch.setenv("SCDK_DOCS_TMP", str(tmp_path))
    namespace: dict = {"__name__": "__docs__"}
    for i, (code, expected) in enumerate(examples(page)):
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            exec(compile(code, f"{page.name}[{i}]", "exec"), namespace)  # noqa: S102
        if expected is not None:
            assert buf.getvalue().rstrip("\n").split("\n") == expected.rstrip("\n").split("\n"), (
                f"{page.name} block {i} printed:\n{buf.getvalue()}"
            )


def test_readme_is_short_and_links_pages_that_exist():
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= README_LINES
    links = re.findall(r"\]\((docs/[^)#]+)", text)
    assert links, "the README links the documentation"
    for link in links:
        assert (ROOT / link).exists(), link
    assert os.path.exists(ROOT / "mkdocs.yml")
