"""Putting an edge node together: a robot or a fleet on its bus (`app`), the ROS graph (`roslink`), the TD
directory (`discovery`) and `td2adaptor run` itself (`node`)."""
