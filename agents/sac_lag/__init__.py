"""SAC-Lagrangian: soft actor-critic under a per-episode cost limit."""
