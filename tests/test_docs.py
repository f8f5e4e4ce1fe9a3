"""The documentation, checked as a reader would use it (docs/about.md states the conventions).

The site builds strictly (no broken link, anchor or page left out of the nav); every command of a
```console block in docs/ runs from the root of the checkout and exits 0 (simbot's own console
scripts, run with this interpreter, and `make -n`); the README's links into docs/ name pages and
headings that exist; and each table of docs/speed.md sits in a block a benchmark owns.
"""

from __future__ import annotations

import importlib.util
import os
import re
import shlex
import subprocess
import sys
import unicodedata
from importlib.metadata import distribution
from pathlib import Path
from types import ModuleType

import pytest

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs"
BUILD_TIMEOUT_S = 900
"""The build takes 25 s here idle and 75 s at a load average of 10 (griffe reads all of simbot's
source for the API reference); a generous bound for a loaded CI machine."""
COMMAND_TIMEOUT_S = 120
"""A `--help` takes about a second (simbot's imports); `simbot describe` of a world a few."""
DOCS_PACKAGES = ("mkdocs", "material", "mkdocstrings", "mkdocstrings_handlers.python")
"""What `make docs` installs (pyproject's `docs` extra): MkDocs, its theme, the API reference."""
FENCE = re.compile(r"^```console[^\n]*\n(.*?)^```", re.MULTILINE | re.DOTALL)
LINK = re.compile(r"\]\((?:\./)?(docs/[^)\s]+)\)")
HEADING = re.compile(r"^#{1,6}\s+(.+?)\s*$", re.MULTILINE)
CODE = re.compile(r"^```.*?^```", re.MULTILINE | re.DOTALL)


def console_commands() -> list[tuple[str, str]]:
    """(page, command) for every `$ ` line of every ```console block of docs/, in page order."""
    found = []
    for page in sorted(DOCS.rglob("*.md")):
        for block in FENCE.findall(page.read_text()):
            found += [(str(page.relative_to(REPO)), line[2:]) for line in block.splitlines() if line.startswith("$ ")]
    return found


def console_scripts() -> dict[str, str]:
    """simbot's console scripts (`simbot`, `simbot-server`, ...) by name → `module:function`, as installed."""
    return {
        point.name: point.value for point in distribution("simbot").entry_points if point.group == "console_scripts"
    }


def argv_of(command: str) -> list[str]:
    """How a fresh clone runs `command`: a console script through this interpreter (the venv's
    scripts may point elsewhere), `make -n` as it is; anything else is not a console block's."""
    program, *args = shlex.split(command)
    scripts = console_scripts()
    if program in scripts:
        module, function = scripts[program].split(":")
        code = f"import sys; from {module} import {function}; sys.argv[0] = {program!r}; sys.exit({function}())"
        return [sys.executable, "-c", code, *args]
    if program == "make" and args[:1] == ["-n"]:
        return ["make", *args]
    raise AssertionError(
        f"{command!r}: a console block holds only commands that run on a fresh clone with no server "
        f"(simbot's own commands: {', '.join(sorted(scripts))}; `make -n`); show others in a sh block"
    )


COMMANDS = console_commands()


def test_the_docs_have_commands_to_check() -> None:
    """The convention is in use: a ```console block that stopped matching would check nothing."""
    assert len(COMMANDS) >= 10, COMMANDS


@pytest.mark.parametrize(("page", "command"), COMMANDS, ids=[f"{p}: {c}" for p, c in COMMANDS])
def test_a_console_command_runs_on_a_fresh_clone(page: str, command: str) -> None:
    done = subprocess.run(
        argv_of(command), cwd=REPO, capture_output=True, text=True, timeout=COMMAND_TIMEOUT_S, stdin=subprocess.DEVNULL
    )
    assert done.returncode == 0, f"{page}: `{command}` exited {done.returncode}: {done.stderr[-2000:]}"
    assert done.stdout.strip(), f"{page}: `{command}` printed nothing"


def slug(heading: str) -> str:
    """The anchor MkDocs gives a heading (Python-Markdown's toc `slugify`: ASCII, lower case, words and
    hyphens), after the Markdown of the heading's text is rendered away."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading).replace("`", "").replace("*", "")
    text = unicodedata.normalize("NFKD", text).encode("ascii", "ignore").decode("ascii")
    text = re.sub(r"[^\w\s-]", "", text).strip().lower()
    return re.sub(r"[-\s]+", "-", text)


def headings(markdown: str) -> list[str]:
    """The texts of a page's headings, not counting `#` lines inside fenced code."""
    return HEADING.findall(CODE.sub("", markdown))


def test_the_readmes_links_into_the_docs_resolve() -> None:
    links = LINK.findall((REPO / "README.md").read_text())
    if not links:
        pytest.skip("the README links to no page of docs/ yet")
    for link in links:
        path, _, anchor = link.partition("#")
        page = REPO / path
        if page.suffix != ".md":  # a figure, such as the live view's screenshot
            assert page.is_file() and not anchor, f"README shows {link}: no such file in docs/"
            continue
        assert page.is_file(), f"README links to {link}: no such page in docs/"
        if anchor:
            anchors = {slug(h) for h in headings(page.read_text())}
            assert anchor in anchors, f"README links to {link}: {path} has no heading with that anchor"


