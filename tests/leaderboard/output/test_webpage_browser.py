"""The leaderboard page in headless Chromium (Selenium): it loads nothing, sorts, filters, shows an entry's details.

The page is made afresh (``uvdms leaderboard --page-only``) from a copy of the committed leaderboard
(``docs/leaderboard``: 91 rows, two tracks, six tasks, multi-seed and filtered entries) and opened as a
``file://`` URL. Chromium and its driver are Debian's (``chromium``, ``chromium-driver``); without them the test is
skipped, unless ``CI_REQUIRE_BROWSER=1`` (set by ``.ci/run``, which installs them), where it fails.
"""

from __future__ import annotations

import csv
import math
import os
import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest

from leaderboard.suite.entries import slugify
from uvdms_cli.main import main as uvdms_main

pytestmark = pytest.mark.slow  # a headless browser

REPO = Path(__file__).resolve().parents[3]
COMMITTED = REPO / "docs" / "leaderboard"
CHROMIUM = Path("/usr/bin/chromium")
CHROMEDRIVER = Path("/usr/bin/chromedriver")
CHROMIUM_FLAGS = (
    "--headless=new",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-dev-shm-usage",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--window-size=1400,1000",
)
"""Flags for a root user on a machine without network (and a fresh ``--user-data-dir``, added per session)."""


def _missing_browser() -> str | None:
    """Why the browser cannot run here (``None``: it can)."""
    try:
        import selenium  # noqa: F401
    except ImportError:
        return "selenium is not installed (the test extra)"
    missing = [str(p) for p in (CHROMIUM, CHROMEDRIVER) if not p.is_file()]
    return f"{', '.join(missing)} missing (apt-get install chromium chromium-driver)" if missing else None


@pytest.fixture(scope="module")
def page_url(tmp_path_factory) -> str:
    """``file://`` URL of the page made from a copy of the committed leaderboard folder."""
    folder = tmp_path_factory.mktemp("page") / "leaderboard"
    shutil.copytree(COMMITTED, folder, ignore=shutil.ignore_patterns("index.html"))
    assert uvdms_main(["leaderboard", "--page-only", str(folder), "--agents-dir", str(REPO / "trained_agents")]) == 0
    return (folder / "index.html").as_uri()


@pytest.fixture(scope="module")
def browser(tmp_path_factory) -> Iterator:
    """A headless Chromium session (skipped without Chromium, failed instead when ``CI_REQUIRE_BROWSER=1``)."""
    reason = _missing_browser()
    if reason is not None:
        if os.environ.get("CI_REQUIRE_BROWSER") == "1":
            pytest.fail(f"CI_REQUIRE_BROWSER=1 but {reason}")
        pytest.skip(reason)
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for flag in (*CHROMIUM_FLAGS, f"--user-data-dir={tmp_path_factory.mktemp('chromium-profile')}"):
        options.add_argument(flag)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(str(CHROMEDRIVER)), options=options)
    driver.set_page_load_timeout(120)
    try:
        yield driver
    finally:
        driver.quit()


@pytest.fixture
def page(browser, page_url):
    """The page, freshly loaded (no sort, filter or detail view left from another test)."""
    browser.get(page_url)
    return browser


def _csv_rows() -> list[dict[str, str]]:
    with (COMMITTED / "leaderboard.csv").open(encoding="utf-8", newline="") as f:
        return list(csv.DictReader(f))


def _visible_rows(driver) -> list[tuple[str, str, str, str]]:
    """(track, task, entry, rank) of every ranking row the page shows."""
    return driver.execute_script(
        """
        return Array.from(document.querySelectorAll("section.board tbody tr"))
          .filter(function (tr) { return tr.offsetParent !== null; })
          .map(function (tr) { return [tr.dataset.track, tr.dataset.task, tr.dataset.entry,
                                       tr.cells[0].getAttribute("data-value")]; });
        """
    )


def _column_values(driver, section: str, metric: str) -> list[float | None]:
    """The ``data-value`` of one metric's cells, in the order the table shows them."""
    values = driver.execute_script(
        "return Array.from(document.querySelectorAll(arguments[0] + ' tbody td[data-metric=\"' + arguments[1] + '\"]'))"
        ".map(function (td) { return td.getAttribute('data-value'); });",
        section,
        metric,
    )
    return [float(v) if v not in ("", None) else None for v in values]


