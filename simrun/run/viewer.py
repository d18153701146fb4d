"""Interactive viewing with keyboard teleoperation of the first robot with wheels (the robot contract's)."""

from __future__ import annotations

import time
from typing import Any

from simrun.robots.contract import robots
from simrun.world.world import World

KEY_SPACE, KEY_RIGHT, KEY_LEFT, KEY_DOWN, KEY_UP = 32, 262, 263, 264, 265
HELP = "arrows: drive (cmd_vel)   space: all stop   mouse: camera   Esc/close: quit"


class Teleop:
    """Maps key presses to ``cmd_vel`` of one drive: up/down change speed, left/right turn rate."""

    def __init__(self, drive: Any, step_linear: float = 0.05, step_angular: float = 0.5) -> None:
        self.drive, self.linear, self.angular = drive, 0.0, 0.0
        self.step_linear, self.step_angular = step_linear, step_angular

    def key(self, keycode: int) -> None:
        """Handle one key."""
        if keycode == KEY_SPACE:
            self.linear = self.angular = 0.0
            self.drive.all_stop()
            return
        if keycode == KEY_UP:
            self.linear += self.step_linear
        elif keycode == KEY_DOWN:
            self.linear -= self.step_linear
        elif keycode == KEY_LEFT:
            self.angular += self.step_angular
        elif keycode == KEY_RIGHT:
            self.angular -= self.step_angular
        else:
            return
        self.drive.cmd_vel(self.linear, self.angular)

    def refresh(self) -> None:
        """Re-send the current command (cmd_vel expires without one)."""
        if self.linear or self.angular:
            self.drive.cmd_vel(self.linear, self.angular)


def run_viewer(world: World) -> None:
    """Open MuJoCo's passive viewer on the world, stepping in real time until the window closes."""
    import mujoco.viewer

    robot = next((name for name, r in robots(world).items() if r.wheels is not None), None)
    teleop = None
    if robot is not None:
        from simrun.services.drive_service import DriveService

        bound = any(s.get("type") == "DriveService" and s.get("entity") == robot for s in world.services)
        teleop = Teleop(world.service("DriveService", robot) if bound else DriveService(world, robot))
    model, data = world.model, world.data
    with mujoco.viewer.launch_passive(model, data, key_callback=teleop.key if teleop else None) as viewer:
        viewer.set_texts((mujoco.mjtFontScale.mjFONTSCALE_150, mujoco.mjtGridPos.mjGRID_TOPLEFT, HELP, ""))
        start_wall, start_sim = time.perf_counter(), data.time
        while viewer.is_running():
            if teleop is not None:
                teleop.refresh()
            world.step(10)
            viewer.sync()
            ahead = (data.time - start_sim) - (time.perf_counter() - start_wall)
            if ahead > 0:
                time.sleep(ahead)
