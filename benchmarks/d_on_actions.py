"""How much does a run's discriminator read the actions, and how much the states? Read from the checkpoint of a
rile.py or gail.py run (the control too): D(s, a) on the demonstrations' states with the actions D was trained on
(noisy under --expert-action-noise), with the expert's clean actions, with the student's mean action, with the
demonstrations' actions of other states (shuffled), and with uniform random actions; on the expert's clean states
with its clean actions (under --expert-state-noise: does D still score the states the student should reach as the
expert's, or only the noisy ones it trained on); then on the student's newest replay states with its stored actions
and with uniform random ones. The gradient of D's logit, split into its state and its action columns, says the same
per unit of input; the share of action components at the box's edge and their spread compare the actions themselves
(the demonstrations D trained on, the clean ones, the student's).
Answers "why does a method hold up (or not) when the demonstrations' actions are noised": a D that scores the
demonstrations' states alike whatever the action rewards the student for reaching the expert's states, and the
action noise cannot hurt it.

    python benchmarks/d_on_actions.py runs/bench__Hopper-v4__gail-paperD-autotune-act1.25__1 [--recent 20000]

With `--out FILE` the numbers also go to a json file; `sweep.py --report` reads those under
benchmarks/results/<env-id>/d-on-actions/<algo>__<seed>.json into the noisy-demonstrations tables.
"""

import argparse
import json
import os
import sys

