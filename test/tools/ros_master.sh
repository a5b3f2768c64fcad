# Sourced by the checks that need a ROS master of their own (check_install_space.sh,
# run_tsan_nodelet_pipeline.sh): other tests, and other engineers on a shared machine, run masters too, so
# each check takes a free port.

# start_ros_master LOG ENV...: starts rosmaster on a free port of 127.0.0.1 under ENV... (an `env -i ...`
# command line) and waits until it answers, for up to a minute: roslaunch, when it starts a master itself,
# gives up after 10 s, which a loaded machine can miss. A port taken between choosing and binding it is
# tried again with another. Sets ROS_MASTER_PORT and ROS_MASTER_PID (stop it with stop_ros_master);
# returns 1, the master's log printed, if no master came up.
start_ros_master() {
  local log="$1" attempt
  shift
  for attempt in 1 2 3; do
    ROS_MASTER_PORT=$(/usr/bin/python3 -c \
      'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
    "$@" ROS_MASTER_URI="http://127.0.0.1:$ROS_MASTER_PORT" ROS_IP=127.0.0.1 \
      rosmaster --core -p "$ROS_MASTER_PORT" >"$log" 2>&1 &
    ROS_MASTER_PID=$!
    for _ in $(seq 300); do
      if /usr/bin/python3 -c "import xmlrpc.client as x; x.ServerProxy('http://127.0.0.1:$ROS_MASTER_PORT').getPid('/c')" \
        >/dev/null 2>&1; then
        return 0
      fi
      kill -0 "$ROS_MASTER_PID" 2>/dev/null || break
      sleep 0.2
    done
    stop_ros_master
    echo "rosmaster on port $ROS_MASTER_PORT did not answer (attempt $attempt):"
    tail -n 20 "$log"
  done
  echo "FAILED: no ROS master came up"
  return 1
}

stop_ros_master() {
  kill "$ROS_MASTER_PID" 2>/dev/null || true
  wait "$ROS_MASTER_PID" 2>/dev/null || true
}
