"""sweep.py: skipping and resuming jobs, the report's statistics, tables and curves, bad files."""

import json
import os
import re
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

import sweep
from conftest import ROOT

TINY = ["--learning-starts", "100", "--eval-freq", "100", "--eval-episodes", "2", "--hidden-dim", "32", "--batch-size", "32",
        "--threads", "1"]  # one intra-op thread: at two, beside busy processes, a resumed job ran past its 300 s


# ---------------------------------------------------------------- statistics


def test_mean_and_standard_error():
    m, se = sweep.mean_se([1.0, 2.0, 3.0, 4.0])
    assert m == 2.5 and se == pytest.approx(np.sqrt(((1.5**2 + 0.5**2) * 2) / 3) / 2)  # s.d. 1.2910 / sqrt(4)
    assert np.isnan(sweep.mean_se([7.0])[1])


def test_interquartile_mean():
    assert sweep.iqm([4, 1, 3, 2]) == 2.5  # drops 1 and 4
    assert sweep.iqm([1, 2, 3, 4, 100, 7, 8, 9]) == 5.5  # middle four of eight: 3, 4, 7, 8
    assert sweep.iqm([1, 2, 30]) == 11.0  # fewer than four values: nothing to trim
    from scipy.stats import trim_mean

    x = np.random.default_rng(0).normal(size=13)
    assert sweep.iqm(x) == pytest.approx(trim_mean(x, 0.25))


def test_bootstrap_interval():
    assert sweep.bootstrap_ci([3.0, 3.0, 3.0]) == (3.0, 3.0)
    assert sweep.bootstrap_ci([3.0]) is None  # one seed: every resample is the same value, no spread to show
    x = [0.1, 0.5, 0.9, 0.7, 0.3]
    lo, hi = sweep.bootstrap_ci(x)
    assert lo < sweep.iqm(x) < hi and (lo, hi) == sweep.bootstrap_ci(x)  # reproducible
    assert min(x) <= lo and hi <= max(x)


def test_difference_interval():
    """mean(a) - mean(b), each group resampled on its own: a = [0, 1] resamples to means 0, 0.5, 1 (p 1/4, 1/2, 1/4),
    b = [0, 0] stays 0, so the 95% interval runs from 0 to 1 and the point estimate 0.5 lies inside. One seed on
    either side: no interval."""
    assert sweep.difference_ci([0.0, 1.0], [0.0, 0.0]) == (0.0, 1.0)
    assert sweep.difference_ci([0.0, 1.0], [0.0]) is None and sweep.difference_ci([0.5], [0.0, 1.0]) is None
    assert sweep.difference_ci([2.0, 2.0], [0.5, 0.5, 0.5]) == (1.5, 1.5)
    assert sweep.difference_ci([0.3, 0.9, 0.4], [0.1, 0.2]) == sweep.difference_ci([0.3, 0.9, 0.4], [0.1, 0.2])


def test_trainer_rows_interval_needs_two_seeds_each():
    """Curves of 8 evaluations (expert 100, random 0): the last quarter is the last two, the second half the last four.
    rile.py one seed [.., 60, 80] against the control's [.., 20, 40]: +0.400, and no interval from one seed; with a
    second seed each the bootstrap interval appears, in the rows and in the README's line alike."""
    rile = fake_result("rile-paperD", 1, [0, 0, 0, 0, 40, 40, 60, 80], 100.0)
    control = fake_result("rile-paperD-control", 1, [0, 0, 0, 0, 0, 0, 20, 40], 100.0)
    runs = {("rile-paperD", "a"): [rile], ("rile-paperD-control", "a"): [control]}
    assert sweep.trainer_rows(["a"], runs) == [("a", "1 and 1 | +0.400 (one seed: no interval) | "
                                                     "+0.400 (one seed: no interval)")]
    runs["rile-paperD", "a"] = [rile, fake_result("rile-paperD", 2, [0] * 6 + [80, 100], 100.0)]
    runs["rile-paperD-control", "a"] = [control, control]
    # last quarter: 0.7 and 0.9 against 0.3 twice, resampled means 0.7, 0.8, 0.9 (p 1/4, 1/2, 1/4) minus 0.3;
    # second half: 0.55 and 0.45 against 0.15, resampled 0.45, 0.5, 0.55 minus 0.15
    assert sweep.trainer_rows(["a"], runs) == [("a", "2 and 2 | +0.500 [+0.400, +0.600] | +0.350 [+0.300, +0.400]")]

    # the README's line on what the trainer adds: the same curves, finals 0.8 and 1.0 against 0.4
    rows = {algo: runs[algo, "a"] for algo in sweep.TRAINER_GAP}
    assert sweep.trainer_gap(rows) == (
        "What the trainer adds, rile.py defaults minus the control (2 and 2 seeds): last quarter +0.500 (95% bootstrap "
        "interval [+0.400, +0.600]), final +0.500, normalized.")


