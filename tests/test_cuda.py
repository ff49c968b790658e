"""Every script on a GPU: a short run with --cuda, stopped and resumed from its checkpoint, then its actor (and
RILe's reward) used on the CPU. Skipped where torch sees no GPU (CI); run by hand on a GPU machine:
`python -m pytest -q tests/test_cuda.py`
(leave MUJOCO_GL unset where the machine has no libEGL: MUJOCO_GL=egl fails at `import mujoco` there).
Last run: 9 passed in 294 s on one H200 (torch 2.11.0+cu130, Python 3.12, gymnasium 1.4.0, mujoco 4.0.0), code
2bc1850, 2026-12-04."""
import json

import pytest
import torch

from conftest import ROOT

pytestmark = pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a GPU")

DEMOS = ["--env-id", "InvertedPendulum-v4", "--expert-path", str(ROOT / "experts/InvertedPendulum-v4.npz"),
         "--num-expert-trajs", "2"]
SMALL = ["--learning-starts", "200", "--eval-freq", "200", "--eval-episodes", "2", "--hidden-dim", "32",
         "--batch-size", "32"]
TRAINER = ["--trainer-hidden-dim", "32", "--trainer-batch-size", "32", "--disc-batch-size", "16"]
SCRIPTS = {  # script: (arguments, steps of the first part (None: no --resume), steps in all)
    "rile.py": ([*DEMOS, *SMALL, *TRAINER, "--dynamics-freq", "200"], 400, 600),
    "gail.py": ([*DEMOS, *SMALL, "--dynamics-freq", "200"], 400, 600),
    "airl.py": ([*DEMOS, *SMALL, "--dynamics-freq", "200"], 400, 600),
    "gaifo.py": ([*DEMOS, *SMALL, "--dynamics-freq", "200"], 400, 600),
    "iqlearn.py": ([*DEMOS, *SMALL], 400, 600),
    "drail_disc.py": ([*DEMOS, *SMALL, *TRAINER, "--disc-hidden-dim", "64"], 400, 600),
    "expert.py": (["--env-id", "InvertedPendulum-v4", *SMALL, "--no-record-demos", "--cudagraphs"], 400, 600),
    "bc.py": ([*DEMOS, "--eval-freq", "200", "--eval-episodes", "2", "--hidden-dim", "32"], 200, 400),
    "bco.py": ([*DEMOS, "--pre-demo-steps", "600", "--alpha", "0.25", "--inverse-steps", "100", "--bc-steps", "100",
                "--inverse-steps-per-iteration", "50", "--bc-steps-per-iteration", "50", "--hidden-dim", "32",
                "--eval-episodes", "2"], None, 900),
}


@pytest.mark.parametrize("script", SCRIPTS)
def test_runs_and_resumes_on_the_gpu_then_its_actor_acts_on_the_cpu(run, tmp_path, script):
    args, first, total = SCRIPTS[script]
    run(script, *args, "--cuda", "--total-timesteps", str(first or total), "--run-name", "g")
    if first:
        out = run(script, "--resume", "runs/g", "--total-timesteps", str(total)).stdout
        assert f"resumed runs/g at step {first}" in out
    results = json.loads((tmp_path / "runs/g/results.json").read_text())
    assert results["finished"] and results["evals"][-1]["step"] == total
    assert results["machine"]["device"].startswith("cuda")  # the resumed part kept --cuda from the checkpoint
    assert all(torch.isfinite(torch.tensor(e["mean"])) for e in results["evals"])
    out = run("expert.py", "--env-id", "InvertedPendulum-v4", "--record-from", "runs/g/actor.pt", "--num-demos", "1",
              "--demo-path", "demos.npz").stdout  # no --cuda: the GPU's actor on the CPU
    assert "recorded 1 episodes" in out
    if script == "rile.py":  # the GPU's frozen reward teaches a fresh student on the CPU
        run(script, *args, "--total-timesteps", "300", "--run-name", "cs", "--reward-from", "runs/g/reward.pt")
