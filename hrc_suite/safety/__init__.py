"""Safety: the reachability shield and collision prevention (NumPy, numba).

Modules: `geometry` (segment/capsule/ball/box distances), `robot_reach` (robot
capsules and reachable sets), `human_reach` (human reachable sets),
`verification` (SSM verdict, joint limits), `collision_prevention` (static
and self-collision checks of goals), and the shield core (`path`,
`long_term_plan`, `shield`); `kernels` compiles the per-cycle geometry.
Nothing here imports MuJoCo or composer.
"""
