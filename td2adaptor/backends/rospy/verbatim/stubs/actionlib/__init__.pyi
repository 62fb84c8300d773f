# The parts of actionlib (ROS 1 actions) that the generated adaptor uses.
import threading
import weakref
from collections.abc import Callable
from typing import Any

import rospy

class CommStateMachine:
    action_goal: Any
    state: int
    def __init__(
        self,
        action_goal: Any,
        transition_cb: Callable[[ClientGoalHandle], None] | None,
        feedback_cb: Callable[[ClientGoalHandle, Any], None] | None,
        send_goal_fn: Callable[[Any], None] | None,
        send_cancel_fn: Callable[[Any], None] | None,
    ) -> None: ...

class ClientGoalHandle:
    comm_state_machine: CommStateMachine
    def __init__(self, comm_state_machine: CommStateMachine) -> None: ...
    def cancel(self) -> None: ...
    def get_comm_state(self) -> int: ...
    def get_goal_status(self) -> int: ...
    def get_goal_status_text(self) -> str: ...
    def get_result(self) -> Any: ...

class GoalManager:
    ActionGoal: type[Any]
    list_mutex: threading.RLock
    statuses: list[weakref.ref[CommStateMachine]]
    send_goal_fn: Callable[[Any], None] | None
    cancel_fn: Callable[[Any], None] | None

class ActionClient:
    manager: GoalManager
    last_status_msg: Any
    pub_goal: rospy.Publisher
    pub_cancel: rospy.Publisher
    status_sub: rospy.Subscriber
    result_sub: rospy.Subscriber
    feedback_sub: rospy.Subscriber
    ActionFeedback: type[Any]
    def __init__(self, ns: str, ActionSpec: Any) -> None: ...
    def send_goal(
        self,
        goal: Any,
        transition_cb: Callable[[ClientGoalHandle], None] | None = None,
        feedback_cb: Callable[[ClientGoalHandle, Any], None] | None = None,
    ) -> ClientGoalHandle: ...
    def stop(self) -> None: ...
