"""report.html in a real headless browser (Debian's chromium driven by selenium): it loads
without console errors, shows one point per Pareto design, a click shows that design's values
and files, and the study's own text is shown as text (never run)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from urllib.parse import unquote, urlparse

import pytest

from optimizer.cli.main import main
from tests.optimizer.conftest import TINY_OUTER_YAML

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
DRIVER = shutil.which("chromedriver")
#: The flags a sandboxed, offline machine needs (no background network, no GPU, no sandbox as root).
FLAGS = ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--disable-dev-shm-usage")
NAME = "<script>alert(1)</script> & co"

pytest.importorskip("selenium", reason="selenium is a test dependency (pip install -e '.[test]')")
pytestmark = pytest.mark.skipif(
    not (CHROMIUM and DRIVER), reason="no chromium and chromedriver here (.ci/run installs Debian's)"
)


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in FLAGS:
        options.add_argument(flag)
    options.add_argument(f"--user-data-dir={tmp_path_factory.mktemp('chromium')}")
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(DRIVER), options=options)
    yield driver
    driver.quit()


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("report")
    study = folder / "study.yaml"
    study.write_text(TINY_OUTER_YAML.replace("name: tiny", f"name: {json.dumps(NAME)}"), encoding="utf-8")
    assert main(["optimize", str(study), "--out", str(folder / "run"), "--quiet"]) == 0
    return folder / "run"


def test_the_page_loads_clean_and_a_click_shows_a_design(browser, run: Path):
    from selenium.common.exceptions import NoAlertPresentException
    from selenium.webdriver.common.by import By

    front = json.loads((run / "pareto.json").read_text(encoding="utf-8"))
    browser.get((run / "report.html").as_uri())
    assert browser.title == f"footopt: {NAME}"  # the name as text
    with pytest.raises(NoAlertPresentException):
        browser.switch_to.alert  # noqa: B018 - nothing the user wrote ran
    circles = browser.find_elements(By.CSS_SELECTOR, "circle.pareto")
    assert len(circles) == len(front["designs"]) > 0
    for k in (0, len(circles) - 1):
        circles[k].click()
        design = front["designs"][k]
        details = browser.find_element(By.ID, "details")
        assert details.find_element(By.TAG_NAME, "h3").text.startswith(f"trial {design['trial']} ")
        shown = {li.text.split(" = ")[0]: float(li.text.split(" = ")[1]) for li in details.find_elements(By.TAG_NAME, "li")}
        for name, value in design["objectives"].items():
            assert shown[name] == value  # the same double, printed and read back
        links = [a.get_attribute("href") for a in details.find_elements(By.TAG_NAME, "a")]
        assert len(links) == 4 and all(Path(unquote(urlparse(h).path)).is_file() for h in links)
        assert "chosen" in circles[k].get_attribute("class")
    errors = [e for e in browser.get_log("browser") if e["level"] == "SEVERE"]
    assert errors == []


def test_user_text_is_escaped_in_the_source(run: Path):
    page = (run / "report.html").read_text(encoding="utf-8")
    assert "<script>alert(1)" not in page
    assert "&lt;script&gt;alert(1)&lt;/script&gt; &amp; co" in page


def test_the_run_folders_plots_are_shown(browser, run: Path):
    """The figures section shows the run folder's plots (here the front), each image loaded."""
    from selenium.webdriver.common.by import By

    browser.get((run / "report.html").as_uri())
    images = browser.find_elements(By.CSS_SELECTOR, "#figures img")
    shown = [Path(unquote(urlparse(i.get_attribute("src")).path)).name for i in images]
    assert shown == ["front.png"]
    assert all(browser.execute_script("return arguments[0].complete && arguments[0].naturalWidth", i) > 0
               for i in images)
