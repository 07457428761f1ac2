"""Composer entities: robots, gripper, workcell arena (and later human, props)."""
