"""ruff with the settings in pyproject.toml: pyflakes errors (unused imports, undefined names) and lines over
CleanRL's 127 characters fail the suite, so CI checks them on every submission."""

import subprocess
import sys

from conftest import ROOT


def test_ruff_finds_nothing():
    proc = subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache", "--output-format", "concise", str(ROOT)],
                          capture_output=True, text=True, cwd=ROOT)
    assert proc.returncode == 0, proc.stdout + proc.stderr
