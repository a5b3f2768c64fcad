# Shared by the scripts in this folder: paths, dependency installation and the catkin build.
# Source it; do not run it.

ALOAM_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# The catkin workspace lives beside the sources (ignored by git); override with ALOAM_WS.
ALOAM_WS="${ALOAM_WS:-$ALOAM_ROOT/.catkin_ws}"
ALOAM_DATA="${ALOAM_DATA:-$ALOAM_ROOT/../shared/data}"
# Debian's ROS tools need Debian's python3 (the image may put another one first on PATH).
export PATH="/usr/bin:/bin:/usr/sbin:/sbin:$PATH"
export ROS_HOME="${ROS_HOME:-$ALOAM_WS/ros_home}"
export ROS_LOG_DIR="${ROS_LOG_DIR:-$ROS_HOME/log}"

# Debian 12 packages the build, the tests and the tools need. libunwind-dev: Ceres's CMake config loads
# glog's, which needs libunwind-dev's; apt would take LLVM's libunwind-14-dev for glog's dependency where
# that is installed (clang development setups), and the configure step then fails. xvfb, imagemagick:
# `demo.sh --screenshot` runs rviz on a virtual display and captures it with ImageMagick's `import`.
ALOAM_DEBIAN_PACKAGES=(
  build-essential cmake clang libclang-rt-14-dev liblz4-dev catkin python3-catkin-pkg python3-rospkg
  ros-base-dev libroscpp-dev librosbag-dev libnodeletlib-dev libnodeletlib-tools libnodelet-dev
  pluginlib-dev libtf2-ros-dev libtf2-eigen-dev libpcl-ros-dev libpcl-dev libeigen3-dev libceres-dev
  libsensor-msgs-dev libnav-msgs-dev libgeometry-msgs-dev libstd-srvs-dev
  libdynamic-reconfigure-config-init-mutex-dev python3-dynamic-reconfigure libdiagnostic-updater-dev
  python3-rostest librostest-dev python3-rosbag python3-nodelet python3-roslaunch libgtest-dev
  ros-message-generation ros-message-runtime python3-genmsg python3-gencpp python3-genpy libstd-msgs-dev
  python3-numpy python3-scipy python3-rospy python3-tf2-ros rviz python3-matplotlib
  python3-diagnostic-msgs python3-std-srvs python3-nav-msgs python3-sensor-msgs rosbash
  git clang-format python3-rosdep2
  libunwind-dev
  xvfb imagemagick
)

# Each line carries the minutes and seconds since the script started, so a log shows where the time goes.
aloam_log() { printf '\033[1m[aloam %d:%02d]\033[0m %s\n' $((SECONDS / 60)) $((SECONDS % 60)) "$*" >&2; }

# Installs whatever of ALOAM_DEBIAN_PACKAGES is missing (needs root or sudo).
aloam_install_deps() {
  local missing=()
  local pkg
  for pkg in "${ALOAM_DEBIAN_PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing+=("$pkg")
  done
  if [ ${#missing[@]} -eq 0 ]; then
    aloam_log "Debian packages: all present"
    return 0
  fi
  local sudo=""
  if [ "$(id -u)" -ne 0 ]; then
    command -v sudo >/dev/null || { aloam_log "need root (or sudo) to install: ${missing[*]}"; return 1; }
    sudo="sudo"
  fi
  aloam_log "installing ${#missing[@]} Debian packages: ${missing[*]}"
  $sudo apt-get update -q
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -q --no-install-recommends "${missing[@]}"
}

# The dependency self-check (scripts/check_deps.py): every Python module, command, launch-file package,
# CMake package and package.xml key the project uses must come from ALOAM_DEBIAN_PACKAGES or its
# dependencies. ALOAM_DEPS_OMIT="pkg ..." checks the list without those (test/tools/check_deps_catch.sh).
aloam_check_deps() {
  local pkgs=() pkg
  for pkg in "${ALOAM_DEBIAN_PACKAGES[@]}"; do
    [[ " ${ALOAM_DEPS_OMIT:-} " == *" $pkg "* ]] || pkgs+=("$pkg")
  done
  /usr/bin/python3 "$ALOAM_ROOT/scripts/check_deps.py" "$ALOAM_ROOT" "${pkgs[@]}"
}

# Creates the workspace (src/aloam_nodelet -> this repository) and builds it in Release.
aloam_build() {
  mkdir -p "$ALOAM_WS/src" "$ROS_LOG_DIR"
  ln -sfn "$ALOAM_ROOT" "$ALOAM_WS/src/aloam_nodelet"
  aloam_log "building in $ALOAM_WS"
  (cd "$ALOAM_WS" && catkin_make -DCMAKE_BUILD_TYPE=Release -j"$(nproc)" "$@" >&2)
}

# Environment of the built workspace (setup.bash reads unset variables, so relax -u around it).
aloam_source_ws() {
  set +u
  # shellcheck disable=SC1091
  source "$ALOAM_WS/devel/setup.bash"
  set -u
}
