"""The paper's experiment, its claims, figures, videos and report, and why SARSA wins."""
