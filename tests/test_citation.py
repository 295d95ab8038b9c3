"""CITATION.cff (Citation File Format 1.2.0) cites this version of the software and, under
``references``, both papers the package implements; CHANGELOG.md and CONTRIBUTING.md exist and
say what they are for. The file is read as text: the CFF keys it must hold are top-level lines."""

from pathlib import Path

import piezohyst

ROOT = Path(__file__).resolve().parents[1]


def _top_level(text: str) -> dict[str, str]:
    keys = {}
    for line in text.splitlines():
        if line and not line.startswith((" ", "#", "-")) and ":" in line:
            key, _, value = line.partition(":")
            keys[key] = value.strip().strip('"')
    return keys


def test_citation_cff_cites_this_version_and_both_seed_papers():
    text = (ROOT / "CITATION.cff").read_text()
    keys = _top_level(text)
    # the keys CFF 1.2.0 requires, and the ones a software citation needs
    assert {"cff-version", "message", "title", "authors", "type", "version", "license"} <= set(keys)
    assert keys["cff-version"] == "1.2.0"
    assert keys["type"] == "software"
    assert keys["version"] == piezohyst.__version__
    refs = text[text.index("\nreferences:") :]
    assert 'doi: "10.1155/2014/769192"' in refs  # seed 1
    assert 'doi: "10.1016/j.heliyon.2020.e03999"' in refs  # seed 2
    assert "Hysteretic benchmark with a dynamic nonlinearity" in refs
    assert "CubeSpec Fine" in refs and "Steering Mirror" in refs  # folded over two lines


def test_changelog_and_contributing():
    changelog = (ROOT / "CHANGELOG.md").read_text()
    assert changelog.startswith("# Changelog") and "## [Unreleased]" in changelog
    contributing = (ROOT / "CONTRIBUTING.md").read_text()
    for gate in ("make lint", "make test", "make docs", "layout.rs"):
        assert gate in contributing
