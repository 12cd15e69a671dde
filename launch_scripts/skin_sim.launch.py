"""ros2 launch file for users with a full ROS 2 Jazzy install (launch_ros is not on PyPI).

    ros2 launch launch_scripts/skin_sim.launch.py device:=sim      # node + bridge + simulated Touch
    ros2 launch launch_scripts/skin_sim.launch.py device:=crtk     # node + bridge to a real sawSensablePhantom

Thin by design: each process is the same `python -m skin_sim_node.cli ...` the scene scripts
start, so nothing here is needed by the tests.
"""

import sys
from pathlib import Path

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, ExecuteProcess
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration, PythonExpression

REPO = Path(__file__).resolve().parents[1]
PARAMS = str(REPO / "config" / "default.yaml")


def generate_launch_description():
    device = LaunchConfiguration("device")
    cli = [sys.executable, "-m", "skin_sim_node.cli"]
    return LaunchDescription(
        [
            DeclareLaunchArgument("device", default_value="sim", description="sim | crtk | omni"),
            DeclareLaunchArgument("hand_path", default_value="press_all_layers"),
            ExecuteProcess(cmd=[*cli, "node", "--ros-args", "--params-file", PARAMS], cwd=str(REPO), output="screen"),
            ExecuteProcess(
                cmd=[*cli, "bridge", "--convention", PythonExpression(["'omni' if '", device, "' == 'omni' else 'crtk'"])],
                cwd=str(REPO),
                output="screen",
            ),
            ExecuteProcess(
                cmd=[*cli, "device", "--hand-path", LaunchConfiguration("hand_path")],
                cwd=str(REPO),
                output="screen",
                condition=IfCondition(PythonExpression(["'", device, "' == 'sim'"])),
            ),
        ]
    )
