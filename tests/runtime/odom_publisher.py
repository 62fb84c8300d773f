"""A child process for tests/runtime/test_property_streams_ros2.py: publishes numbered odometry messages.

`python -m tests.runtime.odom_publisher NAMESPACE COUNT PAUSE REPEATS`: once a subscriber matched, publishes
COUNT messages on /NAMESPACE/odom whose pose.position.x is 0, 1, ... COUNT-1, PAUSE seconds apart, then the
last one REPEATS times more and, if REPEATS > 0, one with x = COUNT; prints `sent` (with the seconds it
`took`) and stays until stopped.
The publisher is a process of its own: rclpy 7.1's EventsExecutor blocks a publisher in its own process.
"""

from __future__ import annotations

import json
import sys
import time


def main() -> None:
    import rclpy
    from nav_msgs.msg import Odometry

    namespace, count, pause, repeats = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4])
    rclpy.init()
    node = rclpy.create_node("odom_publisher")
    publisher = node.create_publisher(Odometry, f"/{namespace}/odom", 10)
    while publisher.get_subscription_count() < 1:
        time.sleep(0.02)
    time.sleep(0.5)  # the match is known both ways
    msg = Odometry()
    msg.header.frame_id = "odom"
    msg.pose.pose.orientation.w = 1.0
    xs = [*range(count), *[count - 1] * repeats, *([count] if repeats else [])]
    begin = time.monotonic()
    for x in xs:
        msg.pose.pose.position.x = float(x)
        publisher.publish(msg)
        time.sleep(pause)
    print(json.dumps({"event": "sent", "took": time.monotonic() - begin}), flush=True)
    while True:
        time.sleep(1.0)


if __name__ == "__main__":
    main()
