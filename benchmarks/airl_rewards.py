"""What airl.py's reward f pays, read from a checkpoint: on the demonstrations, on the learner's recent
replay transitions, and at the absorbing state. Answers "is falling worth more than living?" for a run
with `--termination-remedy absorbing`: staying in the absorbing state forever is worth r_abs / (1 - gamma), r_abs
being SAC's reward there (f at s_abs, or with `--absorbing-anchor min` the batch's lowest living g).

    python benchmarks/airl_rewards.py runs/bench__Hopper-v4__airl-absorbing__1 [--recent 20000]
"""

import argparse
import os
import sys

import gymnasium as gym
import torch

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import airl  # noqa: E402


def open_run(script, doc: str):
    """The command line (a run directory, --recent), then the run's config and checkpoint as `script`
    (the imported module: airl, rile) reads them on --resume. benchmarks/rile_rewards.py uses it too."""
    parser = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    parser.add_argument("run_dir")
    parser.add_argument("--recent", type=int, default=20000, help="how many of the newest replay transitions")
    cli = parser.parse_args()
    torch.set_num_threads(1)
    return (cli, *script.resume(script.Args(resume=cli.run_dir)))


def main():
    cli, args, ckpt = open_run(airl, __doc__)
    if args.termination_remedy != "absorbing":
        sys.exit(f"error: {cli.run_dir} was trained with --termination-remedy {args.termination_remedy}; "
                 "this check is for absorbing-state runs")
    env = gym.make(args.env_id)
    obs_dim, act_dim = env.observation_space.shape[0], env.action_space.shape[0]
    low, high, device = env.action_space.low, env.action_space.high, torch.device("cpu")
    agent = airl.SAC(obs_dim + 1, act_dim, low, high, args, device, absorbing=True)
    agent.load_state_dict(ckpt["agent"])
    anchor = ckpt["config"].get("absorbing_anchor", "learned")  # runs older than the flag learned f at s_abs
    disc = airl.AIRLDiscriminator(obs_dim + 1, act_dim, args.disc_hidden_dim, args.gamma, args.state_only,
                                  args.disc_lr, args.disc_gp, zero_absorbing_potential=anchor == "min",
                                  level_lr=ckpt["config"].get("disc_level_lr", 0.0))
    disc.load_state_dict(ckpt["disc"])
    rb = airl.ReplayBuffer(obs_dim + 1, act_dim, args.buffer_size, device)
    rb.load_state_dict(ckpt["replay_buffer"])
    demos = airl.load_demonstrations(args.expert_path or os.path.join("experts", f"{args.env_id}.npz"), env,
                                     args.num_expert_trajs)
    expert = airl.absorbing_expert(airl.expert_tensors(demos, args, low, high, device))

    with torch.no_grad():
        f_expert = disc(expert["obs"], expert["actions"], expert["next_obs"], expert["terminations"])
        recent = rb.batch(torch.arange(max(0, rb.size - cli.recent), rb.size))
        f_policy = disc(recent.obs, recent.actions, recent.next_obs, recent.terminations)
        g_policy = disc.reward_g(recent.obs, recent.actions)  # h telescopes: g decides whether falling pays
        # what SAC is paid: with the anchor, batches of the SAC batch size, as in training
        mix = ckpt["config"].get("disc_policy_mix", 0.0)  # log pi as the logit sees it
        paid = torch.cat([airl.sac_reward(disc, b, args.reward, anchor == "min",
                                          airl.policy_log_prob(agent, b.obs, b.actions, mix))
                          for b in map(rb.batch, torch.arange(max(0, rb.size - cli.recent), rb.size).split(args.batch_size))])
        log_pi_expert = airl.policy_log_prob(agent, expert["obs"], expert["actions"], mix)
        log_pi_policy = airl.policy_log_prob(agent, recent.obs, recent.actions, mix)
    at_abs = recent.obs[:, -1] > 0
    into_abs = (recent.next_obs[:, -1] > 0) & ~at_abs
    living = ~at_abs & ~into_abs
    horizon = 1 / (1 - args.gamma)
    print(f"{cli.run_dir} at step {ckpt['step']}, gamma {args.gamma}, SAC reward {args.reward}, absorbing anchor {anchor}")
    print(f"f on the demonstrations:              mean {f_expert.mean():8.2f}  std {f_expert.std():6.2f}")
    print(f"f on the learner's living transitions: mean {f_policy[living].mean():8.2f}  std {f_policy[living].std():6.2f}"
          f"  (newest {len(recent.obs)} of the replay buffer)")
    # far apart, D tells expert from learner by log pi alone and f learns little from the expert's side
    log_pi_expert = log_pi_expert[expert["obs"][:, -1] == 0]  # the demonstrations' own states, not s_abs
    print(f"log pi in the logit (median, 10th pct):  expert {log_pi_expert.median():.1f}, "
          f"{log_pi_expert.quantile(0.1):.1f}; learner {log_pi_policy[~at_abs].median():.1f}, "
          f"{log_pi_policy[~at_abs].quantile(0.1):.1f}")
    if at_abs.any():
        print(f"f into the absorbing state:           mean {f_policy[into_abs].mean():8.2f}  ({int(into_abs.sum())} falls)")
        print(f"f at the absorbing state:             mean {f_policy[at_abs].mean():8.2f}")
        print(f"g on living transitions / at s_abs:   mean {g_policy[living].mean():8.2f} / {g_policy[at_abs].mean():.2f}"
              f"  (g's 1st percentile on living: {g_policy[living].quantile(0.01):.2f})")
        print(f"SAC's reward at the absorbing state:  mean {paid[at_abs].mean():8.2f}  (living: {paid[living].mean():.2f})")
        print(f"worth of falling, r_abs / (1 - gamma): {paid[at_abs].mean() * horizon:9.1f}; of living at the "
              f"learner's mean reward: {paid[living].mean() * horizon:9.1f}")
    else:
        print("no falls among these transitions")


if __name__ == "__main__":
    main()