def test_the_page_loads_without_errors_or_network(page):
    from selenium.webdriver.common.by import By

    severe = [e for e in page.get_log("browser") if e["level"] == "SEVERE"]
    assert severe == []  # a blocked load (Content-Security-Policy) or a script error would be logged here
    resources = page.execute_script("return performance.getEntriesByType('resource').map(e => e.name)")
    assert [r for r in resources if not r.startswith("data:")] == []
    images = page.find_elements(By.CSS_SELECTOR, "#plots img")
    assert images and all(page.execute_script("return arguments[0].naturalWidth", img) > 0 for img in images)
    assert len(_visible_rows(page)) == len(_csv_rows())


def test_clicking_a_header_sorts_numerically_and_a_second_click_reverses(page):
    from selenium.webdriver.common.by import By

    section = 'section.board[data-track="velocity"][data-task="case1"]'
    for metric in ("return", "rmse_pos"):  # returns of both signs and magnitudes: text order is not numeric order
        header = page.find_element(By.CSS_SELECTOR, f'{section} th[data-metric="{metric}"]')
        header.click()
        values = _column_values(page, section, metric)
        numbers = [v for v in values if v is not None]
        assert len(numbers) > 2 and numbers == sorted(numbers)
        assert values == numbers + [None] * (len(values) - len(numbers))  # rows without a value last
        assert header.get_attribute("aria-sort") == "ascending"
        header.click()
        values = _column_values(page, section, metric)
        assert [v for v in values if v is not None] == sorted(numbers, reverse=True)
        assert header.get_attribute("aria-sort") == "descending"
    texts = [row["return_mean"] for row in _csv_rows() if row["task"] == "case1" and row["track"] == "velocity"]
    assert sorted(texts) != sorted(texts, key=float)  # (so the check above tells a text sort from a numeric one)
    page.find_element(By.CSS_SELECTOR, f"{section} th:nth-child(1)").click()  # back to rank order
    ranks = [float(r[3]) for r in _visible_rows(page) if r[:2] == ("velocity", "case1")]
    assert ranks == sorted(ranks) and not math.isnan(sum(ranks))


def test_filtering_to_one_task_shows_exactly_its_csv_rows(page):
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import Select

    rows = _csv_rows()
    Select(page.find_element(By.ID, "filter-task")).select_by_value("transport")
    expected = [(r["track"], r["task"], r["entry"], r["rank"]) for r in rows if r["task"] == "transport"]
    assert sorted(map(tuple, _visible_rows(page))) == sorted(expected)
    assert page.find_element(By.ID, "shown-count").text.startswith(f"{len(expected)} of {len(rows)}")

    Select(page.find_element(By.ID, "filter-kind")).select_by_value("baseline")
    baselines = [row for row in expected if next(r for r in rows if r["entry"] == row[2])["kind"] == "baseline"]
    assert sorted(map(tuple, _visible_rows(page))) == sorted(baselines) and baselines
    Select(page.find_element(By.ID, "filter-kind")).select_by_value("")
    Select(page.find_element(By.ID, "filter-track")).select_by_value("torque")
    torque = [row for row in expected if row[0] == "torque"]
    assert sorted(map(tuple, _visible_rows(page))) == sorted(torque) and torque
    Select(page.find_element(By.ID, "filter-safety")).select_by_value("yes")
    assert _visible_rows(page) == []  # no torque entry runs with the velocity safety filter


def test_clicking_an_entry_shows_its_composition_seeds_and_learning_curve(page):
    from selenium.webdriver.common.by import By

    entry = "residual-mpc-dagger-campc-circle-v1+filter"
    overlay = page.find_element(By.ID, "detail-overlay")
    assert not overlay.is_displayed()
    page.find_element(By.CSS_SELECTOR, f'button.entry-link[data-slug="{slugify(entry)}"]').click()
    assert overlay.is_displayed()
    detail = page.find_element(By.ID, "detail-body")
    assert detail.find_element(By.TAG_NAME, "h2").text == entry
    text = detail.text
    assert "residual on mpc + safety filter" in text and "evaluated with the safety filter" in text
    assert all(f"seed_{k}" in text for k in (0, 1, 2)) and "Budget (steps)" in text and "min)" in text
    curve = detail.find_element(By.TAG_NAME, "img")
    assert curve.get_attribute("data-plot") == "plots/learning_curves_residual-mpc-dagger-campc-circle-v1.png"
    assert page.execute_script("return arguments[0].complete && arguments[0].naturalWidth", curve) > 0
    page.find_element(By.ID, "detail-close").click()
    assert not overlay.is_displayed()
