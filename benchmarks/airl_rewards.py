"""What airl.py's reward pays, read from a checkpoint: f and SAC's reward on the demonstrations, on the
learner's recent replay transitions, and where it falls. Answers "is falling worth more than living?":
with `--termination-remedy absorbing` staying in the absorbing state forever is worth r_abs / (1 - gamma),
r_abs being SAC's reward there (f at s_abs, or with `--absorbing-anchor min` the batch's lowest living g);
with terminations terminal (the default) falling is worth its last reward and nothing after it.

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
    absorbing = args.termination_remedy == "absorbing"  # else a termination ends the episode: worth 0 after it
    env = gym.make(args.env_id)
    obs_dim, act_dim = env.observation_space.shape[0], env.action_space.shape[0]
    low, high, device = env.action_space.low, env.action_space.high, torch.device("cpu")
    agent = airl.SAC(obs_dim + absorbing, act_dim, low, high, args, device, absorbing=absorbing)
    agent.load_state_dict(ckpt["agent"])
    anchor = ckpt["config"].get("absorbing_anchor", "learned") if absorbing else "none"  # older runs: learned
    disc = airl.AIRLDiscriminator(obs_dim + absorbing, act_dim, args.disc_hidden_dim, args.gamma, args.state_only,
                                  args.disc_lr, args.disc_gp, zero_absorbing_potential=anchor == "min",
                                  level_lr=ckpt["config"].get("disc_level_lr", 0.0))
    disc.load_state_dict(ckpt["disc"])
    rb = airl.ReplayBuffer(obs_dim + absorbing, act_dim, args.buffer_size, device)
    rb.load_state_dict(ckpt["replay_buffer"])
    demos = airl.load_demonstrations(args.expert_path or os.path.join("experts", f"{args.env_id}.npz"), env,
                                     args.num_expert_trajs)
    expert = airl.expert_tensors(demos, args.seed, device, args.expert_state_noise, args.expert_action_noise, low, high)
    expert = airl.absorbing_expert(expert) if absorbing else expert
    mix = ckpt["config"].get("disc_policy_mix", 0.0)  # log pi as the logit sees it (runs older than the flag: 0)

    def paid(batch):  # what SAC is paid: with the anchor, in batches of the SAC batch size, as in training
        return torch.cat([airl.sac_reward(disc, b, args.reward, anchor == "min",
                                          airl.policy_log_prob(agent, b.obs, b.actions, mix))
                          for b in map(batch, torch.arange(len(idx)).split(args.batch_size))])

    with torch.no_grad():
        f_expert = disc(expert["obs"], expert["actions"], expert["next_obs"], expert["terminations"])
        idx = torch.arange(max(0, rb.size - cli.recent), rb.size)
        recent = rb.batch(idx)
        f_policy = disc(recent.obs, recent.actions, recent.next_obs, recent.terminations)
        g_policy = disc.reward_g(recent.obs, recent.actions)  # h telescopes: g decides whether falling pays
        paid_policy = paid(lambda i: rb.batch(idx[i]))
        idx = torch.arange(len(expert["obs"]))
        paid_expert = paid(lambda i: airl.Batch(expert["obs"][i], expert["actions"][i], expert["next_obs"][i],
                                                torch.zeros(len(i)), expert["terminations"][i], torch.zeros(len(i), 0)))
        log_pi_expert = airl.policy_log_prob(agent, expert["obs"], expert["actions"], mix)
        log_pi_policy = airl.policy_log_prob(agent, recent.obs, recent.actions, mix)
    if absorbing:
        at_abs = recent.obs[:, -1] > 0
        falls = (recent.next_obs[:, -1] > 0) & ~at_abs
        own = expert["obs"][:, -1] == 0  # the demonstrations' own states, not s_abs
    else:
        at_abs, falls, own = torch.zeros_like(recent.terminations, dtype=torch.bool), recent.terminations > 0, slice(None)
    living = ~at_abs & ~falls
    horizon = 1 / (1 - args.gamma)
    print(f"{cli.run_dir} at step {ckpt['step']}, gamma {args.gamma}, SAC reward {args.reward}, "
          f"terminations {args.termination_remedy}, absorbing anchor {anchor}, log pi mix {mix}")
    print(f"f on the demonstrations:              mean {f_expert[own].mean():8.2f}  std {f_expert[own].std():6.2f}")
    print(f"f on the learner's living transitions: mean {f_policy[living].mean():8.2f}  std {f_policy[living].std():6.2f}"
          f"  (newest {len(recent.obs)} of the replay buffer)")
    print(f"SAC's reward on the demonstrations:   mean {paid_expert[own].mean():8.2f}; on the learner's living "
          f"transitions: mean {paid_policy[living].mean():.2f}, lowest {paid_policy[living].min():.2f}")
    # far apart, D tells expert from learner by log pi alone and f learns little from the expert's side
    print(f"log pi in the logit (median, 10th pct):  expert {log_pi_expert[own].median():.1f}, "
          f"{log_pi_expert[own].quantile(0.1):.1f}; learner {log_pi_policy[~at_abs].median():.1f}, "
          f"{log_pi_policy[~at_abs].quantile(0.1):.1f}")
    living_worth = paid_policy[living].mean() * horizon
    if not falls.any():
        print("no falls among these transitions")
    elif absorbing:
        print(f"f into the absorbing state:           mean {f_policy[falls].mean():8.2f}  ({int(falls.sum())} falls)")
        print(f"f at the absorbing state:             mean {f_policy[at_abs].mean():8.2f}")
        print(f"g on living transitions / at s_abs:   mean {g_policy[living].mean():8.2f} / {g_policy[at_abs].mean():.2f}"
              f"  (g's 1st percentile on living: {g_policy[living].quantile(0.01):.2f})")
        print(f"SAC's reward at the absorbing state:  mean {paid_policy[at_abs].mean():8.2f}")
        print(f"worth of falling, r_abs / (1 - gamma): {paid_policy[at_abs].mean() * horizon:9.1f}; of living at the "
              f"learner's mean reward: {living_worth:9.1f}")
    else:  # a termination: the falling step's reward, then nothing
        print(f"SAC's reward on the falling step:     mean {paid_policy[falls].mean():8.2f}  ({int(falls.sum())} falls)")
        print(f"worth of falling, the last reward then 0: {paid_policy[falls].mean():9.1f}; of living at the "
              f"learner's mean reward: {living_worth:9.1f}")


if __name__ == "__main__":
    main()
