"""Safety: the reachability shield and collision prevention (NumPy, numba).

Subpackages (docs/architecture.md, "Packages"): `shield` (the reachability
shield, its state, modes and their compiled verification, paths, the
human's reachable set, the energies it verifies, the compiled cycles) and
`collision_prevention` (static and self-collision checks of goals). What
both use is here: `geometry` (segment/capsule/ball/box distances),
`kernels` (the compiled per-cycle geometry), `robot_reach` (robot capsules
and reachable sets), `long_term_plan` and `plan_kernels` (a goal's
jerk-limited plan), and the energy models of robots and body regions
(`robot_energy`, `arm_energy`, `energy_kernels`, `contact_energy`,
`body_regions`, `clamping`). Nothing here imports the subpackages.
"""
