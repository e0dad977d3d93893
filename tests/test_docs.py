"""The documentation holds together: links resolve, the README stays short, every program
and every docs page can be found.

Checked on README.md, docs/*.md and bench/README.md:

- every relative link (``[text](path)``, ``[text](path#anchor)``, ``[text](#anchor)``, images
  too) names a file or folder that exists, and its anchor matches a heading of the target,
  slugged as GitHub does (lower case, punctuation other than ``-`` and ``_`` dropped, spaces to
  ``-``, repeated headings numbered ``-1``, ``-2``, ...);
- README.md is at most 200 lines;
- every console script of pyproject.toml has a heading in docs/cli.md;
- every docs/*.md is linked from README.md.

Links inside fenced code blocks and inline code are not links and are not checked.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
README = ROOT / "README.md"
README_MAX_LINES = 200


def _doc_files() -> list[Path]:
    return [README, *sorted(DOCS.glob("*.md")), ROOT / "bench" / "README.md"]


_FENCE = re.compile(r"^\s*(```|~~~)")
_INLINE_CODE = re.compile(r"(`+)(.+?)\1")
_LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\[\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
_HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")


def _prose_lines(text: str) -> list[tuple[int, str]]:
    """(line number, line) outside fenced code blocks."""
    out, fenced = [], False
    for number, line in enumerate(text.splitlines(), 1):
        if _FENCE.match(line):
            fenced = not fenced
            continue
        if not fenced:
            out.append((number, line))
    return out


def github_slug(heading: str) -> str:
    """The anchor GitHub gives a heading's text (before numbering repeats)."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading)  # a link: its text
    text = text.replace("`", "")
    text = re.sub(r"<[^>]+>", "", text)  # inline HTML tags
    text = text.strip().lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(path: Path) -> set[str]:
    """Every anchor of a Markdown file's headings, repeats numbered as GitHub does."""
    seen: dict[str, int] = {}
    out = set()
    for _, line in _prose_lines(path.read_text(encoding="utf-8")):
        m = _HEADING.match(line)
        if not m:
            continue
        slug = github_slug(m.group(2))
        if slug in seen:
            seen[slug] += 1
            out.add(f"{slug}-{seen[slug]}")
        else:
            seen[slug] = 0
            out.add(slug)
    return out


def links(path: Path) -> list[tuple[int, str]]:
    """(line number, target) of every link in a Markdown file's prose."""
    out = []
    for number, line in _prose_lines(path.read_text(encoding="utf-8")):
        line = _INLINE_CODE.sub("", line)
        out.extend((number, m.group(1)) for m in _LINK.finditer(line))
    return out


def _is_external(target: str) -> bool:
    return bool(re.match(r"^[a-zA-Z][a-zA-Z0-9+.-]*:", target))


def test_slugs_follow_github():
    assert github_slug("Set-up: two commands") == "set-up-two-commands"
    assert github_slug("`radar-cfg FILE [--json]`") == "radar-cfg-file---json"
    assert github_slug("Subscribing over Zenoh (`radarodom.publish`, `radar-echo`)") == \
        "subscribing-over-zenoh-radarodompublish-radar-echo"
    assert github_slug("Why the defaults") == "why-the-defaults"


@pytest.mark.parametrize("doc", _doc_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_resolve(doc: Path):
    assert doc.is_file(), f"{doc} is missing"
    broken = []
    for number, target in links(doc):
        if _is_external(target):
            continue
        file_part, _, anchor = target.partition("#")
        dest = (doc.parent / file_part).resolve() if file_part else doc
        where = f"{doc.relative_to(ROOT)}:{number}: {target}"
        if not dest.exists():
            broken.append(f"{where}: no such file")
            continue
        if anchor:
            if dest.suffix != ".md" or not dest.is_file():
                broken.append(f"{where}: an anchor into a file that is not Markdown")
            elif anchor not in anchors(dest):
                broken.append(f"{where}: no heading with anchor #{anchor} in {dest.relative_to(ROOT)}")
    assert not broken, "\n".join(broken)


def test_readme_is_short():
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= README_MAX_LINES, f"README.md has {len(lines)} lines, more than {README_MAX_LINES}"


def test_every_program_in_cli_reference():
    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]["scripts"]
    headings = [m.group(2) for _, line in _prose_lines((DOCS / "cli.md").read_text(encoding="utf-8"))
                if (m := _HEADING.match(line))]
    missing = [name for name in scripts
               if not any(re.search(rf"(?<![\w-]){re.escape(name)}(?![\w-])", h) for h in headings)]
    assert not missing, f"docs/cli.md has no heading for {missing}"


def test_every_docs_page_linked_from_readme():
    linked = {(README.parent / target.partition("#")[0]).resolve()
              for _, target in links(README) if not _is_external(target)}
    missing = [str(p.relative_to(ROOT)) for p in sorted(DOCS.glob("*.md")) if p.resolve() not in linked]
    assert not missing, f"README.md does not link {missing}"
