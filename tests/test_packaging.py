"""Packaging habits: type hints shipped, a docs index, a citation file and a changelog that agree with the repo."""

import re
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]


def test_the_package_ships_its_type_hints():
    tomllib = pytest.importorskip("tomllib")
    assert (ROOT / "src" / "drillgym" / "py.typed").is_file()
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "py.typed" in pyproject["tool"]["setuptools"]["package-data"]["drillgym"]


def test_the_project_names_its_authors():
    tomllib = pytest.importorskip("tomllib")
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert project["authors"] == [{"name": "drillgym developers"}]


def test_the_docs_index_lists_every_docs_page_once():
    index = (ROOT / "docs" / "index.md").read_text()
    pages = sorted(p.name for p in (ROOT / "docs").glob("*.md") if p.name != "index.md")
    linked = re.findall(r"\]\(([\w.-]+\.md)\)", index)
    assert sorted(linked) == pages


def test_the_citation_file_cites_the_project_and_both_papers():
    tomllib = pytest.importorskip("tomllib")
    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    version = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    assert cff["cff-version"] == "1.2.0" and cff["version"] == version and cff["authors"]
    li, zhang = cff["references"]
    physics = " ".join((ROOT / "docs" / "physics.md").read_text().split())
    assert (li["year"], zhang["year"]) == (2023, 2005)
    assert li["title"] in physics  # the title as docs/physics.md quotes it


def test_the_changelog_is_for_the_version_pyproject_says():
    tomllib = pytest.importorskip("tomllib")
    version = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    changelog = (ROOT / "CHANGELOG.md").read_text()
    headings = re.findall(r"^## \[(.+?)\](.*)$", changelog, flags=re.MULTILINE)
    assert headings == [("Unreleased", f" — {version}")]
