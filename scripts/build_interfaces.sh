#!/usr/bin/env bash
# Build the package's ROS 2 interfaces (msg/*.msg) for the development venv (.venv), in place:
# `colcon build` of this package against the ROS 2 wheels in .venv, then the generated message
# modules (fall_predictor/msg, the type-support extensions) copied into the source tree, as
# `build_ext --inplace` does, and their shared libraries into .venv/lib (which the wheels' start-up
# hook puts on LD_LIBRARY_PATH). In the same build, Unitree's low-level state messages
# (vendor/unitree_hg: the `lowstate` of a G1) as the interface package unitree_hg, installed into
# the venv like the ROS wheels' message packages (its Python package in site-packages). Skipped when msg/ and CMakeLists.txt are unchanged since the last
# build. On a ROS 2 install none of this is needed: `colcon build` installs everything.
set -euo pipefail
cd "$(dirname "$0")/.."
venv=$PWD/.venv
stamp=build/interfaces.stamp
digest=$(cat CMakeLists.txt package.xml msg/*.msg vendor/unitree_hg/CMakeLists.txt \
         vendor/unitree_hg/package.xml vendor/unitree_hg/msg/*.msg | sha256sum | cut -d' ' -f1)
if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$digest" ] && [ -d fall_predictor/msg ] \
   && .venv/bin/python -c 'import fall_predictor.msg, unitree_hg.msg' 2>/dev/null; then
  exit 0
fi
# The message wheels' CMake exports name the include folders of the machine that built them;
# point them at this venv's Python and NumPy headers (once; idempotent).
py_include=$(.venv/bin/python -c 'import sysconfig; print(sysconfig.get_paths()["include"])')
np_include=$(.venv/bin/python -c 'import numpy; print(numpy.get_include())')
{ grep -rl --include='*.cmake' '/opt/python/cp311-cp311' "$venv/share" 2>/dev/null || true; } | xargs -r sed -i \
  -e "s#/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include#$np_include#g" \
  -e "s#/opt/python/cp311-cp311/include/python3.11#$py_include#g"
command -v cmake >/dev/null || .venv/bin/python -m pip install --quiet cmake
# A copy of the interface sources: CMake refuses include folders (the venv's) inside the source
# folder of the project it builds.
rm -rf build/interfaces && mkdir -p build/interfaces/src/fall_predictor
cp -r CMakeLists.txt package.xml msg build/interfaces/src/fall_predictor/
cp -r vendor/unitree_hg build/interfaces/src/unitree_hg
log=build/interfaces.log
if ! (cd build/interfaces && PATH="$venv/bin:$PATH" AMENT_PREFIX_PATH="$venv" CMAKE_PREFIX_PATH="$venv" \
      "$venv/bin/colcon" build --cmake-args -DINTERFACES_ONLY=ON --no-warn-unused-cli \
      --event-handlers console_direct- >"../interfaces.log" 2>&1); then
  cat "$log"; echo "build_interfaces: colcon build FAILED (log above)"; exit 1
fi
generated=build/interfaces/install/fall_predictor/lib/python3.11/site-packages/fall_predictor
rm -rf fall_predictor/msg fall_predictor/*.so
cp -r "$generated/msg" fall_predictor/msg
cp "$generated"/*.so fall_predictor/
cp build/interfaces/install/fall_predictor/lib/lib*.so "$venv/lib/"
site=$(.venv/bin/python -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
rm -rf "$site/unitree_hg"
cp -r build/interfaces/install/unitree_hg/lib/python3.11/site-packages/unitree_hg "$site/unitree_hg"
cp build/interfaces/install/unitree_hg/lib/lib*.so "$venv/lib/"
.venv/bin/python -c 'from fall_predictor.msg import FallState; from unitree_hg.msg import LowState' \
  || { echo "build_interfaces: fall_predictor.msg or unitree_hg.msg does not import after the build"; exit 1; }
echo "$digest" > "$stamp"
echo "build_interfaces: fall_predictor.msg built ($(ls msg/*.msg | wc -l) messages), and unitree_hg" \
     "($(ls vendor/unitree_hg/msg/*.msg | wc -l) messages)"
