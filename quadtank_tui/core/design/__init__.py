"""PI/PID design from a DelayTF model (Andersson 2000, sections 3-4): lambda tuning,
Ms-constrained PI/PID, closed-loop evaluation, and the 2x2 check of the
quadruple tank's decentralized loops."""
