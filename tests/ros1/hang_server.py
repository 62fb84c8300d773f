"""A procedures_msgs/ProcedureQuery server that answers the first N calls, then never answers again.

Run under /usr/bin/python3 with the RB-1 genpy modules on PYTHONPATH:
    hang_server.py SERVICE_NAME [ANSWER_FIRST_N]
Prints `ready` once advertised.
"""

from __future__ import annotations

import sys
import threading
from typing import Any

import rospy
from procedures_msgs.srv import ProcedureQuery, ProcedureQueryResponse


def main() -> None:
    name = sys.argv[1]
    answers = int(sys.argv[2]) if len(sys.argv) > 2 else 0
    count = [0]
    forever = threading.Event()

    def handle(request: Any) -> Any:
        count[0] += 1
        if count[0] <= answers:
            response = ProcedureQueryResponse()
            response.state.header.id = request.header.id
            response.result.result = "ok"
            return response
        forever.wait()  # never answers
        return None

    rospy.init_node("hang_server", anonymous=True, disable_signals=True)
    rospy.Service(name, ProcedureQuery, handle)
    print("ready", flush=True)
    try:
        while not rospy.is_shutdown():
            forever.wait(0.2)
    except KeyboardInterrupt:
        pass


if __name__ == "__main__":
    main()
