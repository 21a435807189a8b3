#!/usr/bin/env bash
# What the tests use beyond the project's venv, made once (the test command runs this; the run
# command never does). Each part is optional: a test that needs a missing one skips, saying why.
#
#   .ros2tools/     the real `ros2` command, launch and launch_ros (not on PyPI), built by
#                   ../shared/ros2cli/setup.sh where that folder exists (CI has it), unless a
#                   `ros2` command is on PATH already (a ROS install) or it was built before;
#   .cache/colcon/  colcon-core and colcon-ros from PyPI (tools/colcon-requirements.txt), in a
#                   venv of their own.
set -uo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
shared="$root/../shared/ros2cli"
if command -v ros2 >/dev/null 2>&1; then
  echo "test tools: ros2 on PATH ($(command -v ros2))"
elif [ -x .ros2tools/venv/bin/ros2 ]; then
  echo "test tools: ros2 built before (.ros2tools)"
elif [ -x "$shared/setup.sh" ]; then
  echo "test tools: building the ros2 command from $shared (1-2 min, once)"
  "$shared/setup.sh" "$root" > .cache/ros2tools-setup.log 2>&1 \
    || echo "test tools: ros2 build failed (see .cache/ros2tools-setup.log); its tests will skip"
else
  echo "test tools: no ros2 command and no $shared: the tests that need one will skip"
fi
pins="$root/tools/colcon-requirements.txt"
venv="$root/.cache/colcon"
stamp="$venv/.pins"
if [ -x "$venv/bin/colcon" ] && cmp -s "$pins" "$stamp"; then
  exit 0
fi
echo "test tools: colcon into .cache/colcon (PyPI)"
rm -rf "$venv"
base=$(sed -n 's/^executable *= *//p' .venv/pyvenv.cfg)
[ -x "$base" ] || base=$(sed -n 's/^home *= *//p' .venv/pyvenv.cfg)/python3
if [ -x .venv/bin/uv ]; then
  install=(.venv/bin/uv pip install -q --python "$venv/bin/python" -r "$pins")
  made=$("$base" -m venv --without-pip "$venv" && echo ok)
else
  install=("$venv/bin/python" -m pip install -q --disable-pip-version-check -r "$pins")
  made=$("$base" -m venv "$venv" && echo ok)
fi
if [ "$made" = ok ] && "${install[@]}" > .cache/colcon-setup.log 2>&1; then
  cp "$pins" "$stamp"
else
  echo "test tools: colcon could not be installed (see .cache/colcon-setup.log); its test will skip"
  rm -rf "$venv"
fi
exit 0
