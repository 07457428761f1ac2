"""JAX agents for hrc_suite (Acme-shaped); filled by the agents issue."""