# ---------------------------------------------------------------- report


def fake_result(algo, seed, curve, expert=None, env_id="Hopper-v4", random=0.0):
    evals = [{"step": (i + 1) * 1000, "mean": v, "std": 0.0, "normalized": v / expert if expert else None}
             for i, v in enumerate(curve)]
    return {"algo": algo, "env_id": env_id, "seed": seed, "finished": True, "evals": evals, "final_return": curve[-1],
            "final_normalized_return": curve[-1] / expert if expert else None, "expert_return": expert,
            "random_return": random, "wall_time_s": 3600.0 * seed, "sps": 100.0, "machine": {}, "config": {}}


@pytest.fixture
def results_dir(tmp_path):
    d = tmp_path / "results"
    (d / "Hopper-v4").mkdir(parents=True)
    for seed, final in ((1, 1000.0), (2, 2000.0), (3, 3000.0)):
        (d / "Hopper-v4" / f"gail__{seed}.json").write_text(json.dumps(fake_result("gail", seed, [0.0, final], 4000.0)))
    (d / "Hopper-v4" / "rile__1.json").write_text(json.dumps(fake_result("rile", 1, [10.0, 20.0, 3500.0], 3500.0)))
    return d


def test_report_table_plot_and_readme(results_dir, tmp_path):
    readme = tmp_path / "README.md"
    readme.write_text(f"# x\n\n{sweep.README_START}\nold\n{sweep.README_END}\n\nafter\n")
    text = sweep.report(str(results_dir), readme=str(readme))
    # gail: finals 1000, 2000, 3000 -> 2000 +- 577.4 (s.d. 1000 / sqrt 3); normalized 0.5 +- 0.144
    # last quarter: the evaluations after 3/4 of the steps, here the final one alone
    # worst: the lowest of those evaluations over all seeds (gail's seed 1: 0.25)
    assert ("| gail | 3 | 2000.0 ± 577.4 | 0.500 ± 0.144 | 0.500 [0.250, 0.750] | 0.500 ± 0.144 | 0.250 | 2000 | 2.00 "
            "| 3361 |") in text
    assert "| rile | 1 | 3500.0 | 1.000 | 1.000 | 1.000 | 1.000 | 3000 | 1.00 | 3417 |" in text  # one seed: no interval
    png = results_dir / "Hopper-v4-all.png"  # every tag; Hopper-v4.png holds today's defaults, of which there are none
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 5000
    assert not (results_dir / "Hopper-v4.png").exists()
    content = readme.read_text()  # tags `gail` and `rile` are no defaults: the README names none, docs/results.md both
    assert "old" not in content and "| gail | 3 |" not in content and content.endswith("after\n")
    assert "No results with today's defaults yet." in content and "[docs/results.md](docs/results.md)" in content
    assert "| gail | 3 |" in (tmp_path / "docs" / "results.md").read_text()
    assert (results_dir / "REPORT.md").read_text() == text


