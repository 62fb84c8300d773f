"""The robot side of the edge node: the port protocol (`port`), the generated package's port (`genport`), a
simulated robot (`simport`), the ROS 1 bridge (`bridge`), CDR decoding (`cdr`) and procedure states read from
a robot's answers (`procedures`).

This package and `bridge`, `genport`, `port` must stay importable with the standard library alone: the ROS 1
bridge runs them under ROS 1's own interpreter, which has none of td2adaptor's dependencies.
"""
