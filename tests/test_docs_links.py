"""The documentation holds together: every relative link and image in README.md and
docs/*.md resolves (a link with an #anchor into a markdown page, to a heading there, by
GitHub's anchor rules), every module path it names in backquotes exists, every docs page is
linked from the README, and the README stays a front page that begins with the two
commands, the second of which CI runs."""

from __future__ import annotations

import re
from collections import Counter
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
PAGES = [README, *sorted((ROOT / "docs").glob("*.md"))]
#: Where a backquoted module path may live.
CODE_ROOTS = (ROOT, ROOT / "src" / "actionreasoning")
#: The README's limit, in lines.
FRONT_PAGE_LINES = 300

FENCE = re.compile(r"^(`{3,}|~{3,}).*?^\1[ \t]*$", re.MULTILINE | re.DOTALL)
CODE_SPAN = re.compile(r"`[^`]*`")
#: [text](target) and ![alt](target), with an optional "title".
INLINE_LINK = re.compile(r"!?\[(?:[^\]\\]|\\.)*\]\(\s*<?([^\s)>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
REFERENCE_DEFINITION = re.compile(r"^\s{0,3}\[[^\]]+\]:\s*<?(\S+?)>?(?:\s.*)?$", re.MULTILINE)
HTML_SOURCE = re.compile(r"<(?:img|a)\b[^>]*\b(?:src|href)=\"([^\"]+)\"", re.IGNORECASE)
HEADING = re.compile(r"^ {0,3}#{1,6}[ \t]+(.*?)[ \t#]*$", re.MULTILINE)
#: A backquoted path to a source file: a Python module, a prompt or an asset.
MODULE_PATH = re.compile(r"`(\w[\w.-]*(?:/[\w.-]+)+\.(?:py|yaml|yml|j2|xml))`")


def without_code(text: str) -> str:
    """``text`` without its fenced code blocks and code spans, where nothing is a link."""
    return CODE_SPAN.sub("", FENCE.sub("", text))


def slug(heading: str) -> str:
    """GitHub's anchor for a heading: its text as rendered, lower case, without punctuation
    but hyphens and underscores, spaces as hyphens."""
    text = re.sub(r"`([^`]*)`", r"\1", heading)
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", text)
    text = re.sub(r"[^\w\- ]", "", text.strip().lower())
    return text.replace(" ", "-")


def anchors(page: Path) -> set[str]:
    """The anchors of ``page``'s headings; a repeated one gets -1, -2, ... as on GitHub."""
    seen: Counter[str] = Counter()
    found = set()
    for heading in HEADING.findall(FENCE.sub("", page.read_text())):
        base = slug(heading)
        found.add(f"{base}-{seen[base]}" if seen[base] else base)
        seen[base] += 1
    return found


def targets(page: Path) -> list[str]:
    """Every link and image target of ``page``, outside code."""
    text = without_code(page.read_text())
    return [
        target
        for pattern in (INLINE_LINK, REFERENCE_DEFINITION, HTML_SOURCE)
        for target in pattern.findall(text)
    ]


def broken_links(page: Path, root: Path = ROOT) -> list[str]:
    """The relative links and images of ``page`` that do not resolve, each with why: the
    file is missing or outside ``root``, or the heading an anchor names is not on its page."""
    broken = []
    for target in targets(page):
        if re.match(r"[a-z][a-z0-9+.-]*:", target, re.IGNORECASE):  # http:, mailto:, ...
            continue
        path, _, anchor = target.partition("#")
        file = (page.parent / path).resolve() if path else page
        if not file.is_relative_to(root.resolve()):
            broken.append(f"{target}: outside the repository")
        elif not file.exists():
            broken.append(f"{target}: no such file")
        elif anchor and file.suffix == ".md" and anchor not in anchors(file):
            broken.append(f"{target}: no heading #{anchor} in {file.name}")
    return broken


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_every_link_and_image_resolves(page: Path) -> None:
    assert broken_links(page) == []


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_every_module_path_named_exists(page: Path) -> None:
    named = MODULE_PATH.findall(FENCE.sub("", page.read_text()))
    missing = [p for p in named if not any((base / p).exists() for base in CODE_ROOTS)]
    assert missing == []


def test_the_check_finds_each_kind_of_broken_link(tmp_path: Path) -> None:
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "shot.png").write_bytes(b"")
    (tmp_path / "other.md").write_text("# Other page\n\n## The `run.json` file: fields\n")
    page = tmp_path / "docs" / "page.md"
    page.write_text(
        "# Page\n\n## Twice\n\n## Twice\n\n"
        "![fine](shot.png) [fine](../other.md#the-runjson-file-fields) [fine](#twice-1)\n"
        "[fine](https://example.org/missing) `[in code](missing.md)`\n"
        "```\n[in a block](missing.md)\n```\n"
        "![gone](docs/shot.png) [gone](missing.md) [wrong anchor](../other.md#other)\n"
        "[no such heading](#twice-2) [out](../../elsewhere.md)\n"
    )
    assert broken_links(page, root=tmp_path) == [
        "docs/shot.png: no such file",
        "missing.md: no such file",
        "../other.md#other: no heading #other in other.md",
        "#twice-2: no heading #twice-2 in page.md",
        "../../elsewhere.md: outside the repository",
    ]


def test_every_docs_page_is_linked_from_the_readme() -> None:
    linked = {(README.parent / t.partition("#")[0]).resolve() for t in targets(README)}
    assert [p.name for p in PAGES[1:] if p.resolve() not in linked] == []


@pytest.mark.parametrize("page", PAGES[1:], ids=lambda p: p.name)
def test_a_docs_page_opens_with_its_title_and_a_one_line_summary(page: Path) -> None:
    title, blank, summary, after = page.read_text().splitlines()[:4]
    assert title.startswith("# ") and blank == after == ""
    assert summary and not summary.startswith(("#", "*", "-", "|", "```"))


def test_the_readme_is_a_front_page_that_begins_with_the_two_commands() -> None:
    lines = README.read_text().splitlines()
    assert len(lines) <= FRONT_PAGE_LINES
    assert lines[:3] == ["# actionreasoning", "", "```bash"] and lines[5] == "```"
    demo, tests = lines[3:5]
    assert demo.endswith(".venv/bin/actionreasoning demo --out demo")
    assert tests.endswith(".venv/bin/python -m pytest")
    # CI runs the README's test command word for word.
    assert tests in (ROOT / ".ci" / "run").read_text().splitlines()
