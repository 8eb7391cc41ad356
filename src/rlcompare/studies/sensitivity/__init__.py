"""Does the paper's answer hold across α, γ, the ε schedule and the time limit?"""
