"""ruff with the settings in pyproject.toml: pyflakes errors (unused imports, undefined names) and lines over
CleanRL's 127 characters fail the suite, so CI checks them on every submission; so do links between the docs."""

import re
import subprocess
import sys

from conftest import ROOT


def test_ruff_finds_nothing():
    proc = subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache", "--output-format", "concise", str(ROOT)],
                          capture_output=True, text=True, cwd=ROOT)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_every_relative_link_in_the_docs_names_a_file_that_exists():
    """README.md linked docs/sweep.md for a while after the page became docs/sweeps.md."""
    broken = []
    for page in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        for target in re.findall(r"\]\(([^)\s#]+)(?:#[^)]*)?\)", page.read_text()):
            if "://" not in target and not (page.parent / target).exists():
                broken.append(f"{page.relative_to(ROOT)} -> {target}")
    assert not broken, broken
