"""Composer entities: robots, gripper, workcell arena, human, props, markers."""
