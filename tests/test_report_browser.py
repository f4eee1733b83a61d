"""The report in a real browser: headless Chromium (Debian's ``chromium``) driven by Playwright.

The tests open the index, go to the episodes table, filter it to failures, sort it by steps (with the mouse and
with the keyboard), keep the episodes one run solved and another did not, open an episode and check that its
images loaded, with no console error on any page. Without the browser or Playwright they skip with one line (``make
test`` installs both; the HTML checks of ``test_report.py`` run regardless). With ``DRIVENAV_REPORT_SCREENSHOTS``
set to a folder, the episodes table and an episode page are saved there as PNGs (the README's screenshots).
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from drivenav.cli import main

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
playwright = pytest.importorskip(
    "playwright.sync_api", reason="playwright is not installed: the report's browser tests skip (make test installs it)"
)
if CHROMIUM is None:
    pytest.skip(
        "Debian's chromium is not installed: the report's browser tests skip (make test installs it with apt)",
        allow_module_level=True,
    )

TINY = ["--episodes", "4", "--max-steps", "30", "--scenes", "procedural:2", "--pictures", "1"]
MODELS = ["--reasoner", "geometric", "--detector", "ground-truth", "--methods", "drive-nav,frontier"]
SHOTS = os.environ.get("DRIVENAV_REPORT_SCREENSHOTS")


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("ablations")
    assert main(["bench", "ablations", *TINY, *MODELS, "--out", str(out)]) == 0
    return out / "report"


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    with playwright.sync_playwright() as driver:
        launched = driver.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox"])
        yield launched
        launched.close()


@pytest.fixture
def page(browser: Any) -> Iterator[Any]:
    """A page that records console errors and uncaught exceptions in ``page.errors``."""
    opened = browser.new_page(viewport={"width": 1200, "height": 800})
    errors: list[str] = []
    opened.on("console", lambda message: errors.append(message.text) if message.type == "error" else None)
    opened.on("pageerror", lambda error: errors.append(str(error)))
    opened.errors = errors
    yield opened
    opened.close()


def visible_rows(page: Any) -> list[dict[str, str]]:
    """The episodes table's shown rows: their data attributes and their steps cell."""
    rows: list[dict[str, str]] = page.eval_on_selector_all(
        "#episodes tbody tr:not([hidden])",
        "rows => rows.map(r => ({...r.dataset, steps: r.cells[7].textContent}))",
    )
    return rows


def test_filter_sort_pivot_and_open_an_episode(site: Path, page: Any) -> None:
    page.goto((site / "index.html").as_uri())
    assert page.title() == "Run report"
    page.click("text=Every episode")
    page.wait_for_selector("#filters:not([hidden])")
    everything = visible_rows(page)
    assert len(everything) == 8 and page.text_content("#row-count") == "8 of 8 rows"

    page.select_option("#filter-success", "0")
    failures = visible_rows(page)
    assert failures and all(row["success"] == "0" for row in failures)
    assert len(failures) == sum(row["success"] == "0" for row in everything)
    assert "success=0" in page.url  # the filter is kept in the address

    page.click("th >> text=steps")
    steps = [int(row["steps"]) for row in visible_rows(page)]
    assert steps == sorted(steps)
    page.focus("th button:text-is('steps')")
    page.keyboard.press("Enter")  # the headers are buttons: sorting works from the keyboard
    steps = [int(row["steps"]) for row in visible_rows(page)]
    assert steps == sorted(steps, reverse=True)
    if SHOTS:
        page.screenshot(path=str(Path(SHOTS) / "report-episodes.png"))

    page.click("text=clear filters")
    page.select_option("#filter-solved", "drive-nav")
    page.select_option("#filter-unsolved", "frontier")
    solved = {r["episode"]: r["success"] for r in everything if r["method"] == "drive-nav"}
    other = {r["episode"]: r["success"] for r in everything if r["method"] == "frontier"}
    expected = {e for e in solved if solved[e] == "1" and other.get(e) == "0"}
    assert {row["episode"] for row in visible_rows(page)} == expected

    page.click("text=clear filters")
    page.select_option("#filter-success", "0")
    first = visible_rows(page)[0]
    page.click("#episodes tbody tr:not([hidden]) >> nth=0 >> a")
    page.wait_for_load_state("load")
    assert page.title() == f"Episode {first['episode']} · {first['method']}"
    sizes = page.eval_on_selector_all("img", "images => images.map(i => i.complete ? i.naturalWidth : 0)")
    assert sizes and all(width > 0 for width in sizes)
    if SHOTS:
        page.screenshot(path=str(Path(SHOTS) / "report-episode.png"))
    assert page.errors == []


def test_every_page_loads_without_console_errors(site: Path, page: Any) -> None:
    for path in sorted(site.rglob("*.html")):
        page.goto(path.as_uri())
        page.wait_for_load_state("load")
        broken = page.eval_on_selector_all("img", "images => images.filter(i => !(i.naturalWidth > 0)).length")
        assert broken == 0, path
    assert page.errors == []