def test_the_readme_shows_todays_defaults_by_name_and_docs_every_tag(results_dir, tmp_path):
    """The README's section holds the tags DEFAULT_ROWS lists, under readable names, grouped by script, with the line
    on which seeds chose the defaults; docs/results.md holds every tag, the defaults marked; links resolve."""
    hopper = results_dir / "Hopper-v4"
    for algo, seed, final in [("rile-paperD", 1, 3000.0), ("rile-paperD", 2, 3200.0), ("gail-paperD-autotune", 1, 2800.0),
                              ("rile-paperD-control", 1, 1600.0), ("rile-excess-release", 1, 1000.0), ("bco", 1, 2400.0)]:
        (hopper / f"{algo}__{seed}.json").write_text(json.dumps(fake_result(algo, seed, [0.0, final], 3200.0)))
    (results_dir / "HalfCheetah-v4").mkdir()  # rile.py's defaults without the control
    (results_dir / "HalfCheetah-v4" / "rile-paperD__1.json").write_text(
        json.dumps(fake_result("rile-paperD", 1, [0.0, 900.0], 4000.0, env_id="HalfCheetah-v4")))
    (results_dir / "Pendulum-v1").mkdir()  # a table without rile.py's or gail.py's tuned runs: no selection note
    (results_dir / "Pendulum-v1" / "bc-10demos__1.json").write_text(
        json.dumps(fake_result("bc-10demos", 1, [0.0, -200.0], -150.0, env_id="Pendulum-v1")))
    (results_dir / "Walker2d-v4").mkdir()  # an env with no run of today's defaults gets no README table
    (results_dir / "Walker2d-v4" / "gail-pooled__1.json").write_text(
        json.dumps(fake_result("gail-pooled", 1, [0.0, 900.0], 4000.0, env_id="Walker2d-v4")))
    readme = tmp_path / "README.md"
    readme.write_text(f"# x\n\n{sweep.README_START}\n{sweep.README_END}\n")
    sweep.report(str(results_dir), readme=str(readme))
    section = readme.read_text().split(sweep.README_START)[1]
    hopper = section.split("### Hopper-v4")[1].split("###")[0]
    rows = [line.split(" | ")[0][2:] for line in hopper.splitlines() if line.startswith("| ") and "---" not in line]
    assert rows == ["algorithm", "rile.py defaults", "rile.py control: r_S = v(D), no trainer", "gail.py defaults",
                    "bco.py defaults"]  # by script as DEFAULT_ROWS lists them, not by tag
    assert "| rile.py defaults | 2 | 3100.0 ± 100.0 | 0.969 ± 0.031 |" in section
    for tag in ("paperD", "excess-release", "| gail |", "| rile |", "Walker2d-v4", "gail-pooled"):
        assert tag not in section, tag
    assert sweep.SELECTION_NOTE in section and "seeds 3 and 4 were not" in section
    pendulum = section.split("### Pendulum-v1")[1].split("###")[0]
    assert "bc.py defaults with 10 demonstrations" in pendulum and sweep.SELECTION_NOTE not in pendulum
    # what the trainer adds: rile.py normalized 0.9375 and 1 (its last quarter: the final evaluation alone), the
    # control 0.5 from one seed, so no interval
    assert ("What the trainer adds, rile.py defaults minus the control (2 and 1 seeds): last quarter +0.469 (one "
            "seed: no interval), final +0.469, normalized.") in section
    assert section.count("What the trainer adds") == 1 and "What the trainer adds" in hopper  # none without a control
    assert "[Hopper-v4.png](results/Hopper-v4.png)" in section and (tmp_path / "results/Hopper-v4.png").exists()

    docs = (tmp_path / "docs" / "results.md").read_text()
    for row in ("| rile-paperD (rile.py defaults) | 2 |", "| rile-paperD-control (rile.py control: r_S = v(D), no "
                "trainer) | 1 |", "| gail-paperD-autotune (gail.py defaults) | 1 |", "| rile-excess-release | 1 |",
                "| gail | 3 |", "| rile | 1 |", "| gail-pooled | 1 |"):
        assert row in docs, row
    for page, target in [(readme, t) for t in re.findall(r"\]\(([^)]+)\)", section)] + [
            (tmp_path / "docs" / "results.md", t) for t in re.findall(r"\]\(([^)]+)\)", docs) if t != "history.md"]:
        assert (page.parent / target).exists(), (page.name, target)


def test_last_quarter_averages_the_evaluations_after_three_quarters_of_the_steps(results_dir):
    """A run that swings: 8 evaluations at 1k..8k, the last quarter is 7k and 8k (6k is exactly 3/4, left out)."""
    for seed, curve in ((1, [0, 0, 0, 0, 0, 4000, 1000, 3000]), (2, [0, 0, 0, 0, 0, 0, 3000, 4000])):
        (results_dir / "Hopper-v4" / f"swing__{seed}.json").write_text(json.dumps(fake_result("swing", seed, curve, 4000.0)))
    # seed 1: (0.25 + 0.75) / 2 = 0.5; seed 2: (0.75 + 1) / 2 = 0.875; over seeds 0.6875 +- 0.1875, printed 0.187;
    # the worst of those four evaluations: 0.25
    assert "| swing | 2 | 3500.0 ± 500.0 | 0.875 ± 0.125 | 0.875 [0.750, 1.000] | 0.688 ± 0.187 | 0.250 | 8000 |" in (
        sweep.report(str(results_dir), readme=None))
    r = fake_result("raw", 1, [5.0, 7.0, 9.0, 11.0, 13.0])  # no expert return: returns, not normalized
    assert sweep.last_quarter(r, normalize=False) == 12.0  # 4k and 5k, after 3.75k: (11 + 13) / 2
    assert sweep.last_quarter(r, normalize=False, worst=True) == 11.0  # the lower of the two
    assert sweep.last_quarter(r, normalize=False, after=0.5) == 11.0  # 3k, 4k and 5k, after 2.5k: (9 + 11 + 13) / 3