import numpy as np
import torch

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import gail  # noqa: E402
import rile  # noqa: E402


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run_dir")
    parser.add_argument("--recent", type=int, default=20000, help="how many of the newest replay transitions")
    parser.add_argument("--out", help="also write the numbers to this json file")
    cli = parser.parse_args()
    torch.set_num_threads(1)
    path = os.path.join(cli.run_dir, "checkpoint.pt")
    if not os.path.isfile(path):
        sys.exit(f"error: no checkpoint at '{path}'; pass runs/<run> of a rile.py or gail.py run that saved one")
    name = torch.load(path, map_location="cpu", weights_only=False)["config"].get("exp_name")
    if name not in ("rile", "gail"):
        sys.exit(f"error: {cli.run_dir} is a run of {name}; this check reads rile.py and gail.py runs")
    script = rile if name == "rile" else gail
    args, ckpt = script.resume(script.Args(resume=cli.run_dir))
    if getattr(args, "state_only", False):
        sys.exit(f"error: {cli.run_dir} ran with --state-only: its D sees (s, s'), no actions")
    env = script.make_env(args.env_id, args.seed)
    obs_dim, act_dim = env.observation_space.shape[0], env.action_space.shape[0]
    low, high, device = env.action_space.low, env.action_space.high, torch.device("cpu")
    absorbing = args.termination_remedy == "absorbing"
    aug_dim = obs_dim + absorbing
    disc = script.Discriminator(aug_dim + act_dim, args.disc_hidden_dim, args.disc_lr, args.disc_gp,
                                args.disc_gp_center, None, args.disc_normalize == "pooled")
    disc.load_state_dict(ckpt["disc"])
    student = script.SAC(aug_dim, act_dim, low, high, args, device, absorbing=absorbing)
    student.load_state_dict(ckpt["student"] if name == "rile" else ckpt["agent"])
    rb = script.ReplayBuffer(aug_dim, act_dim, args.buffer_size, device, extra_dim=int(
        name == "rile" and args.student_reward == "trainer"))
    rb.load_state_dict(ckpt["replay_buffer"])
    demos = script.load_demonstrations(args.expert_path or os.path.join("experts", f"{args.env_id}.npz"), env,
                                       args.num_expert_trajs)
    clip = (low, high) if getattr(args, "expert_noise_clip", True) else (-np.inf, np.inf)
    trained = script.expert_tensors(demos, args.seed, device, args.expert_state_noise, args.expert_action_noise, *clip)
    clean = script.expert_tensors(demos, args.seed, device)
    pad = (lambda x: torch.cat([x, torch.zeros(len(x), 1)], -1)) if absorbing else (lambda x: x)
    s_demo = pad(trained["obs"])  # every row below holds these states (noisy under --expert-state-noise) fixed
    g = torch.Generator().manual_seed(0)
    uniform = lambda n: torch.as_tensor(low) + (torch.as_tensor(high - low)) * torch.rand(n, act_dim, generator=g)
    with torch.no_grad():
        student_action = student.actor.deterministic(s_demo[:, :obs_dim])
    recent = rb.batch(torch.arange(max(0, rb.size - cli.recent), rb.size))
    live = recent.obs[:, -1] == 0 if absorbing else torch.ones(len(recent.obs), dtype=torch.bool)
    s_student, a_student = recent.obs[live], recent.actions[live]
    d = lambda s, a: disc.prob(torch.cat([s, a], -1)).mean().item()

    print(f"{cli.run_dir} ({name}.py) at step {ckpt['step']}: expert actions noised with std "
          f"{args.expert_action_noise}{'' if np.isfinite(clip[0]).all() else ' (unclipped)'}, "
          f"states with std {args.expert_state_noise}; {len(s_demo)} demonstration pairs")
    rows = [("demonstrations", "the demonstrations' states", [
        ("actions D trained on", trained["actions"], s_demo),
        ("the expert's clean actions", clean["actions"], s_demo),
        ("the student's mean action", student_action, s_demo),
        ("clean actions of other states", clean["actions"][torch.randperm(len(s_demo), generator=g)], s_demo),
        ("uniform random actions", uniform(len(s_demo)), s_demo)]),
        ("clean", "the expert's clean states", [("the expert's clean actions", clean["actions"], pad(clean["obs"]))]),
        ("student", f"the student's {len(s_student)} newest living states", [
        ("its stored actions", a_student, s_student),
        ("uniform random actions", uniform(len(s_student)), s_student)])]
    measured = {}
    for key, where, cases in rows:
        print(f"D on {where}:")
        for label, actions, states in cases:
            measured[f"{key}: {label}"] = d(states, actions)
            print(f"  with {label:32s} {measured[f'{key}: {label}']:.3f}")
    # the logit's gradient per standardised input unit, averaged over the demonstrations and the student's pairs
    x = torch.cat([torch.cat([s_demo, trained["actions"]], -1), torch.cat([s_student, a_student], -1)])
    z = ((x - disc.shift) / disc.scale).requires_grad_(True)
    grad = torch.autograd.grad(disc.net(z).sum(), z)[0].abs()
    per_state, per_action = grad[:, :obs_dim].mean().item(), grad[:, aug_dim:].mean().item()
    # how the actions themselves differ: the share of components at the box's edge (beyond 0.95 of its half-width)
    # and the spread per component, of the demonstrations D trained on, the clean ones and the student's stored ones
    mid, half = torch.as_tensor((high + low) / 2), torch.as_tensor((high - low) / 2)
    kinds = {"demonstrations D trained on": trained["actions"], "clean demonstrations": clean["actions"],
             "the student's stored": a_student}
    edge = {k: ((a - mid).abs() > 0.95 * half).float().mean().item() for k, a in kinds.items()}
    spread = {k: a.std(0).mean().item() for k, a in kinds.items()}
    alpha = student.log_alpha.exp().item()
    print("action components at the box's edge / spread per component: "
          + ", ".join(f"{k} {edge[k]:.2f} / {spread[k]:.2f}" for k in kinds) + f"; the student's temperature {alpha:.3g}")
    if cli.out:
        os.makedirs(os.path.dirname(os.path.abspath(cli.out)), exist_ok=True)
        with open(cli.out, "w") as f:
            json.dump({"run": cli.run_dir, "step": ckpt["step"], "d": measured, "grad_state": per_state,
                       "grad_action": per_action, "edge": edge, "spread": spread,
                       "alpha": alpha, "command": " ".join(["python", *sys.argv])}, f, indent=1)
    ratio = f" (action/state {per_action / per_state:.2f})" if per_state > 0 else ""
    print(f"|d logit / d input| per standardised unit: state columns {per_state:.3f}, action columns "
          f"{per_action:.3f}{ratio}")


if __name__ == "__main__":
    main()
