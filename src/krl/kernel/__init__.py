"""The kernel: an MLP imitating the MPC expert's foot trajectories (thesis 4.2.6.3-4.2.7)."""
