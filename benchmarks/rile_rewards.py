"""What rile.py's learned reward r_S pays, read from a checkpoint: on the demonstrations, on the student's
recent replay transitions, and at the absorbing state (with D there); then one deterministic episode of the student.
For a run of the control (`--student-reward discriminator`), r_S is v(D) = 2D - 1.
Answers "is falling worth less than living, and is walking worth more than standing?" for a run with
`--termination-remedy absorbing`: staying in the absorbing state forever is worth r_abs / (1 - gamma). Last, the
student's critic against what r_S pays: Q at the episode's first step and at the absorbing state beside the discounted
r_S that follows (where r_S is about 0, as under `--trainer-reward naive`, the values the student acts on are the
critic's own).
Both trainer observations: (s, a_S), and (s, s') of `--state-only --trainer-obs transition`.

    python benchmarks/rile_rewards.py runs/bench__Walker2d-v4__rile-absorbing__1 [--recent 20000]
"""

import os
import sys

import numpy as np
import torch

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import rile  # noqa: E402
from benchmarks.airl_rewards import open_run  # noqa: E402


def main():
    cli, args, ckpt = open_run(rile, __doc__)
    if args.termination_remedy != "absorbing":
        sys.exit(f"error: {cli.run_dir} was trained with --termination-remedy {args.termination_remedy}; "
                 "this check is for runs with --termination-remedy absorbing")
    transition = args.trainer_obs == "transition"
    env = rile.make_env(args.env_id, args.seed)
    obs_dim, act_dim = env.observation_space.shape[0], env.action_space.shape[0]
    low, high, device = env.action_space.low, env.action_space.high, torch.device("cpu")
    control = args.student_reward == "discriminator"  # no trainer: r_S = v(D)
    trainer = None if control else rile.make_trainer(obs_dim + 1, act_dim, args, device)
    if trainer is not None:
        trainer.load_state_dict(ckpt["trainer"])
    seen_dim = obs_dim + 1 if args.state_only else act_dim
    disc = rile.Discriminator(obs_dim + 1 + seen_dim, args.disc_hidden_dim, args.disc_lr, args.disc_gp, args.disc_gp_center,
                              None, args.disc_normalize == "pooled")
    disc.load_state_dict(ckpt["disc"])
    student = rile.SAC(obs_dim + 1, act_dim, low, high, args, device, absorbing=True)
    student.load_state_dict(ckpt["student"] if "student" in ckpt else ckpt["agent"])  # before issue 29: "agent"
    rb = rile.ReplayBuffer(obs_dim + 1, act_dim, args.buffer_size, device, extra_dim=int(not control))
    rb.load_state_dict(ckpt["replay_buffer"])
    demos = rile.load_demonstrations(args.expert_path or os.path.join("experts", f"{args.env_id}.npz"), env,
                                     args.num_expert_trajs, args.state_only)
    expert = rile.absorbing_expert(rile.expert_tensors(demos, args.seed, device, args.expert_state_noise,
                                                     args.expert_action_noise, low, high))
    def r_s(obs, actions, next_obs):
        if control:
            return rile.discriminator_reward(disc, torch.cat([obs, next_obs if args.state_only else actions], -1),
                                             args.termination_remedy)
        return rile.student_reward(trainer.actor, rile.trainer_input(obs, actions, next_obs, args.trainer_obs),
                                   args.termination_remedy)

    with torch.no_grad():
        defined = transition or "actions" in expert  # the (s, a_S) trainer has no expert pairs with --state-only
        on_expert = r_s(expert["obs"], expert.get("actions"), expert["next_obs"]) if defined else None
        recent = rb.batch(torch.arange(max(0, rb.size - cli.recent), rb.size))
        on_student = r_s(recent.obs, recent.actions, recent.next_obs)
        student_at_expert = None if transition else (  # the (s, s') trainer would need the s' they lead to
            r_s(expert["obs"], student.actor.deterministic(expert["obs"][:, :-1]), None))
    at_abs, into_abs = recent.obs[:, -1] > 0, (recent.next_obs[:, -1] > 0) & (recent.obs[:, -1] == 0)
    living = ~at_abs & ~into_abs
    horizon = 1 / (1 - args.gamma)
    frozen = ckpt["rile"]["frozen_at"]
    trainer_is = "frozen at step " + str(frozen) if frozen is not None else "learning"
    print(f"{cli.run_dir} at step {ckpt['step']}, gamma {args.gamma}, "
          f"{'no trainer (the control: r_S = v(D))' if control else 'trainer ' + trainer_is}")
    if on_expert is not None:
        print(f"r_S on the demonstrations:               mean {on_expert.mean():7.3f}  std {on_expert.std():6.3f}")
    else:
        print("r_S on the demonstrations:               not defined (--state-only: the trainer sees (s, a_S), the "
              "demonstrations have no a)")
    if student_at_expert is not None:
        print(f"r_S of the student's action at their states: mean {student_at_expert.mean():7.3f}")
    print(f"r_S on the student's living transitions:  mean {on_student[living].mean():7.3f}  std "
          f"{on_student[living].std():6.3f}  (newest {len(recent.obs)} of the replay buffer)")
    if into_abs.any():
        falls = int(into_abs.sum())
        print(f"r_S into the absorbing state:             mean {on_student[into_abs].mean():7.3f}  ({falls} falls)")
    with torch.no_grad():
        s_abs = torch.as_tensor(rile.absorbing_state(obs_dim)).unsqueeze(0)
        r_abs = r_s(s_abs, torch.zeros(1, act_dim), s_abs).item()  # the absorbing state loops to itself
    print(f"r_S at the absorbing state:               {r_abs:7.3f}; worth of falling r_abs / (1 - gamma): "
          f"{r_abs * horizon:.1f}, of living at the student's mean: {on_student[living].mean() * horizon:.1f}")
    if not args.state_only:  # D prices a fall only if it has learned that the demonstrations never reach the absorbing state
        with torch.no_grad():
            d_abs = disc.prob(torch.cat([s_abs, torch.zeros(1, act_dim)], -1)).item()
            d_living = disc.prob(torch.cat([recent.obs[living], recent.actions[living]], -1)).mean().item()
        print(f"D at the absorbing state:                 {d_abs:7.3f}; on the student's living pairs: mean {d_living:.3f}; "
              f"absorbing rows: {int((rb.batch(torch.arange(rb.size)).obs[:, -1] > 0).sum())} of the buffer's {rb.size}")

    obs, _ = env.reset(seed=args.seed + 100_000)  # the first evaluation episode
    x0, rewards, done, steps = env.unwrapped.data.qpos[0], [], False, 0
    aug = lambda o: torch.as_tensor(np.append(o, 0.0), dtype=torch.float32)[None]  # a living state's indicator 0
    critic = lambda o, a: student.qf(o, a).min(0).values.item()  # the value the student's actor climbs
    while not done:
        action = student.actor.act(obs, deterministic=True)
        if steps == 0:
            with torch.no_grad():
                q_first = critic(aug(obs), torch.as_tensor(action)[None])
        next_obs, _, terminated, truncated, _ = env.step(action)
        with torch.no_grad():  # a fall goes into the absorbing state
            rewards.append(r_s(aug(obs), torch.as_tensor(action)[None], s_abs if terminated else aug(next_obs)).item())
        obs = next_obs
        done, steps = terminated or truncated, steps + 1
    moved = env.unwrapped.data.qpos[0] - x0 if hasattr(env.unwrapped, "data") else float("nan")
    print(f"one deterministic episode: {steps} steps, {'fell' if terminated else 'time limit'}, moved {moved:.2f} "
          f"along x, r_S mean {np.mean(rewards):.3f} (min {np.min(rewards):.3f}, max {np.max(rewards):.3f})")
    # what the student's critic expects against what r_S pays: on a reward of about 0 its values can be its own
    paid = float(np.sum(args.gamma ** np.arange(steps) * np.array(rewards)))
    paid += args.gamma**steps * r_abs * horizon if terminated else 0.0  # a fall: the absorbing state's loop after it
    with torch.no_grad():
        q_abs = critic(s_abs, torch.zeros(1, act_dim))
    print(f"the student's critic: Q(s0, a0) {q_first:.3f} against this episode's discounted r_S {paid:.3f}; at the "
          f"absorbing state {q_abs:.3f} against {r_abs * horizon:.3f} (Q also counts SAC's entropy bonus, alpha "
          f"{student.log_alpha.exp().item():.2g}, none at the absorbing state)")


if __name__ == "__main__":
    main()
