"""The studies ``rlcompare reproduce`` runs, by name, with a line each; their modules import only when run."""

TITLES = {
    "paper": "the paper: Q-Learning vs SARSA on MountainCar-v0, ε constant and decaying, and the order ablation",
    "why": "why SARSA wins there: target (max, taken, expectation) x order of choosing A' and updating",
    "cartpole": "the paper's grid of configurations on CartPole-v1",
    "acrobot": "the paper's grid of configurations on Acrobot-v1",
    "book-10.2": "Semi-gradient SARSA with tile coding (Figure 10.2)",
    "book-12.10": "SARSA(λ) with replacing traces (Figure 12.10)",
    "cliff": "Cliff Walking: SARSA, Q-Learning and Expected SARSA (Example 6.6)",
    "book-6.3": "Cliff Walking against α, 100 episodes x 50,000 runs and 100,000 x 10 (Figure 6.3; about 5 min on "
                "2 cores)",
    "deep": "the question with networks: Q(λ), SARSA(λ), DQN, PPO on three environments (the 'deep' extra)",
    "sensitivity": "does SARSA still beat Q-Learning across α, γ, ε_end and the time limit? (a sweep; Ray: --address)",
}
"""Every study, in the order ``--list`` shows them."""
