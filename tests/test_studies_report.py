"""The report: written from a study folder, rendered by headless Chromium with every figure loaded."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from impactometer.errors import ParameterError
from impactometer.studies import StudyOptions, run_study
from impactometer.studies.report import MARKER, collect, write_report

CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def _chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    if Path("/usr/bin/chromium").exists():
        return "/usr/bin/chromium"
    return None


def _rendered_status(page: Path, profile: Path) -> str:
    """The page's own figure check (body[data-figures]) after Chromium loaded it and ran its script."""
    browser = _chromium()
    if browser is None:
        pytest.skip("no Chromium on PATH (chromium, chromium-browser, google-chrome); the report rendering check "
                    "needs a headless browser (.ci/run installs Debian's chromium where apt-get can)")
    dom = subprocess.run([browser, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", "--virtual-time-budget=10000",
                          "--dump-dom", page.as_uri()], capture_output=True, text=True, timeout=120).stdout
    match = re.search(r'<body[^>]*data-figures="([^"]*)"', dom)
    assert match, f"no rendered body in Chromium's output: {dom[:300]!r}"
    return match.group(1)


@pytest.fixture(scope="module")
def report_folder(tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    run_study("peak-force", out, StudyOptions(grid=2), workers=1)
    write_report(out)
    return out


def test_report_lists_figures_tables_and_summary(report_folder):
    text = (report_folder / "index.html").read_text()
    assert text.splitlines()[1] == MARKER
    assert "<img src='peak-force.png'" in text and "href='peak-force.csv'" in text
    assert "Summary: our numbers next to the paper's" in text and "closed form" in text
    assert [r["name"] for r in collect(report_folder)] == ["peak-force"]


def test_every_figure_loads_in_headless_chromium(report_folder, tmp_path):
    assert _rendered_status(report_folder / "index.html", tmp_path / "profile") == "ok 1/1"


def test_a_broken_figure_is_detected_by_the_page(report_folder, tmp_path):
    broken = tmp_path / "broken"
    shutil.copytree(report_folder, broken)
    (broken / "peak-force.png").write_bytes(b"not a png")
    assert _rendered_status(broken / "index.html", tmp_path / "profile").startswith("broken 0/1")


def test_a_foreign_index_html_is_not_overwritten(tmp_path):
    (tmp_path / "index.html").write_text("<html>my page</html>")
    with pytest.raises(ParameterError, match="not written by impactometer; pass --overwrite"):
        write_report(tmp_path)
    assert (tmp_path / "index.html").read_text() == "<html>my page</html>"
    write_report(tmp_path, force=True)
    assert MARKER in (tmp_path / "index.html").read_text()


def test_a_foreign_index_html_is_refused_before_any_work(tmp_path):
    from impactometer.studies import run_studies

    (tmp_path / "index.html").write_text("<html>my page</html>")
    with pytest.raises(ParameterError, match="not written by impactometer"):
        run_studies(["peak-force"], tmp_path, StudyOptions(grid=2), workers=1)
    assert not (tmp_path / "peak-force").exists()
