#!/usr/bin/env python3
"""Progress of a demo run: counts the mapped poses (aft_mapped_to_init) against the sweeps in the bag and
prints one line at each further 10 %, then a last line when stopped (SIGINT or SIGTERM) or when every sweep
has its pose.

  demo_progress.py --bag SIM.bag [--topic velodyne_points] [--pose-topic aft_mapped_to_init]
"""
import argparse
import signal
import sys
import threading

import rosbag
import rospy
from nav_msgs.msg import Odometry


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--bag", required=True)
    parser.add_argument("--topic", default="velodyne_points")
    parser.add_argument("--pose-topic", default="aft_mapped_to_init")
    args = parser.parse_args(rospy.myargv()[1:])

    with rosbag.Bag(args.bag) as bag:
        total = bag.get_message_count(args.topic)
    if total == 0:
        sys.exit("demo_progress: no %s messages in %s" % (args.topic, args.bag))

    lock = threading.Lock()
    state = {"mapped": 0, "shown": 0}
    done = threading.Event()

    def on_pose(_msg):
        with lock:
            state["mapped"] += 1
            tenth = min(10, state["mapped"] * 10 // total)
            if tenth > state["shown"]:
                state["shown"] = tenth
                print("demo: %3d %% mapped (%d of %d sweeps)" % (tenth * 10, state["mapped"], total), flush=True)
            if state["mapped"] >= total:
                done.set()

    rospy.init_node("demo_progress", anonymous=True, disable_signals=True)
    rospy.Subscriber(args.pose_topic, Odometry, on_pose, queue_size=100)
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: done.set())
    print("demo: waiting for %d sweeps to be mapped" % total, flush=True)
    done.wait()
    with lock:
        if state["mapped"] < total:
            print("demo: %d of %d sweeps mapped (the rest were skipped or still in flight)"
                  % (state["mapped"], total), flush=True)
    rospy.signal_shutdown("done")


if __name__ == "__main__":
    main()
