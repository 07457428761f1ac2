"""Human simulation: clips, BVH import, replay (import the submodules)."""
