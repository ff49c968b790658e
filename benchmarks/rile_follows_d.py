"""How rile.py's trainer passes D on, read from a checkpoint: r_S against v(D) = 2D - 1 on the student's
newest pairs (a least-squares line and Pearson) and on the demonstrations, binned by v(D). Shows where the
trainer's reward is fitted (the student's pairs) and where it is an extrapolation (the demonstrations' pairs).
Then the freeze test's statistic on one batch of the trainer's window (its two critics' TD loss relative to the
variance of their targets) beside the same loss relative to the variance of the reward r_T itself: whether the
critic has resolved what its action controls; and that loss split into the variance of its sampled targets, which
no critic removes, and the error beyond it. Last, the value the critics bootstrap from on every row of the trainer's
window: a runaway in a corner of it shows as a few rows far below the rest. For runs with `--termination-remedy
absorbing` and the trainer observing (s, a_S).

    python benchmarks/rile_follows_d.py runs/bench__Hopper-v4__rile-s-pooled-alpha02__1 --recent 10000
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
    if args.termination_remedy != "absorbing" or args.state_only:
        sys.exit(f"error: {cli.run_dir} is not a run with --termination-remedy absorbing on (s, a) pairs")
    if args.student_reward != "trainer":
        sys.exit(f"error: {cli.run_dir} is a run of the control (--student-reward discriminator): it has no trainer, "
                 "its r_S is v(D) itself")
    env = rile.make_env(args.env_id, args.seed)
    obs_dim, act_dim, device = env.observation_space.shape[0], env.action_space.shape[0], torch.device("cpu")
    trainer = rile.make_trainer(obs_dim + 1, act_dim, args, device)
    trainer.load_state_dict(ckpt["trainer"])
    student = rile.SAC(obs_dim + 1, act_dim, env.action_space.low, env.action_space.high, args, device, absorbing=True)
    student.load_state_dict(ckpt["student"])
    disc = rile.Discriminator(obs_dim + 1 + act_dim, args.disc_hidden_dim, args.disc_lr, args.disc_gp, args.disc_gp_center,
                              None, args.disc_normalize == "pooled")
    disc.load_state_dict(ckpt["disc"])
    rb = rile.ReplayBuffer(obs_dim + 1, act_dim, args.buffer_size, device, extra_dim=1)
    rb.load_state_dict(ckpt["replay_buffer"])
    demos = rile.load_demonstrations(args.expert_path or os.path.join("experts", f"{args.env_id}.npz"), env,
                                     args.num_expert_trajs)
    expert = rile.absorbing_expert(rile.expert_tensors(demos, args.seed, device))
    with torch.no_grad():
        recent = rb.batch(torch.arange(max(0, rb.size - cli.recent), rb.size))
        live = recent.obs[:, -1] == 0  # env states, not the absorbing loop

        def r_and_v(obs, actions):
            pairs = torch.cat([obs, actions], -1)
            return trainer.actor.deterministic(pairs).squeeze(-1).numpy(), (2 * disc.prob(pairs) - 1).numpy()

        r, v = r_and_v(recent.obs[live], recent.actions[live])
        r_demo, v_demo = r_and_v(expert["obs"], expert["actions"])
    slope, intercept = np.polyfit(v, r, 1)
    print(f"{cli.run_dir} at step {ckpt['step']}, trainer frozen at {ckpt['rile']['frozen_at']}")
    print(f"student's pairs: r_S = {slope:.2f} v(D) {intercept:+.2f}, Pearson {np.corrcoef(v, r)[0, 1]:.2f}")
    print(f"demonstrations: v(D) mean {v_demo.mean():+.2f}, r_S mean {r_demo.mean():+.2f}, "
          f"Pearson {np.corrcoef(v_demo, r_demo)[0, 1]:.2f}")
    for low in np.arange(-1.0, 1.0, 0.25):
        rows = [(v >= low) & (v < low + 0.25), (v_demo >= low) & (v_demo < low + 0.25)]
        cells = [f"{name} {int(m.sum()):6d} pairs, r_S {x[m].mean() if m.any() else float('nan'):+.2f}"
                 for name, m, x in zip(("student", "demonstrations"), rows, (r, r_demo))]
        print(f"v(D) in [{low:+.2f}, {low + 0.25:+.2f}): " + " | ".join(cells))
    with torch.no_grad():  # the trainer's update on one batch of its window, as rile_update computes it
        torch.manual_seed(0)
        batch = rb.sample(4096, recent=args.trainer_buffer_size)
        obs_trainer, a_trainer = torch.cat([batch.obs, batch.actions], -1), batch.extra
        r_trainer = rile.TRAINER_REWARDS[args.trainer_reward](disc.prob(obs_trainer), a_trainer.squeeze(-1))
        next_obs_trainer = torch.cat([batch.next_obs, student.policy(batch.next_obs)[0]], -1)
        loss, q_mean, target_var = trainer.critic_loss(obs_trainer, a_trainer, next_obs_trainer, r_trainer, batch.terminations)
        # E[(Q - y)^2] = Var(y) + (Q - E[y])^2: the targets' own variance over a'_S and a'_T, which no critic removes,
        # and the critics' error beyond it (what --trainer-freeze-stat excess tests), from 32 draws of y per pair
        q = trainer.qf(obs_trainer, a_trainer)
        ys = torch.stack([trainer.td_target(torch.cat([batch.next_obs, student.policy(batch.next_obs)[0]], -1), r_trainer,
                                            batch.terminations) for _ in range(32)])
        floor, beyond = ys.var(0, unbiased=False).mean(), (q - ys.mean(0)).pow(2).mean()
    print(f"trainer's critics on {len(batch.obs)} pairs of its window: TD loss {loss:.4f}, mean Q {q_mean:.1f}; relative "
          f"to the targets' variance {loss / (2 * target_var):.4f} (the freeze test's statistic), to r_T's variance "
          f"{loss / (2 * r_trainer.var()):.2f}")
    print(f"per critic, relative to r_T's variance: the targets' own variance {floor / r_trainer.var():.3f}, the error "
          f"beyond it {beyond / r_trainer.var():.3f} (--trainer-freeze-stat excess)")
    # The value the critics bootstrap from, min_i Q'_i(o_T', a'_T), on every row of the window: o_T' = (s', a'_S) with
    # the current student's mean action (as rile_update, but no sample) or the action stored in the row after (as the
    # student went on); a'_T the trainer's mean action. A local runaway shows as a few rows far below the rest.
    with torch.no_grad():
        idx = (rb.pos - torch.arange(min(rb.size, args.trainer_buffer_size), 0, -1)) % rb.size  # oldest to newest
        window, following = rb.batch(idx), rb.batch((idx + 1) % rb.size)
        mean_action = student.actor.deterministic(window.next_obs[:, :-1]) * (1 - window.next_obs[:, -1:])  # 0 if absorbing
        fresh = torch.cat([window.next_obs, mean_action], -1)
        stored = torch.cat([window.next_obs, following.actions], -1)
        continues = (following.obs == window.next_obs).all(-1)
        value = lambda o: trainer.qf_target(o, trainer.actor.deterministic(o)).min(0).values
        v_fresh, v_stored = value(fresh), value(stored)
        u = trainer.actor(torch.cat([window.obs, window.actions], -1))[0].abs().max()
    quantiles = (0.0, 0.001, 0.01, 0.5, 1.0)
    print(f"the critics' value of o_T' over the window's {len(idx)} rows, quantiles {quantiles}: "
          + " ".join(f"{q:.2f}" for q in torch.quantile(v_fresh, torch.tensor(quantiles)).tolist())
          + f"; with the stored next action {v_stored[continues].min():.2f} at the lowest; the trainer's largest |pre-tanh "
          f"mean| {u:.2f}")
    print("lowest rows (buffer row: value): " + ", ".join(f"{int(idx[j])}: {v_fresh[j]:.1f}" for j in v_fresh.argsort()[:8]))


if __name__ == "__main__":
    main()