def test_normalized_score_is_zero_for_random_and_one_for_the_expert():
    # Pendulum-v1-like, rewards negative: random -1200, expert -170; a policy at -496 is 704 / 1030 of the way
    assert sweep.normalized_score(-496.0, -1200.0, -170.0) == pytest.approx(704.0 / 1030.0)
    assert sweep.normalized_score(-1200.0, -1200.0, -170.0) == 0.0
    assert sweep.normalized_score(-170.0, -1200.0, -170.0) == 1.0
    # HalfCheetah-v4-like: a policy that learned nothing (-280, random -276.7) reads about 0, not 0.00 of 5035
    assert sweep.normalized_score(-280.0, -276.7, 5034.9) == pytest.approx(-3.3 / 5311.6)
    assert sweep.normalized_score(2000.0, 19.0, 3168.0) == pytest.approx(1981.0 / 3149.0)
    assert sweep.normalized_score(1.0, None, 10.0) is None and sweep.normalized_score(1.0, 5.0, 5.0) is None
    rng = np.random.default_rng(0)  # a policy worse than the expert never reads above 1, whatever the signs
    for random, expert in rng.normal(0, 1000, (200, 2)):
        random, expert = min(random, expert), max(random, expert) + 1e-3
        assert sweep.normalized_score(expert - abs(rng.normal()) - 1e-6, random, expert) < 1.0


def test_older_results_files_are_renormalised_from_their_returns(results_dir):
    """A file without random_return takes the one in its demonstrations' metadata (experts/Hopper-v4.npz)."""
    old = fake_result("old", 1, [0.0, 2000.0], 3000.0)
    del old["random_return"]
    (results_dir / "Hopper-v4" / "old__1.json").write_text(json.dumps(old))
    random = sweep.random_return_of(old)
    with np.load(ROOT / "experts/Hopper-v4.npz") as f:
        assert random == json.loads(str(f["metadata"]))["random_return"] and 0 < random < 100
    text = sweep.report(str(results_dir), readme=None)
    assert f"| old | 1 | 2000.0 | {(2000.0 - random) / (3000.0 - random):.3f} |" in text


def test_runs_of_different_lengths_get_their_own_rows(results_dir):
    longer = fake_result("gail", 4, [0.0, 3900.0, 4000.0], 4000.0) | {"config": {"total_timesteps": 3000}}
    (results_dir / "Hopper-v4" / "gail__4.json").write_text(json.dumps(longer))
    text = sweep.report(str(results_dir), readme=None)
    assert "| gail (2k) | 3 | 2000.0 ± 577.4 |" in text and "| gail (3k) | 1 | 4000.0 | 1.000 |" in text


def test_bad_results_files_are_named_not_crashed_on(results_dir, capsys):
    (results_dir / "Hopper-v4" / "broken__1.json").write_text("{not json")
    (results_dir / "Hopper-v4" / "partial__1.json").write_text(json.dumps({"algo": "partial"}))
    (results_dir / "Hopper-v4" / "empty__1.json").write_text(json.dumps(fake_result("empty", 1, [1.0]) | {"evals": []}))
    text = sweep.report(str(results_dir), readme=None)
    assert "| gail | 3 |" in text
    for name in ("broken__1.json", "partial__1.json", "empty__1.json"):
        assert name in text and name in capsys.readouterr().err or name in text


# ---------------------------------------------------------------- sweeps


def sweep_cmd(results, total, *extra):
    return [sys.executable, "-W", "ignore", str(ROOT / "sweep.py"), "--scripts", "expert.py", "--env-ids",
            "InvertedPendulum-v4", "--seeds", "1", "--total-timesteps", str(total), "--results-dir", str(results),
            *extra, *TINY]


