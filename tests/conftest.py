import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
# small networks and batches keep the end-to-end runs to seconds; every update path still runs
FAST = ["--hidden-dim", "32", "--batch-size", "32", "--eval-episodes", "2"]


def run_script(script: str, *args: str, cwd: Path, check: bool = True, timeout: int = 300):
    """Run a project script as a user would, from `cwd` (runs/ and experts/ land there). Scripts with a
    --threads flag (default 2) run on one unless a test says otherwise: two intra-op threads beside other busy
    processes wait on each other at every small op (a 5 s run took over 300 s in a suite beside two training runs)."""
    if "threads: int" in (ROOT / script).read_text() and not any(a.startswith("--threads") for a in args):
        args = (*args, "--threads", "1")
    proc = subprocess.run([sys.executable, "-W", "ignore", str(ROOT / script), *args], cwd=cwd,
                          capture_output=True, text=True, timeout=timeout)
    if check and proc.returncode != 0:
        raise AssertionError(f"{script} {' '.join(args)} failed ({proc.returncode}):\n{proc.stdout}\n{proc.stderr}")
    return proc


@pytest.fixture
def run(tmp_path):
    return lambda script, *args, **kw: run_script(script, *args, cwd=kw.pop("cwd", tmp_path), **kw)
