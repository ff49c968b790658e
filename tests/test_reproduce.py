"""A MuJoCo task with contacts (Hopper-v4, a few thousand steps, a fixed seed) gives the committed numbers exactly when
the installed versions, the CPU's model and its capability are those the numbers were recorded with, and skips with
a one-line reason otherwise. The model counts as well as the capability: an Intel Xeon and an AMD EPYC, both AVX-512,
with the same versions, differ in the eighth digit of the first evaluation, and contact dynamics grow such a
difference into a different run, so no tolerance both holds across CPUs and catches a change.
`python tests/test_reproduce.py` records them again (after an intended change, or for another CPU)."""

import json
import subprocess
import sys

import pytest

from conftest import ROOT, run_script

EXPECTED = ROOT / "benchmarks" / "results" / "reproduce_hopper.json"
KEYS = ("python", "torch", "numpy", "gymnasium", "mujoco", "cpu", "cpu_capability")
COMMAND = ["gail.py", "--env-id", "Hopper-v4", "--expert-path", str(ROOT / "experts" / "Hopper-v4.npz"), "--seed", "1",
           "--total-timesteps", "3000", "--learning-starts", "1000", "--eval-freq", "1000", "--eval-episodes", "2",
           "--hidden-dim", "64", "--batch-size", "64", "--threads", "1", "--checkpoint-freq", "0", "--no-save-model",
           "--run-name", "reproduce"]


def installed() -> dict:
    """The versions, CPU model and capability a run here would record (the scripts' own `machine`)."""
    out = subprocess.run([sys.executable, "-c", "import json, gail; print(json.dumps(gail.machine('cpu')))"],
                         cwd=ROOT, capture_output=True, text=True, check=True).stdout
    machine = json.loads(out)
    return {key: machine[key] for key in KEYS}


def evaluations(cwd) -> list:
    run_script(*COMMAND, cwd=cwd)
    results = json.loads((cwd / "runs" / "reproduce" / "results.json").read_text())
    return [[e["step"], e["mean"], e["std"]] for e in results["evals"]]


def test_hopper_gives_the_committed_numbers(tmp_path):
    expected = json.loads(EXPECTED.read_text())
    here = installed()
    recorded = expected["machine"]
    differ = [f"{key} {here[key]} (recorded: {recorded.get(key)})" for key in KEYS if here[key] != recorded.get(key)]
    if differ:
        pytest.skip("exact numbers are only expected on the recorded versions and CPU; here " + ", ".join(differ))
    assert evaluations(tmp_path) == expected["evals"], "same versions and CPU, different numbers: the code's behaviour changed"


if __name__ == "__main__":
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as tmp:
        record = {"command": "python " + " ".join(COMMAND), "machine": installed(), "evals": evaluations(Path(tmp))}
    EXPECTED.write_text(json.dumps(record, indent=1) + "\n")
    print(f"wrote {EXPECTED}: {record['evals']}")