def tables_module() -> ModuleType:
    """benchmarks/tables.py, which the benchmarks import by its file name."""
    spec = importlib.util.spec_from_file_location("tables", REPO / "benchmarks" / "tables.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_speed_page_has_a_block_per_benchmark_and_no_table_outside_them() -> None:
    text = (DOCS / "speed.md").read_text()
    names = re.findall(r"^<!-- bench:([\w-]+) -->$", text, re.MULTILINE)
    assert names, "docs/speed.md holds no benchmark block"
    assert len(names) == len(set(names)), f"a block appears twice: {names}"
    benchmarks = sorted(path.stem.removeprefix("bench_") for path in (REPO / "benchmarks").glob("bench_*.py"))
    assert sorted(names) == benchmarks, f"docs/speed.md's blocks {sorted(names)} are not one per benchmark {benchmarks}"
    for name in names:
        assert f"\n<!-- /bench:{name} -->\n" in text, f"docs/speed.md: block {name} is never closed"
    for table in re.findall(
        r"^\|.*\|$",
        re.sub(r"^<!-- bench:.*?^<!-- /bench:[\w-]+ -->$", "", text, flags=re.DOTALL | re.MULTILINE),
        re.MULTILINE,
    ):
        raise AssertionError(f"docs/speed.md: a table row outside every benchmark's block: {table}")


def test_a_benchmark_rewrites_its_block_and_nothing_else(tmp_path: Path) -> None:
    tables = tables_module()
    page = tmp_path / "speed.md"
    page.write_text(
        "intro\n<!-- bench:a -->\nold\n<!-- /bench:a -->\nmiddle\n<!-- bench:b -->\nkept\n<!-- /bench:b -->\n"
    )
    tables.publish("a", ["| x | y |", "| --- | --- |", "| 1 | 2 |"], page)
    text = page.read_text()
    assert "old" not in text and "| 1 | 2 |" in text
    assert text.startswith("intro\n<!-- bench:a -->\n*Measured ") and "\nmiddle\n<!-- bench:b -->\nkept\n" in text
    assert f"{len(os.sched_getaffinity(0))} cores" in text
    with pytest.raises(SystemExit, match="no <!-- bench:c -->"):
        tables.publish("c", ["| x |"], page)


def test_the_site_builds_strictly(tmp_path: Path) -> None:
    missing = [name for name in DOCS_PACKAGES if importlib.util.find_spec(name.split(".")[0]) is None]
    if missing:
        pytest.skip(f"the docs' packages are not installed ({', '.join(missing)}): pip install -e '.[docs]'")
    site = tmp_path / "site"
    done = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--config-file", str(REPO / "mkdocs.yml")]
        + ["--site-dir", str(site)],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=BUILD_TIMEOUT_S,
        env=dict(os.environ, NO_MKDOCS_2_WARNING="1"),
    )
    assert done.returncode == 0, done.stderr[-4000:]
    for page in DOCS.rglob("*.md"):
        relative = page.relative_to(DOCS).with_suffix("")
        built = site / (relative.parent if relative.name == "index" else relative) / "index.html"
        assert built.is_file(), f"{page.relative_to(REPO)} was not built"
        html = built.read_text()
        for heading in headings(page.read_text()):  # the anchors the README check expects are the site's
            assert f'id="{slug(heading)}"' in html, f"{page.relative_to(REPO)}: no anchor {slug(heading)!r}"
    reference = (site / "reference" / "systems" / "index.html").read_text()
    assert "SystemContext" in reference and "require_sensor" in reference, "the API reference lacks the contract"


LAYOUT = DOCS / "layout.md"
LISTED_TREES = ("simbot", "clients")
"""The trees whose every module docs/layout.md names."""


def layout_rows() -> list[tuple[Path, set[str]]]:
    """Each row of docs/layout.md's table of what is here: the folder it speaks of (an indented path
    lies under the row above it with less indent) and every name it puts in backticks."""
    rows: list[tuple[Path, set[str]]] = []
    folders: list[tuple[int, Path]] = [(-1, REPO)]
    for line in LAYOUT.read_text().splitlines():
        cells = line.split("|")
        first = re.match(r"`( *)([^`]+)`", cells[1].strip()) if len(cells) > 3 else None
        if first is None:
            continue
        indent, path = len(first.group(1)), first.group(2)
        while folders[-1][0] >= indent:
            folders.pop()
        resolved = folders[-1][1] / path
        if path.endswith("/"):
            folders.append((indent, resolved))
        names = {name.strip() for name in re.findall(r"`([^`]+)`", line)}
        rows.append((resolved if path.endswith("/") else resolved.parent, names | {resolved.name}))
    return rows


def unlisted_modules() -> list[str]:
    """The modules of simbot/ and clients/ that no row of their folder (or, where the page gives the
    folder no row, of the nearest folder above it that has one) names, as `name.py` or `name`."""
    rows = layout_rows()
    folders = {folder for folder, _ in rows}
    missing = []
    for module in sorted(p for tree in LISTED_TREES for p in (REPO / tree).rglob("*.py") if p.name != "__init__.py"):
        folder = next(f for f in (module.parent, *module.parent.parents) if f in folders)
        named = set().union(*(names for f, names in rows if f == folder))
        if not {module.name, module.stem} & named:
            missing.append(str(module.relative_to(REPO)))
    return missing


def test_the_layout_page_names_every_module() -> None:
    """docs/layout.md is where a newcomer looks for a module: each of simbot/ and clients/ is named
    in its folder's rows."""
    assert unlisted_modules() == []