def test_interrupted_job_resumes_finished_job_is_skipped(tmp_path):
    results = tmp_path / "results"
    run_results = tmp_path / "runs/bench__InvertedPendulum-v4__expert__1/results.json"
    proc = subprocess.Popen(sweep_cmd(results, 1500), cwd=tmp_path, start_new_session=True,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    deadline = time.time() + 120
    while time.time() < deadline:
        if run_results.exists() and len(json.loads(run_results.read_text())["evals"]) >= 3:
            break
        time.sleep(0.1)
    os.killpg(proc.pid, signal.SIGTERM)  # like a session ending: the sweep and its job are stopped
    proc.communicate(timeout=60)
    deadline = time.time() + 120  # the sweep exits at once; its job first writes its checkpoint (slow under load)
    while time.time() < deadline:
        try:
            os.killpg(proc.pid, 0)
        except ProcessLookupError:
            break
        time.sleep(0.1)
    status = subprocess.run(sweep_cmd(results, 1500, "--status"), cwd=tmp_path, capture_output=True, text=True)
    assert "1 interrupted" in status.stdout, status.stdout
    stopped_at = json.loads(run_results.read_text())["evals"][-1]["step"]
    assert stopped_at < 1500

    again = subprocess.run(sweep_cmd(results, 1500), cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0 and "done, final return" in again.stdout, again.stdout + again.stderr
    final = json.loads((results / "InvertedPendulum-v4" / "expert__1.json").read_text())
    assert [e["step"] for e in final["evals"]] == list(range(100, 1501, 100))  # one continuous curve
    assert "--resume" in final["command"]

    third = subprocess.run(sweep_cmd(results, 1500), cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert "1 of 1 jobs already done; running 0" in third.stdout


def test_a_finished_run_whose_result_was_not_copied_is_collected_with_the_command_it_ran(tmp_path, monkeypatch):
    """A sweep stopped between a job's end and the copy collects the result on its next call, recording --resume
    only where the run was resumed (it used to add --resume to any run that had a checkpoint)."""
    monkeypatch.chdir(tmp_path)
    for seed, resumed in ((1, None), (2, "runs/bench__Hopper-v4__expert__2")):
        job = sweep.Job("expert.py", "Hopper-v4", seed, 2000, ["--threads", "1"])
        os.makedirs(job.run_dir)
        open(os.path.join(job.run_dir, "checkpoint.pt"), "w").close()
        finished = fake_result("expert", seed, [1.0, 2.0]) | {"config": {"total_timesteps": 2000, "resume": resumed}}
        (tmp_path / job.run_dir / "results.json").write_text(json.dumps(finished))
        assert sweep.run_job(job, str(tmp_path / "results")).endswith("done, final return 2.0")
        command = json.loads((tmp_path / "results/Hopper-v4" / f"expert__{seed}.json").read_text())["command"]
        assert command.startswith(f"python expert.py --env-id Hopper-v4 --seed {seed} --total-timesteps 2000")
        assert ("--resume" in command) == bool(resumed)


def test_submitit_launcher_path(tmp_path, monkeypatch):
    pytest.importorskip("submitit")
    monkeypatch.chdir(tmp_path)
    results = tmp_path / "results"
    sweep.main(["--scripts", "expert.py", "--env-ids", "InvertedPendulum-v4", "--seeds", "2",
                    "--total-timesteps", "300", "--results-dir", str(results), "--launcher", "submitit-local", *TINY])
    final = json.loads((results / "InvertedPendulum-v4" / "expert__2.json").read_text())
    assert final["finished"] and final["evals"][-1]["step"] == 300 and final["seed"] == 2


def test_unknown_script_is_a_clear_error(capsys):
    with pytest.raises(SystemExit):
        sweep.main(["--scripts", "nope.py"])
    assert "no script 'nope.py'" in capsys.readouterr().err


def test_a_result_of_another_length_does_not_count_as_done(tmp_path):
    job = sweep.Job("expert.py", "Hopper-v4", 1, 200_000, [])
    path = tmp_path / "Hopper-v4" / "expert__1.json"
    path.parent.mkdir()
    path.write_text(json.dumps({"config": {"total_timesteps": 50_000}}))
    assert sweep.job_state(job, str(tmp_path)) == "waiting"
    path.write_text(json.dumps({"config": {"total_timesteps": 200_000}}))
    assert sweep.job_state(job, str(tmp_path)) == "done"
    path.write_text("{broken")
    assert sweep.job_state(job, str(tmp_path)) == "waiting"


def test_scalars_averages_each_tag_between_evaluations(tmp_path):
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import scalars
    from torch.utils.tensorboard import SummaryWriter

    writer = SummaryWriter(str(tmp_path))
    for step, q in [(1, 2.0), (2, 4.0), (3, 9.0), (4, 1.0), (5, 3.0)]:
        writer.add_scalar("losses/q", q, step)
    writer.add_scalar("eval/return", 100.0, 3)
    writer.add_scalar("eval/return", 50.0, 5)
    writer.close()
    rows = scalars.table(scalars.load(str(tmp_path)), ["losses/q"])
    assert [(step, value) for step, value, _ in rows] == [(3, 100.0), (5, 50.0)]
    assert [means[0] for _, _, means in rows] == [pytest.approx(5.0), pytest.approx(2.0)]  # (2+4+9)/3, (1+3)/2
    with pytest.raises(SystemExit, match="not logged in this run: losses/nope"):
        scalars.table(scalars.load(str(tmp_path)), ["losses/nope"])
    with pytest.raises(SystemExit, match="no events"):
        scalars.load(str(tmp_path / "empty"))


def test_report_says_when_rows_came_from_different_versions():
    same = {"torch": "2.13.0+cpu", "numpy": "2.4.6", "gymnasium": "1.4.0", "mujoco": "4.0.0", "cpu": "AMD EPYC",
            "cpu_capability": "AVX2"}
    runs = lambda algo, machine: [fake_result(algo, 1, [1.0]) | {"machine": machine}]
    assert sweep.version_note({"gail": runs("gail", same), "rile": runs("rile", same)}) == ""
    note = sweep.version_note({"gail": runs("gail", same), "rile": runs("rile", same | {"cpu_capability": "AVX512"}),
                                   "bc": runs("bc", {"torch": "2.13.0+cpu"})})
    assert note.startswith("Versions differ between these rows: ") and note.count("(") == 3
    assert "cpu_capability AVX512 (rile)" in note and "cpu_capability AVX2 (gail)" in note and "torch 2.13.0+cpu (bc)" in note


def test_the_experiments_page_from_results_files_alone(tmp_path):
    """docs/experiments.md: per condition and method the seeds' last-quarter scores, their mean, its fraction of the
    method's clean mean beside the paper's Humanoid fraction; rile.py minus the control with its interval; D on the
    demonstrations and on the student; a figure; 'not yet run' and the command where no results exist."""
    hopper = tmp_path / "results" / "Hopper-v4"
    hopper.mkdir(parents=True)
    for algo, seed, score in [("rile-paperD", 1, 0.9), ("rile-paperD", 2, 1.0), ("rile-paperD-control", 1, 1.0),
                              ("rile-paperD-act1.25", 1, 0.5), ("rile-paperD-act1.25", 2, 0.45),
                              ("rile-paperD-control-act1.25", 1, 0.8), ("rile-paperD-tr-naive", 1, 0.3),
                              ("rile-paperD-act1.25-noclip", 1, 0.19)]:
        curve = [1000.0 * score] * 200  # 200 evaluations, 1k apart: a 200k run
        if algo == "rile-paperD-control-act1.25":
            curve[100:150] = [300.0] * 50  # a fall at 101k-150k: in the second half, not in the last quarter
        r = fake_result(algo, seed, curve, 1000.0)
        r["reward_measures"] = [{"step": 160_000, "d_demos": 0.9, "d_student": 0.1},
                                {"step": 200_000, "d_demos": 0.7, "d_student": 0.3}]
        (hopper / f"{algo}__{seed}.json").write_text(json.dumps(r))
    probe = {"step": 200_000, "grad_state": 0.2, "grad_action": 0.05, "command": "python benchmarks/d_on_actions.py r",
             "d": {"demonstrations: actions D trained on": 0.8, "demonstrations: the expert's clean actions": 0.79,
                   "demonstrations: the student's mean action": 0.78, "demonstrations: uniform random actions": 0.77,
                   "demonstrations: clean actions of other states": 0.5, "student: its stored actions": 0.3,
                   "student: uniform random actions": 0.29,
                   "clean: the expert's clean actions": 0.76}}  # benchmarks/d_on_actions.py --out, in its folder
    (hopper / "d-on-actions").mkdir()
    (hopper / "d-on-actions" / "rile-paperD-act1.25__2.json").write_text(json.dumps(probe))
    probe["d"]["clean: the expert's clean actions"] = 0.4  # under state noise D on the clean states differs
    (hopper / "d-on-actions" / "rile-paperD-state0.5__1.json").write_text(json.dumps(probe))
    readme = tmp_path / "README.md"
    readme.write_text("# x\n")
    sweep.report(str(tmp_path / "results"), readme=str(readme))
    page = (tmp_path / "docs" / "experiments.md").read_text()
    table = page.split("### Hopper-v4")[1]
    assert "| actions 1.25 | rile.py, seed 2 | 200k | 0.80 / 0.79 / 0.78 / 0.77 | 0.76 | 0.30 / 0.29 | 0.25 |" in table
    assert "| states 0.5 | rile.py, seed 1 | 200k | 0.80 / 0.79 / 0.78 / 0.77 | 0.40 | 0.30 / 0.29 | 0.25 |" in table
    assert "d-on-actions" not in page.split("### HalfCheetah-v4")[1].split("## Covariate")[0]  # none measured there
    # rile.py: clean (0.9 + 1.0) / 2 = 0.95; actions 1.25: (0.5 + 0.45) / 2 = 0.475, 0.50 of clean; paper 5154 / 5928
    assert "| clean | 0.90, 1.00: **0.95** | 1.00: **1.00** | not yet run | not yet run |" in table
    assert ("| actions 1.25 | 0.50, 0.45: **0.47** = 0.50 of clean (paper 0.87) | 0.80: **0.80** = 0.80 of clean | "
            "not yet run (paper 0.16) | not yet run (paper 0.82) |") in table
    # rile.py minus the control: last quarter 0.475 - 0.8; second half 0.475 - (50 x 0.3 + 50 x 0.8) / 100 = -0.075,
    # no interval beside the control's one seed; D: the mean of the last quarter's measures, (0.9 + 0.7) / 2
    assert ("| actions 1.25 | 2 and 1 | -0.325 (one seed: no interval) | -0.075 (one seed: no interval) | "
            "0.80 / 0.20, 0.80 / 0.20 | 0.80 / 0.20 | - |") in table
    # a condition only rile.py and gail.py run: '-' for the others, and commands for those two only
    assert "| actions 1.25 unclipped | 0.19: **0.19** = 0.20 of clean | - | not yet run | - |" in table
    assert "--no-expert-noise-clip  # actions 1.25 unclipped, gail.py" in table and "unclipped, airl.py" not in table
    assert "python sweep.py --scripts airl.py --env-ids Hopper-v4 --seeds 1 2 --total-timesteps 200000" in table
    assert "--tag state0.5 --expert-state-noise 0.5  # states 0.5, airl.py" in table
    png = tmp_path / "results" / "noise-Hopper-v4.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and f"]({os.path.relpath(png, tmp_path / 'docs')})" in page
    assert "### HalfCheetah-v4" in page and not (tmp_path / "results" / "noise-HalfCheetah-v4.png").exists()
    trainer = page.split("## The six trainer rewards")[1].split("##")[0]
    # final 0.30 of the best row's 0.90: 0.33; the paper's words beside the rows it ranks
    assert "| naive | 0.30 | 0.33 | 0.30 | never | - | `python sweep.py --scripts rile.py --env-ids Hopper-v4 " in trainer
    assert "| exp-difference (default) | 0.90 | 1.00 | 0.90 | 1k | highest final score |" in trainer
    assert "| sigmoid | not yet run |" in trainer and "| exp-naive | not yet run | | | | fastest to converge" in trainer
    assert (tmp_path / "results" / "trainer-rewards-Hopper-v4.png").exists()


def test_the_expert_data_table_against_the_zero_runs(tmp_path):
    """Expert data: each row's final score and first evaluation at 0.8 or above as fractions of its 0 % run's (the
    student's: the defaults; the trainer's: the screening run in benchmarks/screens/, whose command says so)."""
    results, screens = tmp_path / "results" / "Hopper-v4", tmp_path / "screens" / "Hopper-v4"
    results.mkdir(parents=True)
    screens.mkdir(parents=True)
    rise = lambda at, top: [0.0] * (at - 1) + [1000.0 * top] * (200 - at + 1)  # 0.8 or above from step `at` k
    for folder, algo, curve in [(results, "rile-paperD", rise(40, 0.9)), (results, "rile-paperD-sef0.5", rise(20, 0.81)),
                                (screens, "rile-paperD-tef0", rise(50, 1.0)), (results, "rile-paperD-tef0.5", rise(25, 0.8))]:
        (folder / f"{algo}__1.json").write_text(json.dumps(fake_result(algo, 1, curve, 1000.0)))
    readme = tmp_path / "README.md"
    readme.write_text("# x\n")
    sweep.report(str(tmp_path / "results"), readme=str(readme))
    page = (tmp_path / "docs" / "experiments.md").read_text().split("## Expert data in the buffers")[1]
    assert "| none in the student's batches, 0.1 of the trainer's (defaults) | 0.90 | - | 0.90 | 40k | - |" in page
    assert "| 0.5 of the student's batches | 0.81 | 0.90 | 0.81 | 20k | 0.50 |" in page  # 0.81 / 0.9, 20k / 40k
    assert ("| 0 of the trainer's batches | 1.00 | - | 1.00 | 50k | - | `python sweep.py --scripts rile.py --env-ids "
            "Hopper-v4 --seeds 1 --total-timesteps 200000 --threads 1 --checkpoint-freq 10000 --tag paperD-tef0 "
            "--trainer-expert-fraction 0 --results-dir benchmarks/screens` |") in page
    assert "| 0.5 of the trainer's batches | 0.80 | 0.80 | 0.80 | 25k | 0.50 |" in page  # of the screened 0 % run
    assert "| 1.0 of the trainer's batches | not yet run |" in page
    assert (tmp_path / "results" / "expert-data-Hopper-v4.png").exists()


def test_the_covariate_shift_table_against_the_no_noise_score(tmp_path):
    """Covariate shift: the source row is the run each frozen reward came from; each noisy row is a fraction of the
    no-noise row, the paper's Humanoid fraction beside it (RILe 5196 / 5928 at the heavy level); the commands name
    each method's frozen reward."""
    hopper = tmp_path / "results" / "Hopper-v4"
    hopper.mkdir(parents=True)
    for algo, seed, score in [("rile-paperD-source", 1, 0.9), ("rile-paperD", 2, 1.0), ("rile-paperD-shift0", 1, 0.8),
                              ("rile-paperD-shift0", 2, 0.6), ("rile-paperD-shift1.25", 1, 0.35),
                              ("rile-paperD-control-shift1.25", 1, 0.5), ("rile-paperD-control-shift1.25", 2, 0.5)]:
        result = fake_result(algo, seed, [1000.0 * score] * 200, 1000.0)
        if algo == "rile-paperD-shift0":  # what the frozen reward paid: measured at 100k, 160k and 200k
            result["reward_measures"] = [{"step": step, "r_s_demos": 0.9, "r_s_student": 0.1 * seed + step / 1e6,
                                          "cpr": cpr} for step, cpr in ((100_000, 0.9), (160_000, -0.2), (200_000, 0.4))]
        (hopper / f"{algo}__{seed}.json").write_text(json.dumps(result))
    (hopper / "frozen-rollouts").mkdir()  # benchmarks/frozen_reward_rollouts.py --out, two actors, two episodes
    row = lambda actor, action, ret, falls, per_step, disc: {
        "actor": actor, "action": action, "return": ret, "terminated": falls, "frozen_per_step": per_step,
        "frozen_discounted": disc}
    (hopper / "frozen-rollouts" / "airl.json").write_text(json.dumps({"episodes": 2, "command": "python x.py", "rows": [
        row("experts/Hopper-v4-actor.pt", "mean", [3000, 3100], [False, False], [0.9, 0.8], [80, 70]),
        row("experts/Hopper-v4-actor.pt", "sampled", [2900, 2900], [False, True], [0.7, 0.6], [60, 50]),
        row("runs/bench__Hopper-v4__airl-shift1.25__2", "mean", [100, 200], [True, True], [-0.5, -0.4], [-9, -8]),
        row("runs/bench__Hopper-v4__airl-shift1.25__2", "sampled", [100, 100], [True, True], [-0.5, -0.5], [-9, -9])]}))
    readme = tmp_path / "README.md"
    readme.write_text("# x\n")
    sweep.report(str(tmp_path / "results"), readme=str(readme))
    shift = (tmp_path / "docs" / "experiments.md").read_text().split("## Covariate shift")[1].split("\n## ")[0]
    assert "| airl.py | the demonstrator | 3050 / 2900 | 0 / 1 of 2 | 0.850 / 0.650 | 75.0 / 55.0 |" in shift
    assert "| airl.py | fresh student, noise 1.25, seed 2 | 150 / 100 | 2 / 2 of 2 | -0.450 / -0.500 | -8.5 / -9.0 |" in shift
    # the last measure's r_S on the student (0.1 * seed + 0.2) / on the demos, the correlation over 160k and 200k
    assert "| no noise | 0.30 / 0.90, env +0.10; 0.40 / 0.90, env +0.10 | - | - | - |" in shift
    assert "| source run | - | - | - | - |" in shift
    assert "| source run | 0.90: **0.90** | not yet run | not yet run | not yet run |" in shift  # seed 1 only
    assert "| no noise | 0.80, 0.60: **0.70** | not yet run |" in shift
    assert "| noise 1.25 | 0.35: **0.35** = 0.50 of no noise (paper 0.88) | 0.50, 0.50: **0.50** | " in shift
    assert "| noise 1.25 | 1 and 2 | -0.150 (one seed: no interval) | -0.150 (one seed: no interval) |" in shift
    assert ("--tag airl-shift0.5" not in shift and "--tag shift0.5 --reward-from benchmarks/rewards/Hopper-v4/airl__1.pt "
            "--student-action-noise 0.5  # noise 0.5, airl.py") in shift
    assert (tmp_path / "results" / "shift-Hopper-v4.png").exists()
